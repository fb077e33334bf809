"""rover_env.soil.soil_forces against the independent adaptive-quadrature reference (issue 15).

Acceptance of issue 15: agreement to 2e-3 of F_z over random parameters, speeds and sinkages.
Skipped until `rover_env.soil` exists (it is written on another branch). Speeds stay clear of
v_eps (SOIL.md leaves its value open) except at exact rest, where s = 0 whatever v_eps is.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from soil_reference import REQUIRED, load_preset, reference_soil_forces, slip_speeds

soil = pytest.importorskip("rover_env.soil")

R, B = 0.085, 0.05
TOL = 2e-3  # of |F_z|, issue 15's acceptance figure
SEED = 1015


def _params(p: dict) -> object:
    return soil.SoilParams(**{k: float(p[k]) for k in REQUIRED})


def _random_params(rng: np.random.Generator) -> dict:
    return {
        "c": rng.uniform(0.0, 3000.0),
        "phi_deg": rng.uniform(20.0, 45.0),
        "k_c": rng.uniform(0.0, 2e4),
        "k_phi": rng.uniform(3e5, 3e6),
        "n0": rng.uniform(0.6, 1.4),
        "n1": rng.uniform(0.0, 0.6),
        "k_x": rng.uniform(0.005, 0.05),
        "k_y": rng.uniform(0.005, 0.05),
        "a0": rng.uniform(0.3, 0.5),
        "a1": rng.uniform(0.0, 0.4),
        "lam": rng.uniform(0.0, 1.0),
    }


def _speed(rng: np.random.Generator) -> float:
    v = rng.uniform(0.005, 0.5)
    return float(v if rng.random() < 0.7 else -v)


def _compare(v_x, v_y, v_w, h, p, tol=TOL):
    """Assert soil_forces within tol of the reference (of |F_z|); return (error, s)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ref = reference_soil_forces(v_x, v_y, v_w, h, R, B, p)
    got = soil.soil_forces(v_x, v_y, v_w, h, R, B, _params(p))
    scale = max(abs(ref["F_z"]), 1e-9)
    for key in ("F_x", "F_y", "F_z"):
        assert float(np.asarray(getattr(got, key))) == pytest.approx(ref[key], abs=tol * scale), (
            key,
            v_x,
            v_y,
            v_w,
            h,
            p,
        )
    assert float(np.asarray(got.T)) == pytest.approx(ref["T"], abs=tol * scale * R), ("T", p)
    assert float(np.asarray(got.s)) == pytest.approx(ref["s"], abs=1e-12)
    err = [abs(float(np.asarray(getattr(got, k))) - ref[k]) for k in ("F_x", "F_y", "F_z")]
    return max(*err, abs(float(np.asarray(got.T)) - ref["T"]) / R) / scale, ref["s"]


def test_soil_params_fields_match_soil_md():
    assert {f.name for f in dataclasses.fields(soil.SoilParams)} >= set(REQUIRED)


def test_random_parameters_speeds_and_sinkages():
    rng = np.random.default_rng(SEED)
    for _ in range(200):
        p = _random_params(rng)
        v_x, v_y, v_w = _speed(rng), _speed(rng) * rng.uniform(0.0, 0.5), _speed(rng)
        h = rng.uniform(0.0005, 0.07)
        _compare(v_x, v_y, v_w, h, p)


@pytest.mark.parametrize("s", [-0.6, -0.2, 0.0, 0.1, 0.3, 0.6, 0.9])
@pytest.mark.parametrize("name", ["regolith", "mars-sand", "dune-sand"])
def test_presets_across_slip(name, s):
    from pathlib import Path

    p = load_preset(Path(__file__).resolve().parents[1] / "configs" / "soil" / f"{name}.yaml")
    v_x, v_w = slip_speeds(s)
    for h in (0.004, 0.015, 0.04):
        _compare(v_x, 0.0, v_w, h, p)
        _compare(-v_x, 0.02, -v_w, h, p)  # backwards with side slip


def test_edge_cases():
    rng = np.random.default_rng(SEED + 1)
    p = _random_params(rng)
    _compare(0.0, 0.0, 0.0, 0.01, p)  # at rest: s = 0, d = +1
    _compare(0.1, 0.0, -0.05, 0.01, p)  # wheel reversed under forward travel: s clamped
    _compare(0.1, 0.0, 0.12, 2 * R, p)  # sinkage beyond the radius: clipped to r
    _compare(0.1, 0.0, 0.12, 0.0, p)  # no contact
    _compare(0.1, 0.0, 0.12, -0.01, p)


# Found by 3000 random cases of _random_params (seed 1015, cases 1387 and 2385): the only two of
# 3000 beyond 2e-3 before soil_forces split its arcs where j_x changes sign (4.1e-3 and 2.7e-3
# of F_z), both locked-and-reversed braking (s clamped at -1) with a deep wheel (0.72-0.80 r)
# and a short shear modulus (k_x ~6 mm): |j_x| / k_x makes a sharp kink there, which fixed
# Gauss-Legendre arcs do not resolve; the reference splits its integrals there too (and agrees
# with 200001-point Simpson to 1e-13).
HARD_BRAKING = [
    (
        (0.3014934865711448, -0.13906514905933304, -0.08068985295519802, 0.06115931643213284),
        {"c": 1705.469162, "phi_deg": 37.571821, "k_c": 19725.082565, "k_phi": 1171640.270484}
        | {"n0": 1.253635, "n1": 0.366604, "k_x": 0.005981, "k_y": 0.044062}
        | {"a0": 0.476629, "a1": 0.395866, "lam": 0.002831},
    ),
    (
        (0.062130058560242715, 0.007952951333629518, -0.00530904721576405, 0.0676944908612453),
        {"c": 2043.657947, "phi_deg": 38.054132, "k_c": 18021.55538, "k_phi": 2352516.422057}
        | {"n0": 1.238963, "n1": 0.396985, "k_x": 0.006285, "k_y": 0.013855}
        | {"a0": 0.356088, "a1": 0.021388, "lam": 0.105318},
    ),
]
KINK_TOL = 2e-5
"""Bound of the two cases above: 1.1e-6 and 2.6e-6 of F_z measured with the split arcs."""
BRAKING_TOL = 5e-4
"""Bound of the wide cases with s < 0 (where j_x can change sign): 1.7e-4 of F_z measured worst
over 5000 of them (seed 1018), the level of the cases without a kink; 1.7e-2 before the split."""


@pytest.mark.parametrize("case", range(len(HARD_BRAKING)))
def test_hard_braking_kink(case):
    (v_x, v_y, v_w, h), p = HARD_BRAKING[case]
    _compare(v_x, v_y, v_w, h, p, tol=KINK_TOL)


def _wide_case(rng: np.random.Generator) -> tuple[tuple[float, float, float, float], dict]:
    """A case wider than test_random_parameters_speeds_and_sinkages' draws, where kinks live.

    Sinkage to 0.95 r, either travel direction, s uniform over [-1, 1), k_x down to 3 mm.
    """
    p = _random_params(rng)
    p["k_x"] = rng.uniform(0.003, 0.05)
    v = rng.uniform(0.005, 0.5) * (1.0 if rng.random() < 0.5 else -1.0)
    v_x, v_w = slip_speeds(rng.uniform(-1.0, 1.0), v)
    v_y = rng.uniform(-0.5, 0.5) * abs(v_x)
    return (v_x, v_y, v_w, rng.uniform(0.0005, 0.95 * R)), p


@pytest.mark.parametrize(
    ("seed", "cases"), [(SEED + 2, 300), pytest.param(SEED + 3, 5000, marks=pytest.mark.slow)]
)
def test_wide_random_cases(seed, cases):
    """Every case within issue 15's 2e-3 of F_z; the braking ones (s < 0) within BRAKING_TOL.

    The worst of all (1.2e-3 over 5000, seed 1018) is a shallow wheel whose F_z nearly
    cancels (5e-4 N beside F_x = 3.7 N), where a relative error of F_z means little.
    """
    rng = np.random.default_rng(seed)
    braking = []
    for _ in range(cases):
        (v_x, v_y, v_w, h), p = _wide_case(rng)
        err, s = _compare(v_x, v_y, v_w, h, p)
        if s < 0.0:
            braking.append(err)
    assert len(braking) > cases // 3
    assert max(braking) < BRAKING_TOL
