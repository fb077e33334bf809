"""Tests of the Gim–Nikravesh tire model (SPEC §3) and its transient-slip form.

Expected values are computed here from the paper's formulas (eqs. 10–17), written out
independently of the implementation's factored forms, never copied from its output.
"""

from __future__ import annotations

import ast
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from rover_env import tire
from rover_env.tire import (
    DEFAULT_TIRE_PARAMS,
    TireArrays,
    TireForces,
    TireParams,
    gim_magnitudes,
    lateral_factor,
    lateral_slip,
    normal_force,
    slip_ratio,
    stack_params,
    tire_forces,
    transient_forces,
    transient_step,
)

# Any RuntimeWarning (0/0, overflow) at standstill or with F_z = 0 is a bug.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

P = DEFAULT_TIRE_PARAMS
REL = 1e-12
SETTINGS = settings(max_examples=300, deadline=None)

# Speeds over the brief's range, with exact zeros and values at the regularisation edge.
speed = st.one_of(
    st.just(0.0),
    st.sampled_from([-5.0, -1e-3, -1e-9, 1e-9, 1e-3, 5.0]),
    st.floats(-5.0, 5.0, allow_nan=False, allow_infinity=False),
)
deflection = st.one_of(st.just(0.0), st.floats(-0.05, 0.1))
deflection_rate = st.one_of(st.just(0.0), st.floats(-1.0, 1.0))


@st.composite
def contact_states(draw: st.DrawFn) -> tuple[float, float, float, float, float]:
    """(v_x, v_y, v_w, delta, delta_dot), often with v_w tied to v_x (equal, opposite)."""
    v_x = draw(speed)
    tie = draw(st.sampled_from(["free", "free", "equal", "opposite", "scaled"]))
    if tie == "equal":
        v_w = v_x
    elif tie == "opposite":
        v_w = -v_x
    elif tie == "scaled":
        v_w = v_x * draw(st.floats(-2.0, 3.0))
    else:
        v_w = draw(speed)
    return v_x, draw(speed), v_w, draw(deflection), draw(deflection_rate)


def _columns(states: list[tuple[float, ...]]) -> list[np.ndarray]:
    return list(np.array(states, dtype=np.float64).T)


many_states = st.lists(contact_states(), min_size=1, max_size=12)


# ---------------------------------------------------------------------------------------
# Parameters and API shape
# ---------------------------------------------------------------------------------------


def test_module_is_numpy_only() -> None:
    tree = ast.parse(Path(tire.__file__).read_text())
    imported: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, "relative import"
            imported.add((node.module or "").split(".")[0])
    assert not imported & {"mujoco", "gymnasium", "rover_env"}


def test_default_params_are_the_papers_table_3() -> None:
    assert (P.mu_x, P.mu_y, P.C_s, P.C_alpha, P.C_z, P.D_z) == (0.4, 0.5, 100.0, 50.0, 1000.0, 72.2)
    assert (P.v_eps, P.sigma_x, P.sigma_y, P.D_x, P.D_y) == (1e-3, 0.02, 0.02, 100.0, 100.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        P.mu_x = 1.0  # type: ignore[misc]
    assert not hasattr(P, "__dict__")  # slots


ALL_FIELDS = [f.name for f in dataclasses.fields(TireParams)]
DAMPINGS = {"D_x", "D_y", "D_z"}


@pytest.mark.parametrize("name", ALL_FIELDS)
@pytest.mark.parametrize("bad", [-0.1, math.nan, math.inf, -math.inf])
def test_params_reject_bad_values(name: str, bad: float) -> None:
    with pytest.raises(ValueError, match=rf"TireParams\.{name} must be") as info:
        TireParams(**{name: bad})
    assert repr(bad) in str(info.value)


def test_params_k_re_is_a_fraction() -> None:
    assert TireParams(k_re=1.0).k_re == 1.0
    with pytest.raises(ValueError, match=r"TireParams\.k_re must be in \[0, 1\], got 1\.5"):
        TireParams(k_re=1.5)


def test_params_error_message_format() -> None:
    with pytest.raises(ValueError) as info:
        TireParams(mu_x=-0.1)
    assert str(info.value) == "TireParams.mu_x must be > 0, got -0.1"


@pytest.mark.parametrize("name", ALL_FIELDS)
def test_params_zero_allowed_only_for_dampings(name: str) -> None:
    if name in (*DAMPINGS, "k_re", "v_floor", "lateral_split"):
        assert getattr(TireParams(**{name: 0.0}), name) == 0.0
    else:
        with pytest.raises(ValueError, match=rf"TireParams\.{name} must be > 0, got 0.0"):
            TireParams(**{name: 0.0})


def test_tire_forces_fields() -> None:
    assert TireForces._fields == ("F_x", "F_y", "F_z", "S", "S_alpha")


def test_broadcasting_to_common_shape() -> None:
    v_x = np.linspace(-1.0, 1.0, 4)  # (4,)
    delta = np.array([[0.0], [0.01], [0.03]])  # (3, 1)
    out = tire_forces(v_x, 0.1, 0.5, delta, 0.0)
    for value in out:
        assert isinstance(value, np.ndarray)
        assert value.shape == (3, 4)
    scalar = tire_forces(0.2, 0.0, 0.25, 0.027, 0.0)
    assert all(np.shape(value) == () for value in scalar)


# ---------------------------------------------------------------------------------------
# Steady-state properties over wide random inputs
# ---------------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)  # each example is a batch of up to 12 contacts
@given(states=many_states)
def test_friction_bounds_and_finiteness(states: list[tuple[float, ...]]) -> None:
    v_x, v_y, v_w, delta, delta_dot = _columns(states)
    out = tire_forces(v_x, v_y, v_w, delta, delta_dot)
    for value in out:
        assert np.all(np.isfinite(value))
    assert np.all(out.F_z >= 0.0)
    assert np.all(np.abs(out.F_x) <= P.mu_x * out.F_z * (1.0 + REL))
    assert np.all(np.abs(out.F_y) <= P.mu_y * out.F_z * (1.0 + REL))
    assert np.all(np.abs(out.S) <= 1.0)
    assert np.all(out.S_alpha >= 0.0)
    # Both forces oppose the sliding of the contact patch.
    assert np.all(out.F_y * v_y <= 0.0)
    assert np.all(out.F_x * (v_x - v_w) <= 0.0)


@settings(max_examples=100, deadline=None)
@given(
    states=many_states,
    mu=st.lists(st.tuples(st.floats(0.01, 2.0), st.floats(0.01, 2.0)), min_size=1, max_size=1),
)
def test_friction_bounds_with_per_wheel_mu(
    states: list[tuple[float, ...]], mu: list[tuple[float, float]]
) -> None:
    v_x, v_y, v_w, delta, delta_dot = _columns(states)
    # One friction coefficient pair per wheel, varied along the batch.
    mu_x = mu[0][0] * np.linspace(0.5, 1.0, v_x.size)
    mu_y = mu[0][1] * np.linspace(1.0, 0.5, v_x.size)
    out = tire_forces(v_x, v_y, v_w, delta, delta_dot, mu_x=mu_x, mu_y=mu_y)
    assert np.all(np.abs(out.F_x) <= mu_x * out.F_z * (1.0 + REL))
    assert np.all(np.abs(out.F_y) <= mu_y * out.F_z * (1.0 + REL))


def test_standstill_is_finite_and_force_free() -> None:
    out = tire_forces(0.0, 0.0, 0.0, 0.027, 0.0)
    assert float(out.F_z) == pytest.approx(27.0)
    assert (float(out.F_x), float(out.F_y), float(out.S), float(out.S_alpha)) == (0, 0, 0, 0)


@SETTINGS
@given(v_x=speed, v_y=speed, delta=deflection, delta_dot=deflection_rate)
def test_zero_slip_gives_zero_longitudinal_force(
    v_x: float, v_y: float, delta: float, delta_dot: float
) -> None:
    out = tire_forces(v_x, v_y, v_x, delta, delta_dot)
    assert out.F_x == 0.0
    assert out.S == 0.0


@SETTINGS
@given(v_x=speed, v_w=speed, delta=deflection, delta_dot=deflection_rate)
def test_zero_lateral_speed_gives_zero_lateral_force(
    v_x: float, v_w: float, delta: float, delta_dot: float
) -> None:
    out = tire_forces(v_x, 0.0, v_w, delta, delta_dot)
    assert out.F_y == 0.0
    assert out.S_alpha == 0.0


loaded = st.tuples(st.floats(1e-3, 0.1), st.floats(-0.01, 1.0))  # delta, delta_dot: F_z > 0
magnitude = st.floats(1e-3, 5.0)
gap = st.floats(1e-2, 5.0)


def _loaded_forces(v_x: float, v_w: float, load: tuple[float, float]) -> TireForces:
    delta, delta_dot = load
    assume(P.C_z * delta + P.D_z * delta_dot > 1e-6)
    out = tire_forces(v_x, 0.0, v_w, delta, delta_dot)
    assert out.F_z > 0.0
    return out


@SETTINGS
@given(v=magnitude, d=gap, load=loaded)
def test_forward_spin_pushes_forward(v: float, d: float, load: tuple[float, float]) -> None:
    out = _loaded_forces(v, v + d, load)  # wheel faster than the forward travel
    assert out.F_x > 0.0
    assert out.S < 0.0


@SETTINGS
@given(v=magnitude, frac=st.floats(0.0, 0.99), load=loaded)
def test_forward_skid_brakes(v: float, frac: float, load: tuple[float, float]) -> None:
    out = _loaded_forces(v, v * frac, load)  # 0 <= v_w < v_x
    assert out.F_x < 0.0
    assert out.S > 0.0


@SETTINGS
@given(v=magnitude, d=gap, load=loaded)
def test_reverse_spin_pushes_backward(v: float, d: float, load: tuple[float, float]) -> None:
    out = _loaded_forces(-v, -v - d, load)  # spinning backwards faster than reversing
    assert out.F_x < 0.0
    assert out.S < 0.0


@SETTINGS
@given(v=magnitude, frac=st.floats(0.0, 0.99), load=loaded)
def test_reverse_skid_brakes(v: float, frac: float, load: tuple[float, float]) -> None:
    out = _loaded_forces(-v, -v * frac, load)  # v_x < v_w <= 0
    assert out.F_x > 0.0
    assert out.S > 0.0


def test_slip_ratio_opposite_signs_clamp_and_tie_convention() -> None:
    # Wheel turning backwards while the hub rolls forward, the wheel's speed dominant:
    # the travel direction is the wheel's, and it spins: S = -1.
    assert slip_ratio(1.0, -2.0, 1e-3) == -1.0
    # Hub dominant: travel is forward, the wheel turns against it: a skid, S = +1.
    assert slip_ratio(2.0, -1.0, 1e-3) == 1.0
    # Equal and opposite: sign(v_x) decides (documented convention): S = +1 both ways.
    assert slip_ratio(1.5, -1.5, 1e-3) == 1.0
    assert slip_ratio(-1.5, 1.5, 1e-3) == 1.0


@SETTINGS
@given(v_x=speed, v_w=speed)
def test_slip_ratio_matches_eq_10_away_from_standstill(v_x: float, v_w: float) -> None:
    assume(max(abs(v_x), abs(v_w)) >= 1e-3)
    s = float(slip_ratio(v_x, v_w, P.v_eps))
    if v_x > 0.0 and v_w > 0.0:  # the paper's forward-motion case, eq. (10)
        expected = (v_x - v_w) / v_x if v_x > v_w else (v_x - v_w) / v_w
        assert s == pytest.approx(expected, rel=1e-12, abs=1e-15)
    assert abs(s) <= 1.0


def test_slip_ratio_regularised_at_standstill() -> None:
    v_eps = 1e-3
    # Both speeds below v_eps: the denominator is v_eps, so S -> 0 continuously.
    assert float(slip_ratio(2e-4, 1e-4, v_eps)) == pytest.approx((2e-4 - 1e-4) / v_eps)
    assert float(slip_ratio(0.0, 0.0, v_eps)) == 0.0


@pytest.mark.parametrize("name", ["v_x", "v_y", "v_w", "delta", "delta_dot", "mu_x", "mu_y"])
@pytest.mark.parametrize(
    ("bad", "word"), [(math.nan, "NaN"), (math.inf, "inf"), (-math.inf, "inf")]
)
def test_non_finite_input_is_named(name: str, bad: float, word: str) -> None:
    args = {
        "v_x": np.full(5, 0.3),
        "v_y": np.full(5, 0.01),
        "v_w": np.full(5, 0.35),
        "delta": np.full(5, 0.02),
        "delta_dot": np.zeros(5),
        "mu_x": np.full(5, 0.4),
        "mu_y": np.full(5, 0.5),
    }
    args[name][3] = bad
    with pytest.raises(ValueError, match=rf"tire_forces: {name} contains {word} at index \(3,\)"):
        tire_forces(**args)  # type: ignore[arg-type]


def test_non_finite_scalar_input_is_named() -> None:
    with pytest.raises(ValueError, match=r"tire_forces: delta_dot contains NaN"):
        tire_forces(0.0, 0.0, 0.0, 0.01, math.nan)


# ---------------------------------------------------------------------------------------
# Closed-form checks against the paper's equations
# ---------------------------------------------------------------------------------------


def _eq13_full(slip: float, F_z: float, mu: float, stiffness: float) -> float:
    """Eq. (13) as printed, with (12) and (15): C S l^2 + mu F_z (1 - 3 l^2 + 2 l^3)."""
    slip_c = 3.0 * mu * F_z / stiffness
    l_n = max(0.0, 1.0 - slip / slip_c)
    return stiffness * slip * l_n**2 + mu * F_z * (1.0 - 3.0 * l_n**2 + 2.0 * l_n**3)


@SETTINGS
@given(
    slip=st.floats(0.0, 2.0),
    slip_alpha=st.floats(0.0, 5.0),
    F_z=st.floats(0.1, 200.0),
    mu_x=st.floats(0.05, 1.5),
    mu_y=st.floats(0.05, 1.5),
)
def test_eq13_full_form_equals_simplified_form(
    slip: float, slip_alpha: float, F_z: float, mu_x: float, mu_y: float
) -> None:
    mag_x, mag_y = gim_magnitudes(slip, slip_alpha, F_z, mu_x, mu_y, P)
    full_x = _eq13_full(slip, F_z, mu_x, P.C_s)
    full_y = _eq13_full(slip_alpha, F_z, mu_y, P.C_alpha)
    # The algebraic identity itself, in plain floats: with (15), (13) = mu F_z (1 - l^3).
    l_x = max(0.0, 1.0 - slip / (3.0 * mu_x * F_z / P.C_s))
    assert full_x == pytest.approx(mu_x * F_z * (1.0 - l_x**3), rel=1e-9, abs=1e-12 * F_z)
    assert float(mag_x) == pytest.approx(full_x, rel=1e-9, abs=1e-12 * F_z)
    assert float(mag_y) == pytest.approx(full_y, rel=1e-9, abs=1e-12 * F_z)


@SETTINGS
@given(F_z=st.floats(0.1, 200.0), mu=st.floats(0.05, 1.5), k=st.floats(1.0, 50.0))
def test_full_sliding_beyond_critical_slip(F_z: float, mu: float, k: float) -> None:
    s_c = 3.0 * mu * F_z / P.C_s  # eq. (15)
    s_alpha_c = 3.0 * mu * F_z / P.C_alpha  # eq. (16)
    mag_x, mag_y = gim_magnitudes(k * s_c, k * s_alpha_c, F_z, mu, mu, P)
    assert float(mag_x) == pytest.approx(mu * F_z, rel=REL)
    assert float(mag_y) == pytest.approx(mu * F_z, rel=REL)
    # Just below the critical slip part of the patch still grips: strictly less.
    below_x, below_y = gim_magnitudes(0.99 * s_c, 0.99 * s_alpha_c, F_z, mu, mu, P)
    assert float(below_x) < mu * F_z
    assert float(below_y) < mu * F_z


@pytest.mark.parametrize("F_z", [1.0, 27.0, 150.0])
def test_small_slip_slope_is_cornering_stiffness(F_z: float) -> None:
    h = 1e-7
    mag_x, mag_y = gim_magnitudes(h, h, F_z, P.mu_x, P.mu_y, P)
    assert float(mag_x) / h == pytest.approx(P.C_s, rel=1e-5)
    assert float(mag_y) / h == pytest.approx(P.C_alpha, rel=1e-5)
    zero_x, zero_y = gim_magnitudes(0.0, 0.0, F_z, P.mu_x, P.mu_y, P)
    assert float(zero_x) == 0.0
    assert float(zero_y) == 0.0


def test_zero_normal_force_gives_zero_forces() -> None:
    mag_x, mag_y = gim_magnitudes(np.array([0.0, 0.3, 1.0]), 0.5, 0.0, 0.4, 0.5, P)
    assert np.all(mag_x == 0.0)
    assert np.all(mag_y == 0.0)


@SETTINGS
@given(delta=st.floats(1e-6, 0.1))
def test_normal_force_at_rest_is_spring(delta: float) -> None:
    assert float(normal_force(delta, 0.0, P)) == pytest.approx(P.C_z * delta, rel=REL)


def test_normal_force_no_tension_and_no_contactless_damping() -> None:
    # Compressed but extending fast: the damper would pull; eq. (17) floors at 0.
    assert float(normal_force(0.01, -1.0, P)) == 0.0  # 10 - 72.2 < 0
    # Out of contact yet approaching: no damping-only force.
    assert float(normal_force(-0.01, 1.0, P)) == 0.0
    assert float(normal_force(0.0, 1.0, P)) == 0.0
    # In contact and compressing: spring plus damper.
    assert float(normal_force(0.02, 0.1, P)) == pytest.approx(1000.0 * 0.02 + 72.2 * 0.1)


def test_hand_computed_spinning_example() -> None:
    # v_x = 0.2, v_w = 0.25 m/s (spinning, forward), v_y = 0.01 m/s, static 27 mm: 27 N.
    out = tire_forces(0.2, 0.01, 0.25, 0.027, 0.0)
    S = (0.2 - 0.25) / 0.25  # eq. (10), v_x < v_w: divide by v_w -> -0.2
    F_z = 1000.0 * 0.027  # eq. (17) at rest -> 27 N
    S_c = 3 * 0.4 * 27.0 / 100.0  # eq. (15) -> 0.324
    l_nx = 1 - 0.2 / S_c  # eq. (12) -> 0.3827
    F_x = 100.0 * 0.2 * l_nx**2 + 0.4 * 27.0 * (1 - 3 * l_nx**2 + 2 * l_nx**3)  # eq. (13)
    tan_alpha = 0.01 / 0.2
    S_alpha = (1 - 0.2) * tan_alpha  # eq. (11), spinning -> 0.04
    S_alpha_c = 3 * 0.5 * 27.0 / 50.0  # eq. (16) -> 0.81
    l_ny = 1 - S_alpha / S_alpha_c
    F_y = 50.0 * S_alpha * l_ny**2 + 0.5 * 27.0 * (1 - 3 * l_ny**2 + 2 * l_ny**3)  # eq. (14)

    assert S == pytest.approx(-0.2)
    assert F_x == pytest.approx(10.1946, abs=1e-4)  # by hand: 2.9294 + 10.8 * 0.67270
    assert float(out.S) == pytest.approx(S, rel=1e-12)
    assert float(out.F_z) == pytest.approx(F_z, rel=1e-12)
    assert float(out.F_x) == pytest.approx(+F_x, rel=1e-12)  # spinning drives forward
    assert float(out.S_alpha) == pytest.approx(S_alpha, rel=1e-12)
    assert float(out.F_y) == pytest.approx(-F_y, rel=1e-12)  # opposes v_y > 0


def test_hand_computed_skid_and_reverse_examples() -> None:
    # Skid: v_x = 0.25, v_w = 0.2 -> S = (0.25 - 0.2) / 0.25 = +0.2: same magnitude, braking.
    l_nx = 1 - 0.2 / (3 * 0.4 * 27.0 / 100.0)
    F_x = 0.4 * 27.0 * (1 - l_nx**3)
    skid = tire_forces(0.25, 0.0, 0.2, 0.027, 0.0)
    assert float(skid.S) == pytest.approx(0.2, rel=1e-12)
    assert float(skid.F_x) == pytest.approx(-F_x, rel=1e-12)
    # Reverse spinning: v_x = -0.2, v_w = -0.25 -> S = -0.2, pushing backwards.
    rev = tire_forces(-0.2, 0.0, -0.25, 0.027, 0.0)
    assert float(rev.S) == pytest.approx(-0.2, rel=1e-12)
    assert float(rev.F_x) == pytest.approx(-F_x, rel=1e-12)
    # Skidding lateral slip is |tan alpha| itself: 0.01 / 0.25.
    assert float(lateral_slip(0.25, 0.01, 0.2, 0.2, 1e-3)) == pytest.approx(0.04, rel=1e-12)


# ---------------------------------------------------------------------------------------
# Transient (relaxation-length) form
# ---------------------------------------------------------------------------------------


def _run(
    u_x: np.ndarray,
    u_y: np.ndarray,
    v: tuple[np.ndarray, np.ndarray, np.ndarray],
    F_z: np.ndarray,
    dt: float,
    steps: int,
    params: TireParams | TireArrays = P,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    du_x = du_y = np.zeros_like(u_x)
    for _ in range(steps):
        u_x, u_y, du_x, du_y = transient_step(u_x, u_y, *v, F_z, dt, params)
    return u_x, u_y, du_x, du_y


same_sign_wheels = st.lists(
    st.tuples(
        st.floats(0.01, 5.0),  # |v_x|
        st.one_of(st.just(0.0), st.just(1.0), st.floats(0.0, 3.0)),  # v_w / v_x
        st.one_of(st.just(0.0), st.floats(-5.0, 5.0)),  # v_y
        st.floats(1e-3, 0.1),  # delta
        st.sampled_from([-1.0, 1.0]),  # direction of travel
    ),
    min_size=1,
    max_size=6,
)


@settings(max_examples=100, deadline=None)
@given(wheels=same_sign_wheels)
def test_transient_converges_to_steady_forces(wheels: list[tuple[float, ...]]) -> None:
    speed_abs, ratio, v_y, delta, sign = np.array(wheels, dtype=np.float64).T
    v_x = sign * speed_abs
    v_w = v_x * ratio
    F_z = P.C_z * delta
    # 60 relaxation lengths of the slowest wheel, in 200 exact-exponential steps.
    slowest = np.min(np.maximum(np.abs(v_x), np.abs(v_w)))
    dt = 60.0 * P.sigma_x / slowest / 200
    zero = np.zeros_like(v_x)
    u_x, u_y, du_x, du_y = _run(zero, zero, (v_x, v_y, v_w), F_z, dt, 200)
    f_x, f_y = transient_forces(u_x, u_y, du_x, du_y, F_z, P)
    steady = tire_forces(v_x, v_y, v_w, delta, 0.0)
    np.testing.assert_allclose(f_x, steady.F_x, rtol=1e-9, atol=1e-12 * F_z.max())
    np.testing.assert_allclose(f_y, steady.F_y, rtol=1e-9, atol=1e-12 * F_z.max())


@SETTINGS
@given(
    v_x=st.floats(0.01, 5.0),
    ratio=st.floats(0.0, 3.0),
    v_y=st.floats(-5.0, 5.0),
    sign=st.sampled_from([-1.0, 1.0]),
)
def test_transient_steady_state_is_eq_10_and_11(
    v_x: float, ratio: float, v_y: float, sign: float
) -> None:
    # Analytic fixed point of the ODE: u_x / sigma = (v_x - v_w) / V, u_y / sigma = v_y / V.
    v_x *= sign
    v_w = ratio * v_x
    V = max(abs(v_x), abs(v_w))
    u_x = P.sigma_x * (v_x - v_w) / V
    u_y = P.sigma_y * v_y / V
    F_z = 27.0
    f_x, f_y = transient_forces(u_x, u_y, 0.0, 0.0, F_z, P)
    steady = tire_forces(v_x, v_y, v_w, F_z / P.C_z, 0.0)
    assert float(f_x) == pytest.approx(float(steady.F_x), rel=1e-9, abs=1e-12)
    assert float(f_y) == pytest.approx(float(steady.F_y), rel=1e-9, abs=1e-12)


@SETTINGS
@given(
    u=st.one_of(st.just(0.0), st.floats(1e-12, 1e-7), st.floats(-1e-7, -1e-12)),
    F_z=st.floats(1.0, 100.0),
)
def test_standstill_tire_is_a_spring(u: float, F_z: float) -> None:
    f_x, f_y = transient_forces(u, u, 0.0, 0.0, F_z, P)
    # Linear spring C / sigma for small deflections; Gim's law softens it by a relative
    # amount of about q = (|u| / sigma) / slip_c, so that is the tolerance.
    q_x = abs(u) / P.sigma_x / (3.0 * P.mu_x * F_z / P.C_s)
    q_y = abs(u) / P.sigma_y / (3.0 * P.mu_y * F_z / P.C_alpha)
    spring_x = -P.C_s / P.sigma_x * u
    spring_y = -P.C_alpha / P.sigma_y * u
    assert float(f_x) == pytest.approx(spring_x, rel=1.01 * q_x + 1e-12, abs=1e-300)
    assert float(f_y) == pytest.approx(spring_y, rel=1.01 * q_y + 1e-12, abs=1e-300)
    assert abs(float(f_x)) <= abs(spring_x) * (1 + REL)  # never stiffer than the spring


def test_parked_rover_holds_without_creep() -> None:
    F_z = np.full(2, 27.0)
    zero = np.zeros(2)
    # A brief slide of 1e-6 m, then standstill: the deflection (and the force) stays.
    push = (np.array([1e-3, -1e-3]), np.array([5e-4, 0.0]), zero)
    u_x, u_y, _, _ = _run(zero, zero, push, F_z, 1e-3, 1)
    held = _run(u_x, u_y, (zero, zero, zero), F_z, 1e-3, 1000)
    np.testing.assert_array_equal(held[0], u_x)
    np.testing.assert_array_equal(held[1], u_y)
    np.testing.assert_array_equal(held[2], 0.0)
    f_x, f_y = transient_forces(*held, F_z, P)
    np.testing.assert_allclose(f_x, -P.C_s / P.sigma_x * u_x, rtol=1e-3)
    assert np.all(f_x * np.array([1.0, -1.0]) < 0.0)  # holds against the push
    assert f_y[0] < 0.0
    assert f_y[1] == 0.0


@SETTINGS
@given(
    u_x=st.floats(-0.05, 0.05),
    u_y=st.floats(-0.05, 0.05),
    v_x=speed,
    v_y=speed,
    v_w=speed,
    F_z=st.floats(0.0, 200.0),
    dt=st.sampled_from([1e-4, 1e-2, 1.0, 1e3, 1e9]),
)
def test_transient_step_never_grows_beyond_steady_or_bounds(
    u_x: float, u_y: float, v_x: float, v_y: float, v_w: float, F_z: float, dt: float
) -> None:
    new_x, new_y, du_x, du_y = transient_step(u_x, u_y, v_x, v_y, v_w, F_z, dt, P)
    for value in (new_x, new_y, du_x, du_y):
        assert np.isfinite(value)
    lim_x = P.sigma_x * min(1.0, 3.0 * P.mu_x * F_z / P.C_s)
    lim_y = P.sigma_y * 3.0 * P.mu_y * F_z / P.C_alpha
    assert abs(new_x) <= lim_x * (1 + REL)
    assert abs(new_y) <= lim_y * (1 + REL)
    V = max(abs(v_x), abs(v_w))
    if V > 0.0:
        # The exact solution moves monotonically from u towards the fixed point.
        star_x = P.sigma_x * (v_x - v_w) / V
        star_y = P.sigma_y * v_y / V
        assert min(u_x, star_x) - 1e-15 <= new_x or abs(new_x) == pytest.approx(lim_x)
        assert new_x <= max(u_x, star_x) + 1e-15 or abs(new_x) == pytest.approx(lim_x)
        assert min(u_y, star_y) - 1e-15 <= new_y or abs(new_y) == pytest.approx(lim_y)
        assert new_y <= max(u_y, star_y) + 1e-15 or abs(new_y) == pytest.approx(lim_y)
    np.testing.assert_allclose(du_x, (new_x - u_x) / dt, rtol=1e-12)


def test_slip_floor_regularises_the_steady_slip_below_it() -> None:
    # Below the floor the transient form settles at Gim's regularised slip
    # (v_x - v_w) / max(|v_x|, |v_w|, v_floor); above it the floor changes nothing.
    fl = dataclasses.replace(P, v_floor=0.05)
    v_x = np.array([0.01, -0.02, 0.2])
    v_w = np.array([0.02, -0.01, 0.25])
    v_y = np.array([0.004, 0.0, 0.01])
    ux = uy = np.zeros(3)
    vx = vy = np.zeros(3)
    for _ in range(1500):  # 15 s: 37 of the slowest relaxation times, sigma / v_floor
        ux, uy, _, _ = transient_step(ux, uy, v_x, v_y, v_w, 27.0, 0.01, fl)
        vx, vy, _, _ = transient_step(vx, vy, v_x, v_y, v_w, 27.0, 0.01, P)
    den = np.maximum(np.maximum(np.abs(v_x), np.abs(v_w)), 0.05)
    np.testing.assert_allclose(ux / fl.sigma_x, (v_x - v_w) / den, rtol=1e-9)
    np.testing.assert_allclose(uy / fl.sigma_y, v_y / den, rtol=1e-9)
    np.testing.assert_allclose(ux[2], vx[2], rtol=1e-12)  # 0.25 m/s: above the floor
    # at 2 cm/s the floor lowers the slip: 0.2 against 0.5 (held at full sliding, 0.32)
    assert abs(ux[0]) < 0.7 * abs(vx[0])


def test_huge_lambda_dt_is_stable() -> None:
    # lambda dt = 5 / 0.02 * 1e6: an explicit Euler step would blow up by 2.5e8.
    u0 = np.array([0.01, -0.01, 0.004])
    v_x = np.array([5.0, -5.0, 5.0])
    v_w = np.array([5.0, -5.0, 4.0])
    v_y = np.zeros(3)
    u_x, u_y = u0, u0
    for _ in range(50):
        u_x, u_y, _, _ = transient_step(u_x, u_y, v_x, v_y, v_w, 27.0, 1e6, P)
        assert np.all(np.isfinite(u_x))
        assert np.all(np.abs(u_x) <= np.abs(u0) + 1e-15)
    # Pure decay where there is no slip, and the exact fixed point where there is.
    np.testing.assert_array_equal(u_x[:2], 0.0)
    assert u_x[2] == pytest.approx(P.sigma_x * (5.0 - 4.0) / 5.0, rel=1e-12)
    np.testing.assert_array_equal(u_y, 0.0)


def test_zero_normal_force_relaxes_state_and_zeroes_force() -> None:
    u = np.array([0.01, -0.02, 0.0])
    u_x, u_y, du_x, du_y = transient_step(u, u, 1.0, 0.3, 2.0, 0.0, 1e-3, P)
    np.testing.assert_array_equal(u_x, 0.0)
    np.testing.assert_array_equal(u_y, 0.0)
    f_x, f_y = transient_forces(u, u, du_x + 5.0, du_y - 5.0, 0.0, P)
    np.testing.assert_array_equal(f_x, 0.0)
    np.testing.assert_array_equal(f_y, 0.0)


@SETTINGS
@given(
    u_x=st.floats(-0.1, 0.1),
    u_y=st.floats(-0.1, 0.1),
    du_x=st.floats(-10.0, 10.0),
    du_y=st.floats(-10.0, 10.0),
    F_z=st.floats(0.0, 200.0),
    mu_x=st.floats(0.01, 2.0),
    mu_y=st.floats(0.01, 2.0),
)
def test_transient_forces_respect_friction_bound(
    u_x: float, u_y: float, du_x: float, du_y: float, F_z: float, mu_x: float, mu_y: float
) -> None:
    f_x, f_y = transient_forces(u_x, u_y, du_x, du_y, F_z, P, mu_x=mu_x, mu_y=mu_y)
    assert abs(float(f_x)) <= mu_x * F_z * (1 + REL)
    assert abs(float(f_y)) <= mu_y * F_z * (1 + REL)
    # Patch damping opposes the deflection rate when the spring part is zero.
    zero_x, _ = transient_forces(0.0, 0.0, du_x, 0.0, F_z, P, mu_x=mu_x, mu_y=mu_y)
    assert float(zero_x) * du_x <= 0.0


def test_per_wheel_params_match_scalar_params() -> None:
    rng = np.random.default_rng(1)
    v_x, v_y, v_w = rng.uniform(-2.0, 2.0, (3, 6))
    u_x, u_y = rng.uniform(-0.01, 0.01, (2, 6))
    F_z = rng.uniform(0.0, 60.0, 6)
    ref_step = transient_step(u_x, u_y, v_x, v_y, v_w, F_z, 1e-3, P)
    ref_forces = transient_forces(*ref_step, F_z, P)
    for params in (P.as_arrays(), P.as_arrays(6), stack_params([P] * 6)):
        got_step = transient_step(u_x, u_y, v_x, v_y, v_w, F_z, 1e-3, params)
        np.testing.assert_allclose(got_step, ref_step, rtol=1e-14, atol=1e-300)
        got_forces = transient_forces(*got_step, F_z, params)
        np.testing.assert_allclose(got_forces, ref_forces, rtol=1e-14, atol=1e-300)
    # Different constants per wheel: wheel 0 grips twice as hard as the default.
    wheels = stack_params([TireParams(mu_x=0.8)] + [P] * 5)
    f_x, _ = transient_forces(np.full(6, 0.02), 0.0, 0.0, 0.0, 27.0, wheels)
    assert f_x[0] == pytest.approx(-0.8 * 27.0)
    np.testing.assert_allclose(f_x[1:], -0.4 * 27.0)


def test_patch_damping_adds_minus_d_times_rate() -> None:
    # No deflection, slow deflection rate: the force is the damper alone, within mu F_z.
    rate = np.array([0.01, -0.02])
    f_x, f_y = transient_forces(0.0, 0.0, rate, -rate, 27.0, P)
    np.testing.assert_allclose(f_x, -P.D_x * rate, rtol=1e-12)
    np.testing.assert_allclose(f_y, P.D_y * rate, rtol=1e-12)
    undamped = TireParams(D_x=0.0, D_y=0.0)
    f_x, f_y = transient_forces(0.0, 0.0, rate, -rate, 27.0, undamped)
    np.testing.assert_array_equal(f_x, 0.0)
    np.testing.assert_array_equal(f_y, 0.0)


def test_lateral_split_is_a_switch() -> None:
    assert TireParams(lateral_split=1.0).lateral_split == 1.0
    with pytest.raises(ValueError, match=r"TireParams\.lateral_split must be 0 or 1, got 0\.5"):
        TireParams(lateral_split=0.5)


@pytest.mark.parametrize(
    ("v_x", "v_w"),
    [(0.05, -0.12), (0.10, 0.14), (0.12, 0.05), (-0.04, 0.10), (0.10, -0.06)],
    ids=["spins-against-travel", "spins", "skids", "spins-backward-hub", "turns-against-hub"],
)
def test_lateral_split_settles_on_eq_11_for_every_sign(v_x: float, v_w: float) -> None:
    """With lateral_split 1 the transient form settles on SPEC's steady forces (eq. 11's
    spin/skid split with tan(alpha) = v_y / v_x) for every sign of v_x and v_w; the default
    form does only where they share a sign or the hub's speed dominates (stop 63: a pivot's
    driven wheels turn against their hubs, faster)."""
    v_y, delta = 0.01, 0.027
    F_z = P.C_z * delta
    split = dataclasses.replace(P, lateral_split=1.0)

    def settled(params: TireParams) -> float:
        ux = uy = np.zeros(1)
        for _ in range(20000):  # 20 s of 1 ms steps: hundreds of relaxation times
            ux, uy, uxd, uyd = transient_step(ux, uy, v_x, v_y, v_w, F_z, 1e-3, params)
        lat = lateral_factor(v_x, v_w, params)
        return float(transient_forces(ux, uy, uxd, uyd, F_z, params, lat_factor=lat)[1][0])

    want = tire_forces(v_x, v_y, v_w, delta, 0.0, split).F_y
    assert abs(float(want)) > 0.0 or v_w * v_x < 0  # a lateral force to compare (or none: spun)
    np.testing.assert_allclose(settled(split), want, rtol=1e-6, atol=1e-9)
    if np.sign(v_x) != np.sign(v_w) and abs(v_w) > abs(v_x):  # the wheel's speed dominates
        assert abs(settled(P) - float(want)) > 0.05 * abs(float(want)) + 1e-3
    else:  # both forms divide by the hub's speed or agree on eq. (11)
        np.testing.assert_allclose(settled(P), want, rtol=1e-6, atol=1e-9)
