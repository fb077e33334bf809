"""The sensor-noise term of a named effect's interval (rover_env.calibration.noise_interval)."""

from __future__ import annotations

import numpy as np

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.fit import Fit
from rover_env.calibration.noise_interval import NoiseSE, draw_moments, widen_by_noise


def _design(seed: int = 0) -> tuple[np.ndarray, list[slice]]:
    rng = np.random.default_rng(seed)
    jac = rng.normal(size=(240, 2))
    jac[:12, 0] *= 30.0  # one window carries most of the first variable
    return jac, [slice(a, a + 12) for a in range(0, 240, 12)]


def test_draws_give_the_least_squares_covariance_and_bias() -> None:
    """White noise of SD s: covariance s^2 (J'J)^-1; a constant offset c in every draw moves
    the estimate by -(J'J)^-1 J'c, and the scatter does not see it."""
    jac, slices = _design()
    rng = np.random.default_rng(1)
    s, offset = 0.5, 0.5
    draws = [np.asarray(offset + s * rng.normal(size=jac.shape[0])) for _ in range(3000)]
    cov, bias = draw_moments(jac, slices, draws)
    want = s**2 * np.linalg.inv(jac.T @ jac)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(want)), rtol=0.05)
    want_bias = -np.linalg.solve(jac.T @ jac, jac.T @ np.full(jac.shape[0], offset))
    # The draws' mean is itself a mean of 3000 draws: four of its standard errors.
    mc = 4 * np.sqrt(np.diag(want) / len(draws))
    assert np.all(np.abs(bias - want_bias) < mc)
    assert np.all(np.abs(want_bias) > 10 * mc)  # the offset's move is resolved


def test_correlated_noise_within_a_window_widens_it() -> None:
    """Noise shared by a window's rows (a quantisation offset at its reference sample) adds
    coherently: the covariance is larger than white noise of the same SD gives."""
    jac, slices = _design(2)
    jac = np.abs(jac)
    rng = np.random.default_rng(3)
    white = [0.5 * rng.normal(size=jac.shape[0]) for _ in range(2000)]
    shared = [np.repeat(0.5 * rng.normal(size=len(slices)), 12) for _ in range(2000)]
    c_white, _ = draw_moments(jac, slices, white)
    c_shared, _ = draw_moments(jac, slices, shared)
    assert np.all(np.diag(c_shared) > 3 * np.diag(c_white))


def _fit(x: float, lo: float, hi: float, side: str = "") -> Fit:
    c = next(c for c in catalogue() if c.name == "torque_limit")
    a = np.array
    return Fit(
        [c],
        a([x]),
        a([lo]),
        a([hi]),
        a([(hi - lo) / 3.92]),
        0.0,
        1,
        {},
        0.0,
        "train",
        sided=(side,),
    )


def test_widening_reaches_the_noise_and_never_narrows() -> None:
    f = _fit(-0.0968, -0.150, -0.0932)
    assert widen_by_noise(f, NoiseSE(np.array([0.006]), np.array([0.0]), 6, 32))
    assert f.ci_lo[0] == -0.150  # already wider than 1.96 x 0.006 below
    assert abs(f.ci_hi[0] - (-0.0968 + 1.96 * 0.006)) < 1e-12
    assert f.noise_se is not None and f.se[0] >= 0.006
    g = _fit(-0.0968, -0.150, -0.0932)
    assert not widen_by_noise(g, NoiseSE(np.array([1e-4]), np.array([0.0]), 6, 32))
    assert (g.ci_lo[0], g.ci_hi[0]) == (-0.150, -0.0932)


def test_a_one_sided_interval_keeps_its_bound() -> None:
    """Estimate at "off" (only an upper bound claimed): the open side widens, the bound
    stays where the fit put it."""
    f = _fit(0.0, -0.01, 0.0, side="lower")
    assert widen_by_noise(f, NoiseSE(np.array([0.01]), np.array([0.01]), 6, 32))
    assert f.ci_hi[0] == 0.0
    assert abs(f.ci_lo[0] - (-1.96 * np.hypot(0.01, 0.01))) < 1e-12
