"""The independent SOIL.md reference reproduces the figures of SOIL.md and NOTES.md (2026-11-24).

Rover wheel: r 0.085 m, b 0.05 m, 27 N; SOIL.md's regolith values. Check values are quoted to
the digits NOTES.md / SOIL.md give them, so each tolerance is half a unit of the last digit.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from soil_reference import (
    reference_operating_point,
    reference_soil_forces,
    reference_static_sinkage,
    slip_speeds,
    wong_slip,
)

R, B, W = 0.085, 0.05, 27.0
REGOLITH = {
    "c": 800.0,
    "phi_deg": 37.2,
    "k_c": 1.37e3,
    "k_phi": 8.14e5,
    "n0": 1.0,
    "n1": 0.0,
    "k_x": 0.036,
    "k_y": 0.020,
    "a0": 0.40,
    "a1": 0.15,
    "lam": 0.9,
}


@pytest.fixture(autouse=True)
def _quad_warnings_fail():
    """An IntegrationWarning means the reference is not converged: make it an error."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


def test_notes_static_sinkage_lambda_09():
    assert reference_static_sinkage(W, R, B, REGOLITH) * 1e3 == pytest.approx(14.3, abs=0.05)


@pytest.mark.parametrize(("s", "dpw"), [(0.0, -0.016), (0.2, 0.146), (0.5, 0.316), (0.9, 0.449)])
def test_notes_pull_over_load_lambda_09(s, dpw):
    op = reference_operating_point(W, R, B, REGOLITH, s)
    assert op["F_z"] == pytest.approx(W, rel=1e-9)
    assert op["DP/W"] == pytest.approx(dpw, abs=5e-4)


@pytest.mark.parametrize(("s", "h_mm"), [(0.2, 20.0), (0.5, 31.0), (0.9, 51.0)])
def test_notes_slip_sinkage_n1_05(s, h_mm):
    op = reference_operating_point(W, R, B, {**REGOLITH, "n1": 0.5}, s)
    assert op["h"] * 1e3 == pytest.approx(h_mm, abs=0.5)


@pytest.mark.parametrize(
    ("lam", "h_mm", "dpw0", "dpw03"),
    [
        (0.9, 14.0, -0.02, 0.21),
        pytest.param(
            0.3,
            17.0,
            -0.11,
            0.09,
            marks=pytest.mark.xfail(
                strict=True,
                reason="SOIL.md's F_x/F_z -0.11 at s = 0 (lambda 0.3) does not reproduce: -0.1046 "
                "(full F_z) or -0.1045 (pressure-only sinkage); see the report",
            ),
        ),
        pytest.param(
            0.0,
            23.0,
            -0.25,
            -0.11,
            marks=pytest.mark.xfail(
                strict=True,
                reason="SOIL.md's 23 mm static sinkage (lambda 0) is the pressure-only sinkage "
                "(23.00 mm); balancing the full F_z at s = 0 gives 22.46 mm",
            ),
        ),
    ],
)
def test_soil_md_lambda_table(lam, h_mm, dpw0, dpw03):
    """SOIL.md's orientation figures, the sinkage balancing SOIL.md's full F_z at each slip."""
    p = {**REGOLITH, "lam": lam}
    assert reference_static_sinkage(W, R, B, p) * 1e3 == pytest.approx(h_mm, abs=0.5)
    assert reference_operating_point(W, R, B, p, 0.0)["DP/W"] == pytest.approx(dpw0, abs=5e-3)
    assert reference_operating_point(W, R, B, p, 0.3)["DP/W"] == pytest.approx(dpw03, abs=5e-3)


@pytest.mark.parametrize(("lam", "h_mm"), [(0.9, 14.0), (0.3, 17.0), (0.0, 23.0)])
def test_soil_md_static_sinkage_is_pressure_only(lam, h_mm):
    """SOIL.md's static sinkages all reproduce when the load is carried by normal stress alone."""
    h = reference_static_sinkage(W, R, B, {**REGOLITH, "lam": lam}, pressure_only=True)
    assert h * 1e3 == pytest.approx(h_mm, abs=0.5)


@pytest.mark.parametrize(
    ("lam", "h_mm", "dpw0", "dpw03"),
    [(0.9, 14.34, -0.0163, 0.2115), (0.3, 16.70, -0.1046, 0.0861), (0.0, 22.46, -0.2526, -0.1099)],
)
def test_lambda_table_full_precision(lam, h_mm, dpw0, dpw03):
    """This reference's own figures (what the report quotes), to the digits quoted."""
    p = {**REGOLITH, "lam": lam}
    assert reference_static_sinkage(W, R, B, p) * 1e3 == pytest.approx(h_mm, abs=0.005)
    assert reference_operating_point(W, R, B, p, 0.0)["DP/W"] == pytest.approx(dpw0, abs=5e-5)
    assert reference_operating_point(W, R, B, p, 0.3)["DP/W"] == pytest.approx(dpw03, abs=5e-5)


def test_notes_lambda_0_needs_slip_above_half_for_pull():
    p = {**REGOLITH, "lam": 0.0}
    assert reference_operating_point(W, R, B, p, 0.5)["DP/W"] < 0.0
    assert reference_operating_point(W, R, B, p, 0.9)["DP/W"] > 0.0


def test_slip_definition_and_speeds():
    for s in (-0.9, -0.3, 0.0, 0.2, 0.9):
        vx, vw = slip_speeds(s)
        assert wong_slip(vx, vw)[0] == pytest.approx(s, abs=1e-12)
        assert wong_slip(-vx, -vw) == pytest.approx((wong_slip(vx, vw)[0], -1.0))
    assert wong_slip(0.0, 0.0) == (0.0, 1.0)  # at rest: d = +1, no slip
    assert wong_slip(0.1, -0.05)[0] == -1.0  # clamped (d = +1: braking beyond lock)
    assert wong_slip(0.1, -0.1)[0] == 1.0  # d = sign(v_w) = -1: spinning backwards
    with pytest.raises(ValueError, match="slip"):
        slip_speeds(1.0)


def _simpson_forces(v_x, v_y, v_w, h, p, pts=20001):
    """Brute-force composite Simpson on each piece: checks that the quad results converged."""
    ref = reference_soil_forces(v_x, v_y, v_w, h, R, B, p)
    s, d = wong_slip(v_x, v_w)
    th_f, th_r, th_m = ref["theta_f"], ref["theta_r"], ref["theta_m"]
    tan_phi = math.tan(math.radians(p["phi_deg"]))
    k_s = p["k_c"] / B + p["k_phi"]
    n = p["n0"] + p["n1"] * abs(s)
    tan_b = math.tan(math.atan2(v_y, max(abs(v_x), 1e-3)))
    acc = np.zeros(4)
    for a, z, front in ((th_r, th_m, False), (th_m, th_f, True)):
        if z <= a:
            continue
        th = np.linspace(a, z, pts)
        if front:
            arg = np.cos(th) - math.cos(th_f)
        else:
            arg = np.cos(th_f - (th - th_r) / (th_m - th_r) * (th_f - th_m)) - math.cos(th_f)
        sig = k_s * (R * np.clip(arg, 0.0, None)) ** n
        jx = R * (th_f - th - (1 - s) * (math.sin(th_f) - np.sin(th)))
        jy = R * (1 - s) * (th_f - th) * tan_b
        tx = (p["c"] + sig * tan_phi) * np.sign(jx) * (1 - np.exp(-np.abs(jx) / p["k_x"]))
        ty = (p["c"] + sig * tan_phi) * np.sign(jy) * (1 - np.exp(-np.abs(jy) / p["k_y"]))
        wts = np.ones(pts)
        wts[1:-1:2], wts[2:-1:2] = 4.0, 2.0
        wts *= (z - a) / (pts - 1) / 3.0
        f = [tx * np.cos(th) - sig * np.sin(th), tx * np.sin(th) + sig * np.cos(th), ty, tx]
        acc += [float(wts @ fi) for fi in f]
    brute = {
        "F_x": d * R * B * acc[0],
        "F_z": R * B * acc[1],
        "F_y": -R * B * acc[2],
        "T": d * R * R * B * acc[3],
    }
    return ref, brute


def test_quadrature_converged_against_brute_force_simpson():
    rng = np.random.default_rng(1015)
    for _ in range(12):
        p = {
            **REGOLITH,
            "c": rng.uniform(0.0, 3000.0),
            "phi_deg": rng.uniform(25.0, 40.0),
            "n0": rng.uniform(0.6, 1.4),
            "n1": rng.uniform(0.0, 0.6),
            "lam": rng.uniform(0.0, 1.0),
        }
        vx, vy, vw = rng.uniform(-0.3, 0.3, size=3)
        h = rng.uniform(0.002, 0.06)
        ref, brute = _simpson_forces(vx, vy, vw, h, p)
        for k in ("F_x", "F_y", "F_z", "T"):
            # Simpson's own error near theta_f (sigma ~ (theta_f - theta)^n) bounds this check.
            assert ref[k] == pytest.approx(brute[k], abs=2e-5 * abs(ref["F_z"]) + 1e-9), k


def test_signs_and_symmetries():
    vx, vw = slip_speeds(0.3)
    f = reference_soil_forces(vx, 0.02, vw, 0.02, R, B, REGOLITH)
    g = reference_soil_forces(-vx, 0.02, -vw, 0.02, R, B, REGOLITH)  # same wheel, backwards
    m = reference_soil_forces(vx, -0.02, vw, 0.02, R, B, REGOLITH)  # mirrored side slip
    assert f["F_x"] > 0.0 and f["T"] > 0.0 and f["F_z"] > 0.0  # driving: pull forward, resist
    assert f["F_y"] < 0.0  # opposes sliding to the left
    assert (g["F_x"], g["T"], g["F_z"], g["F_y"], g["s"]) == pytest.approx(
        (-f["F_x"], -f["T"], f["F_z"], f["F_y"], f["s"]), rel=1e-9
    )
    assert (m["F_x"], m["F_z"], m["F_y"]) == pytest.approx((f["F_x"], f["F_z"], -f["F_y"]))
    brake = reference_soil_forces(
        *slip_speeds(-0.3)[:1], 0.0, slip_speeds(-0.3)[1], 0.02, R, B, REGOLITH
    )
    assert brake["s"] == pytest.approx(-0.3) and brake["F_x"] < 0.0 and brake["T"] < 0.0


def test_no_contact_and_radius_clip():
    z = reference_soil_forces(0.1, 0.01, 0.12, 0.0, R, B, REGOLITH)
    assert (z["F_x"], z["F_y"], z["F_z"], z["T"]) == (0.0, 0.0, 0.0, 0.0)
    assert reference_soil_forces(0.1, 0.0, 0.12, -0.01, R, B, REGOLITH)["F_z"] == 0.0
    deep = reference_soil_forces(0.1, 0.01, 0.12, 2 * R, R, B, REGOLITH)
    at_r = reference_soil_forces(0.1, 0.01, 0.12, R, R, B, REGOLITH)
    assert deep == at_r


def test_bad_input_is_named():
    with pytest.raises(KeyError, match="k_phi"):
        reference_soil_forces(
            0.1, 0.0, 0.1, 0.01, R, B, {k: v for k, v in REGOLITH.items() if k != "k_phi"}
        )
    with pytest.raises(ValueError, match="lam"):
        reference_soil_forces(0.1, 0.0, 0.1, 0.01, R, B, {**REGOLITH, "lam": 1.5})
    with pytest.raises(ValueError, match="below the load"):
        reference_static_sinkage(1e5, R, B, REGOLITH)
