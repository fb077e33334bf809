"""The free wheels' left/right reading difference profiled out of every fit (stop 55): a
real rover's free wheels differ by about 1 % in radius and load, and read it on every
window; the common part (rolling radius, slip, soil) is the effects' and stays."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rover_env.calibration.evaluator import FREE_GAIN_MAX, Evaluator
from rover_env.calibration.replay import ReplaySettings, Window, WindowResult
from rover_env.config import load_rover


def _result(k_left: float, k_right: float, i: int) -> WindowResult:
    """A window whose logged free wheels read ``k_left`` and ``k_right`` times the model's."""
    s = np.linspace(0.0, 5.0 + i, 20)
    sim = np.zeros((20, 11))
    sim[:, 4] = sim[:, 5] = s
    log = sim.copy()
    log[:, 4] *= k_left
    log[:, 5] *= k_right
    z = np.zeros((0, 3))
    return WindowResult(Window(0, 0, 20), np.arange(20), sim - log, sim, np.zeros(0, np.intp), z, z)


def _evaluator(k_left: float, k_right: float) -> Evaluator:
    ev = Evaluator(load_rover("proto_explorer"), ReplaySettings(), [], {}, profile_free_gain=True)
    key = json.dumps({}, sort_keys=True)
    for which in ("train", "held"):
        ev.cache[(key, which)] = [_result(k_left, k_right, i) for i in range(4)]
    return ev


def test_a_left_right_difference_is_profiled_out() -> None:
    ev = _evaluator(1.01, 0.99)
    assert ev.free_gains({})[0] == pytest.approx(0.01, rel=1e-9)
    for r in ev.run({}, "held"):
        assert np.abs(r.resid[:, 4:6]).max() < 1e-12


def test_the_common_part_stays_for_the_effects() -> None:
    """Both free wheels 2 % slow (a rolling radius, slip): nothing profiled."""
    ev = _evaluator(0.98, 0.98)
    assert ev.free_gains({})[0] == pytest.approx(0.0, abs=1e-12)
    held = ev.run({}, "held")
    assert np.abs(held[0].resid[:, 4:6]).max() > 0.05


def test_the_difference_is_bounded_by_the_tolerance() -> None:
    ev = _evaluator(1.2, 0.8)
    assert ev.free_gains({})[0] == FREE_GAIN_MAX


def _common(k_left: float, k_right: float, bound: float) -> Evaluator:
    ev = _evaluator(k_left, k_right)
    ev.free_common_max = bound
    return ev


def test_a_common_reading_within_the_tolerance_is_profiled_out() -> None:
    """Stop 58: both free wheels 0.6 % larger than the driven ones (a 1 % radius tolerance)
    read as a rolling resistance unless their common reading is profiled too."""
    ev = _common(0.994, 0.994, 0.01)
    assert ev.free_gains({}) == pytest.approx((0.0, -0.006), abs=1e-12)
    for r in ev.run({}, "held"):
        assert np.abs(r.resid[:, 4:6]).max() < 1e-12


def test_common_and_difference_together() -> None:
    ev = _common(1.015, 0.995, 0.01)
    g, c = ev.free_gains({})
    assert c == pytest.approx(0.005, rel=1e-9) and g == pytest.approx(0.01, rel=1e-9)


def test_the_common_part_beyond_the_tolerance_stays_for_the_effects() -> None:
    """Both 3 % slow: 1 % is profiled, the other 2 % is left for the effects to explain."""
    ev = _common(0.97, 0.97, 0.01)
    g, c = ev.free_gains({})
    assert c == -0.01 and g == pytest.approx(0.0, abs=1e-12)
    held = ev.run({}, "held")
    s = held[0].sim[:, 4] / 0.99  # the model's own increments, before reading them 1 % slow
    assert np.allclose(held[0].resid[:, 4], 0.02 * s, rtol=1e-9, atol=1e-12)
