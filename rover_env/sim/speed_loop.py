"""The speed loop's setpoints: one step of the simulator's, and their recursion over a whole
log, wheel by wheel on Python floats.

:func:`advance_setpoints` is the simulator's one step on the four
driven wheels; the replay runs it once per log sample to start every window from the
setpoints the loop had (:func:`rover_env.calibration.replay.setpoint_errors`), again for
every model whose loop differs (a lag, a delay, a torque limit under conditional
integration). On 4-vectors numpy's per-call cost is most of each step: 0.25 s per 50 s
log, half a replay. :func:`setpoint_recursion` does the same IEEE operations in the same
order on Python floats, so its numbers are the same to the bit (tested against
``advance_setpoints``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rover_env.config import MotorSpec

Array = NDArray[np.float64]


def advance_setpoints(
    sp: Array, q: Array, dq: Array, w: Array, u: Array, dt: float, motor: MotorSpec
) -> Array:
    """The speed loop's integrated angle setpoints of the driven wheels after one step.

    ``sp``: the setpoints before; ``q``, ``w``: the wheel angles and rates now; ``dq``: the
    wheels' motion over the step (``w dt`` in the simulator, whose semi-implicit integrator
    moves ``q`` by exactly that; the logged increment in the replay's recursion); ``u``: the
    speed targets over the step; ``motor``: the physical motor (after the model extensions,
    so its ``torque_limit`` is the one the ``<dcmotor>`` applies).

    ``"clamp"``: ``sp + u dt`` clipped to ``max_angle_error`` of ``q``. ``"conditional"``: the
    same, then, if the motor's raw PI torque ``integral_gain (sp - q) + speed_gain (u - w)``
    lies outside what the ``<dcmotor>`` delivers (its ``saturation`` torque and its voltage
    line ``stall_torque (1 -+ w / no_load_speed)``: MuJoCo's dcmotor drives the voltage
    ``(R/K) tau + K w`` clamped to +-``voltage``) and the integrand ``u - w`` has the raw
    torque's sign, the integral ``sp - q`` is frozen: ``sp + dq`` (clipped the same way).
    ``"back_calculation"``: where the raw torque lies outside the voltage line alone (the
    current limit, ``torque_limit``, clips the torque after it, out of the loop's sight),
    the integral is bled by the excess at the tracking time ``T_t = tracking_ratio T_i``
    (``T_i = speed_gain / integral_gain``); with the line's torque ``tau`` held over the
    step, ``sp - q`` relaxes to ``tau / integral_gain + (u - w) (T_t - T_i)`` as
    ``exp(-dt / T_t)``, taken exactly (so the replay's one step per log sample follows the
    simulator's substeps), clipped the same way.
    The C plugin (``tire_plugin.c``, ``speed_loop``) does the same operations in order.
    """
    err = motor.max_angle_error
    nxt = np.clip(sp + u * dt, q - err, q + err)
    if motor.anti_windup == "clamp":
        return np.asarray(nxt, dtype=np.float64)
    raw = motor.integral_gain * (nxt - q) + motor.speed_gain * (u - w)
    line_hi = motor.stall_torque * (1.0 - w / motor.no_load_speed)
    line_lo = -motor.stall_torque * (1.0 + w / motor.no_load_speed)
    if motor.anti_windup == "back_calculation":
        tau = np.clip(raw, line_lo, line_hi)
        t_i = motor.speed_gain / motor.integral_gain
        t_t = motor.tracking_ratio * t_i
        rest = tau / motor.integral_gain + (u - w) * (t_t - t_i)
        a = math.exp(-dt / t_t)
        bled = np.clip(q + (rest + (sp - q + dq - rest) * a), q - err, q + err)
        return np.asarray(np.where(tau != raw, bled, nxt), dtype=np.float64)
    hi = np.minimum(motor.torque_limit, line_hi)
    lo = np.maximum(-motor.torque_limit, line_lo)
    tau = np.clip(raw, lo, hi)
    frozen = (tau != raw) & (np.sign(u - w) == np.sign(raw))
    held = np.clip(sp + dq, q - err, q + err)
    return np.asarray(np.where(frozen, held, nxt), dtype=np.float64)


def _clip(x: float, lo: float, hi: float) -> float:
    """``np.clip`` of one float (for numbers: the bound it passes, else ``x``)."""
    return hi if x > hi else lo if x < lo else x


def _sign(x: float) -> float:
    """``np.sign`` of one float (0 at 0)."""
    return 1.0 if x > 0 else -1.0 if x < 0 else 0.0 * x


def setpoint_recursion(t: Array, phi: Array, u: Array, motor: MotorSpec) -> Array:
    """(N, 4) setpoint minus wheel angle after :func:`advance_setpoints` at every sample.

    ``t`` (N,) sample times, ``phi`` (N, >=4) the driven wheels' logged angles (first four
    columns), ``u`` (N, 4) the targets the loop integrates over each interval (row k: from
    sample k to k + 1). Sample 0 starts from setpoint 0 clipped to the bound; each later
    sample takes the logged angle as the wheel's, its increment as the motion and the
    increment over the interval as the rate."""
    n = len(t)
    err = motor.max_angle_error
    clamp = motor.anti_windup == "clamp"
    back = motor.anti_windup == "back_calculation"
    ig, sg = motor.integral_gain, motor.speed_gain
    t_i = sg / ig
    t_t = motor.tracking_ratio * t_i
    tl, st, nl = motor.torque_limit, motor.stall_torque, motor.no_load_speed
    tt = np.asarray(t, dtype=np.float64).tolist()
    out = np.zeros((n, 4))
    for j in range(4):
        q_all = np.asarray(phi[:, j], dtype=np.float64).tolist()
        u_all = np.asarray(u[:, j], dtype=np.float64).tolist()
        col = [0.0] * n
        sp = 0.0
        for k in range(n):
            q = q_all[k]
            if k == 0:
                sp = _clip(sp, q - err, q + err)
            else:
                dt = tt[k] - tt[k - 1]
                dq = q - q_all[k - 1]
                w = dq / dt
                uk = u_all[k - 1]
                nxt = _clip(sp + uk * dt, q - err, q + err)
                if clamp:
                    sp = nxt
                else:
                    raw = ig * (nxt - q) + sg * (uk - w)
                    line_hi = st * (1.0 - w / nl)
                    line_lo = -st * (1.0 + w / nl)
                    if back:
                        tau = _clip(raw, line_lo, line_hi)
                        rest = tau / ig + (uk - w) * (t_t - t_i)
                        a = math.exp(-dt / t_t)
                        bled = _clip(q + (rest + (sp - q + dq - rest) * a), q - err, q + err)
                        sp = bled if tau != raw else nxt
                    else:
                        hi = min(tl, line_hi)
                        lo = max(-tl, line_lo)
                        tau = _clip(raw, lo, hi)
                        frozen = tau != raw and _sign(uk - w) == _sign(raw)
                        sp = _clip(sp + dq, q - err, q + err) if frozen else nxt
            col[k] = sp - q
        out[:, j] = col
    return out
