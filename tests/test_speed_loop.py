"""The setpoint recursion on Python floats (``setpoint_recursion``) gives the simulator's
``advance_setpoints``, step by step on numpy, to the bit: both anti-windup forms, with the
motor saturating (a low torque limit, steps beyond it) and jittered sample times."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rover_env.config import MotorSpec
from rover_env.sim.simulator import advance_setpoints
from rover_env.sim.speed_loop import setpoint_recursion


def numpy_recursion(t: np.ndarray, phi: np.ndarray, u: np.ndarray, mo: MotorSpec) -> np.ndarray:
    """The replay's recursion as it was before stop 57: one ``advance_setpoints`` per sample."""
    sp = np.zeros(4)
    errs = np.zeros((len(t), 4))
    for k in range(len(t)):
        q = phi[k, :4]
        if k == 0:
            sp = np.clip(sp, q - mo.max_angle_error, q + mo.max_angle_error)
        else:
            dt = float(t[k] - t[k - 1])
            dq = q - phi[k - 1, :4]
            sp = advance_setpoints(sp, q, dq, dq / dt, u[k - 1], dt, mo)
        errs[k] = sp - q
    return errs


def drive(seed: int, n: int = 1500) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times with jitter, wheel angles lagging stepped targets (6 columns, as a log's)."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.018, 0.022, n))
    u = np.repeat(rng.uniform(-4.0, 4.0, (n // 50 + 1, 4)), 50, axis=0)[:n]
    w = np.zeros((n, 6))
    for k in range(1, n):  # a wheel that reaches its target at a bounded rate
        w[k, :4] = w[k - 1, :4] + np.clip(u[k - 1] - w[k - 1, :4], -0.3, 0.3)
    phi = np.cumsum(w * np.gradient(t)[:, None], axis=0)
    return t, phi, u


@pytest.mark.parametrize("form", ["clamp", "conditional", "back_calculation"])
@pytest.mark.parametrize("torque_limit", [3.0, 0.4])
def test_same_numbers_as_advance_setpoints(form: str, torque_limit: float) -> None:
    mo = replace(MotorSpec(), anti_windup=form, torque_limit=torque_limit, max_angle_error=0.2)
    if form == "back_calculation":  # its voltage line within the drive's reach
        mo = replace(mo, stall_torque=1.0, no_load_speed=4.5, tracking_ratio=0.5)
    t, phi, u = drive(7)
    got = setpoint_recursion(t, phi, u, mo)
    assert np.array_equal(got, numpy_recursion(t, phi, u, mo))
    assert np.abs(got).max() > 1e-3  # not all zero: the loop integrates something
    if form == "back_calculation":  # and its branch taken
        clamp = setpoint_recursion(t, phi, u, replace(mo, anti_windup="clamp"))
        assert np.abs(got - clamp).max() > 0.01


def test_the_forms_differ_when_the_motor_saturates() -> None:
    """Else the conditional and back-calculation branches above would be tested on the
    clamp's numbers (or on each other's)."""
    t, phi, u = drive(8)
    base = replace(MotorSpec(), torque_limit=0.4, max_angle_error=0.2)
    clamp = setpoint_recursion(t, phi, u, replace(base, anti_windup="clamp"))
    cond = setpoint_recursion(t, phi, u, replace(base, anti_windup="conditional"))
    assert np.abs(clamp - cond).max() > 0.01
    # back-calculation sees the voltage line only: bring it within the drive's reach
    line = replace(base, stall_torque=1.0, no_load_speed=4.5, speed_gain=4.0, integral_gain=16.0)
    back = setpoint_recursion(t, phi, u, replace(line, anti_windup="back_calculation"))
    for other in ("clamp", "conditional"):
        o = setpoint_recursion(t, phi, u, replace(line, anti_windup=other))
        assert np.abs(back - o).max() > 0.01, other
