"""Dead reckoning from the free wheels against the pose (SPEC §4: the paper's 50 s drive
ended about 1 % off along the direction of travel).

The two free wheels (3L, 3R) roll without drive, so on straight, moving seconds the pose's
path length over their travel at the rolling radius r_e is 1 + f, f the rolling radius's
change, plus whatever makes a free wheel slide (a rolling resistance drags it, loose soil
makes it bulldoze). It needs no model: two sensors of one rover against each other.
Diagnose reports it beside the same statistic of the model's own twin drives.
"""

from __future__ import annotations

import math

import numpy as np

from rover_env.logs import DriveLog

MOVING = 0.05
"""Free-wheel travel (m) a pose interval needs to count: moving, not creeping."""
STRAIGHT = 0.02
"""Largest heading change (rad) over a pose interval that counts as straight."""


def path_and_travel(log: DriveLog, r_e: float) -> tuple[float, float]:
    """(pose path length, the free wheels' mean travel at ``r_e``) over the straight,
    moving intervals between the log's pose samples (m, m)."""
    have = np.flatnonzero(np.all(np.isfinite(log.pose), axis=1))
    if have.size < 2:
        return 0.0, 0.0
    x, y, yaw = log.pose[have].T
    free = 0.5 * (log.phi[have, 4] + log.phi[have, 5])
    path = np.hypot(np.diff(x), np.diff(y))
    travel = np.abs(np.diff(free)) * r_e
    turn = np.abs(np.angle(np.exp(1j * np.diff(yaw))))
    ok = (travel > MOVING) & (turn < STRAIGHT)
    return float(path[ok].sum()), float(travel[ok].sum())


def travel_scale(logs: list[DriveLog], r_e: float) -> float:
    """Path over free-wheel travel minus 1, over all ``logs`` together (NaN when none has
    a straight, moving interval)."""
    got = np.array([path_and_travel(g, r_e) for g in logs]).reshape(-1, 2)
    travel = float(got[:, 1].sum())
    return float(got[:, 0].sum() / travel - 1.0) if travel > 0 else math.nan
