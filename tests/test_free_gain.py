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
    assert ev.free_gain({}) == pytest.approx(0.01, rel=1e-9)
    for r in ev.run({}, "held"):
        assert np.abs(r.resid[:, 4:6]).max() < 1e-12


def test_the_common_part_stays_for_the_effects() -> None:
    """Both free wheels 2 % slow (a rolling radius, slip): nothing profiled."""
    ev = _evaluator(0.98, 0.98)
    assert ev.free_gain({}) == pytest.approx(0.0, abs=1e-12)
    held = ev.run({}, "held")
    assert np.abs(held[0].resid[:, 4:6]).max() > 0.05


def test_the_difference_is_bounded_by_the_tolerance() -> None:
    ev = _evaluator(1.2, 0.8)
    assert ev.free_gain({}) == FREE_GAIN_MAX
