"""The speed loop's setpoint recursion over a whole log, wheel by wheel on Python floats.

:func:`rover_env.sim.simulator.advance_setpoints` is the simulator's one step on the four
driven wheels; the replay runs it once per log sample to start every window from the
setpoints the loop had (:func:`rover_env.calibration.replay.setpoint_errors`), again for
every model whose loop differs (a lag, a delay, a torque limit under conditional
integration). On 4-vectors numpy's per-call cost is most of each step: 0.25 s per 50 s
log, half a replay. :func:`setpoint_recursion` does the same IEEE operations in the same
order on Python floats, so its numbers are the same to the bit (tested against
``advance_setpoints``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rover_env.config import MotorSpec

Array = NDArray[np.float64]


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
    ig, sg = motor.integral_gain, motor.speed_gain
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
                    hi = min(tl, st * (1.0 - w / nl))
                    lo = max(-tl, -st * (1.0 + w / nl))
                    tau = _clip(raw, lo, hi)
                    frozen = tau != raw and _sign(uk - w) == _sign(raw)
                    sp = _clip(sp + dq, q - err, q + err) if frozen else nxt
            col[k] = sp - q
        out[:, j] = col
    return out
