"""Drive plans of calibration logs: speed-target schedules of the driven wheels.

Shared by the project's log generator (:mod:`rover_env.generators.make_logs`), the second,
deliberately different one (:mod:`rover_env.generators.foreign_logs`) and the proposed
deciding drives (:mod:`rover_env.calibration.evidence`), so none of them imports another.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

__all__ = ["PLANS", "drive_schedule", "drive_targets"]

PLANS = ("test", "reversals", "turn-accel", "steps", "speeds", "straight", "accel")

Segment = tuple[float, tuple[float, float]]  # (duration s, (left, right) rad/s)


def _test_plan(rng: np.random.Generator, vmax: float) -> list[Segment]:
    u = lambda lo, hi: float(rng.uniform(lo, hi))  # noqa: E731
    v1, v2, v3 = u(0.35, 0.5) * vmax, u(0.55, 0.7) * vmax, u(0.8, 0.95) * vmax
    d = u(0.2, 0.35) * vmax
    blocks: list[list[Segment]] = [
        [(u(4, 6), (v1, v1))],  # step from rest, straight
        [(u(4, 6), (v2 - d, v2 + d))],  # left turn
        [(u(3, 5), (v3, v3))],  # fast straight (acceleration step)
        [(u(4, 6), (v2 + d, v2 - d))],  # right turn
        [(u(2, 3), (0.0, 0.0))],  # brake to a stop
        [(u(4, 5), (-v2, -v2))],  # reverse
        [(u(3, 4), (-v1 - d, -v1 + d))],  # reverse turning
        [(u(1.5, 2.5), (0.0, 0.0))],
        [(u(3, 4), (-0.4 * vmax, 0.4 * vmax))],  # pivot turn left
        [(u(3, 4), (0.4 * vmax, -0.4 * vmax))],  # pivot turn right
        [(u(3, 5), (v3 - d, v3 + d))],  # fast turn
    ]
    order = [0, *(1 + rng.permutation(len(blocks) - 1))]
    return [s for i in order for s in blocks[i]]


PIVOT = (11.0, 13.0)
"""Seconds of the reversals plan's pivot (drawn, of the plan's 55.5-57.5 s; a 50 s drive
squeezes it to 9.9-11.3 s): long enough to leave the first line's heading, so the crossing
line reads the slope across it. A six-wheel rover scrubs as it pivots: at 0.45 of the top
wheel speed this model and the independent generator turned 25-30° in 4 s (exploratory seed
74793, block 53600's case 53606), about 7° a second, and this plan's pivot 65-90°. A rover
that pivots at 15-18° a second would come round to about its first line (limits.md)."""


def _reversal_plan(rng: np.random.Generator, vmax: float) -> list[Segment]:
    out: list[Segment] = []
    for v in (0.5 * vmax, 0.75 * vmax):
        out += [(6.0, (v, v)), (1.5, (0.0, 0.0)), (6.0, (-v, -v)), (1.5, (0.0, 0.0))]
    w = 0.45 * vmax
    out += [(float(rng.uniform(*PIVOT)), (-w, w)), (1.0, (0.0, 0.0))]
    out += [(6.0, (0.6 * vmax, 0.6 * vmax)), (1.5, (0.0, 0.0)), (6.0, (-0.6 * vmax, -0.6 * vmax))]
    return out


def _turn_accel_plan(rng: np.random.Generator, vmax: float) -> list[Segment]:
    out: list[Segment] = []
    for sign in (1.0, -1.0, 1.0, -1.0):
        v, d = float(rng.uniform(0.6, 0.9)) * vmax, float(rng.uniform(0.25, 0.35)) * vmax
        out += [
            (1.5, (0.0, 0.0)),
            (3.0, (v - sign * d, v + sign * d)),
            (1.5, (0.2 * vmax, 0.2 * vmax)),
            (2.5, (v + sign * d, v - sign * d)),
        ]
    out += [(4.0, (-0.4 * vmax, 0.4 * vmax)), (4.0, (0.5 * vmax, -0.5 * vmax))]
    return out


def _steps_plan(rng: np.random.Generator, vmax: float) -> list[Segment]:
    out: list[Segment] = []
    for _ in range(18):
        v = float(rng.uniform(-0.9, 0.9)) * vmax
        dv = float(rng.uniform(-0.2, 0.2)) * vmax
        out.append((float(rng.uniform(0.6, 4.0)), (v - dv, v + dv)))
    return out


def _speeds_plan(rng: np.random.Generator, vmax: float) -> list[Segment]:
    out: list[Segment] = []
    for f in rng.permutation([0.15, 0.3, 0.45, 0.6, 0.75, 0.9]):
        v = float(f) * vmax
        out += [(4.0, (v, v)), (3.0, (v * 0.85, v * 1.15))]
    return out


def _straight_plan(rng: np.random.Generator, vmax: float) -> list[Segment]:
    out: list[Segment] = []
    for f in (0.5, 0.8, 0.65):
        v = float(f + rng.uniform(-0.05, 0.05)) * vmax
        out += [(12.0, (v, v)), (1.0, (0.0, 0.0)), (12.0, (-v, -v)), (1.0, (0.0, 0.0))]
    return out


def _accel_plan(rng: np.random.Generator, vmax: float) -> list[Segment]:
    out: list[Segment] = []
    for _ in range(6):
        hold = float(rng.uniform(1.5, 2.5))
        out += [
            (hold, (vmax, vmax)),
            (1.0, (0.0, 0.0)),
            (hold, (-vmax, -vmax)),
            (0.5, (vmax, vmax)),
        ]
    return out


_PLANS: dict[str, Callable[[np.random.Generator, float], list[Segment]]] = {
    "test": _test_plan,
    "reversals": _reversal_plan,
    "turn-accel": _turn_accel_plan,
    "steps": _steps_plan,
    "speeds": _speeds_plan,
    "straight": _straight_plan,
    "accel": _accel_plan,
}


def _timed(
    plan: str, rng: np.random.Generator, duration: float, vmax: float
) -> tuple[Array, Array]:
    """The plan's segments stretched to ``duration``: (each segment's end, its (left, right))."""
    if plan not in _PLANS:
        raise ValueError(f"unknown drive plan {plan!r}; have {', '.join(PLANS)}")
    segs = _PLANS[plan](rng, vmax)
    scale = duration / sum(s[0] for s in segs)  # stretch or squeeze the plan to the duration
    ends = np.cumsum([s[0] * scale for s in segs])
    return ends, np.array([s[1] for s in segs])


def drive_schedule(
    plan: str, rng: np.random.Generator, duration: float, vmax: float
) -> Callable[[float], Array]:
    """Speed targets (1L 1R 2L 2R) as a function of time for one drive of ``plan``."""
    ends, lr = _timed(plan, rng, duration, vmax)

    def schedule(t: float) -> Array:
        k = min(int(np.searchsorted(ends, t, side="right")), len(lr) - 1)
        left, right = lr[k]
        return np.array([left, right, left, right])

    return schedule


def drive_targets(
    plan: str, rng: np.random.Generator, duration: float, vmax: float, t: Array
) -> Array:
    """(len(t), 4) speed targets of ``drive_schedule`` at every time of ``t`` at once."""
    ends, lr = _timed(plan, rng, duration, vmax)
    k = np.minimum(np.searchsorted(ends, np.asarray(t, dtype=float), side="right"), len(lr) - 1)
    return np.tile(lr[k], (1, 2))
