"""Dead reckoning from the free wheels against the pose (SPEC §4: the paper's 50 s drive
ended about 1 % off along the direction of travel).

The two free wheels (3L, 3R) roll without drive, so on straight, moving seconds the pose's
path length over their travel at the rolling radius r_e is 1 + f, f the rolling radius's
change, plus whatever makes a free wheel slide (a rolling resistance drags it, loose soil
makes it bulldoze). It needs no model: two sensors of one rover against each other.
Diagnose compares it with the same statistic on its model's own twin drives and names a
rolling radius by the difference (its odometry stage).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rover_env.logs import DriveLog

MOVING = 0.05
"""Free-wheel travel (m) a pose interval needs to count: moving, not creeping."""
STRAIGHT = 0.02
"""Largest heading change (rad) over a pose interval that counts as straight."""


FREE = (4, 5)
"""The free wheels' columns in a log's wheel angles (3L, 3R)."""

FIX_SPACING = 0.9
"""Fewest seconds between the pose fixes dead reckoning reads; closer ones are thinned. The
statistic is judged per interval between fixes (moving: over :data:`MOVING` of travel), and
its clean band was measured on 1 Hz fixes: a 10-100 Hz reference (motion capture, RTK,
a fused odometry topic) would leave every interval shorter than 5 cm and nothing to read
(10 Hz fixes on the independent generator: no interval; thinned to 1 Hz: the 1 Hz reading)."""


def fixes(t: NDArray[np.float64], pose: NDArray[np.float64]) -> NDArray[np.float64]:
    """``pose`` (N, 3, NaN where not sampled) with its fixes thinned to at least
    :data:`FIX_SPACING` apart (the first kept, then each first one that far after the last
    kept); 1 Hz fixes come back as they are, and rows that are not whole fixes (a yaw alone)
    are left as they are."""
    have = np.flatnonzero(np.all(np.isfinite(pose), axis=1))
    if have.size < 2 or np.min(np.diff(t[have])) >= FIX_SPACING:
        return pose
    keep = [int(have[0])]
    for k in have[1:]:
        if t[k] - t[keep[-1]] >= FIX_SPACING:
            keep.append(int(k))
    out = pose.copy()
    out[np.setdiff1d(have, keep)] = np.nan
    return out


def path_and_travel(
    log: DriveLog, r_e: float, wheels: tuple[int, ...] = FREE
) -> tuple[float, float]:
    """(the pose's path along its heading, the mean travel of ``wheels`` (the free ones) at
    ``r_e``) over the straight, moving intervals between the log's pose fixes
    (:func:`fixes`) (m, m)."""
    return path_and_travel_of(fixes(log.t, log.pose), log.phi, r_e, wheels)


def path_and_travel_of(
    pose: NDArray[np.float64],
    phi: NDArray[np.float64],
    r_e: float,
    wheels: tuple[int, ...] = FREE,
) -> tuple[float, float]:
    """:func:`path_and_travel` on arrays: ``pose`` (N, 3), NaN where not sampled; ``phi``
    (N, 6) wheel angles. Straight and moving are judged on the free wheels' mean travel,
    whichever ``wheels`` are measured, so that each wheel is read over the same intervals."""
    have = np.flatnonzero(np.all(np.isfinite(pose), axis=1))
    if have.size < 2:
        return 0.0, 0.0
    x, y, yaw = pose[have].T
    free = np.mean(phi[have][:, list(FREE)], axis=1)
    read = np.mean(phi[have][:, list(wheels)], axis=1)
    # Along the mean heading, not the chord's length: linear in the pose noise, so noise
    # does not lengthen the path (|a + noise| is biased up by about noise^2 / 2|a|).
    mid = yaw[:-1] + 0.5 * np.angle(np.exp(1j * np.diff(yaw)))
    path = np.abs(np.diff(x) * np.cos(mid) + np.diff(y) * np.sin(mid))
    turn = np.abs(np.angle(np.exp(1j * np.diff(yaw))))
    ok = (np.abs(np.diff(free)) * r_e > MOVING) & (turn < STRAIGHT)
    return float(path[ok].sum()), float((np.abs(np.diff(read)) * r_e)[ok].sum())


def scale_of(got: list[tuple[float, float]]) -> float:
    """Path over travel minus 1 over (path, travel) pairs together (NaN without travel)."""
    arr = np.array(got, dtype=float).reshape(-1, 2)
    travel = float(arr[:, 1].sum())
    return float(arr[:, 0].sum() / travel - 1.0) if travel > 0 else math.nan


def travel_scale(logs: list[DriveLog], r_e: float, wheels: tuple[int, ...] = FREE) -> float:
    """Path over the travel of ``wheels`` (the free ones) minus 1, over all ``logs``
    together (NaN when none has a straight, moving interval)."""
    return scale_of([path_and_travel(g, r_e, wheels) for g in logs])


NOISE_SAMPLES = 10
"""Fewest straight pose intervals (moving or not) that measure the pose's own noise."""


def pose_noise_parts(
    pose: NDArray[np.float64],
    phi: NDArray[np.float64],
    r_e: float,
) -> tuple[float, float, NDArray[np.float64]]:
    """(the path's sensitivity to the pose fixes' noise, the free wheels' travel, the
    cross-track pose increments) of :func:`path_and_travel_of` on one log. The path is linear
    in each fix's noise e_k: it moves by sum_k c_k . e_k, so independent noise of standard
    deviation sigma per axis moves it by sigma sqrt(sum |c_k|^2) (the first number; within a
    straight run the fixes between intervals cancel, so it grows with the runs, not the
    metres). Across the heading a straight interval's increment is that noise alone (and a
    little side slip): those increments measure sigma sqrt(2), from the logs themselves."""
    have = np.flatnonzero(np.all(np.isfinite(pose), axis=1))
    if have.size < 2:
        return 0.0, 0.0, np.zeros(0)
    x, y, yaw = pose[have].T
    free = np.mean(phi[have][:, list(FREE)], axis=1)
    mid = yaw[:-1] + 0.5 * np.angle(np.exp(1j * np.diff(yaw)))
    along = np.diff(x) * np.cos(mid) + np.diff(y) * np.sin(mid)
    cross = -np.diff(x) * np.sin(mid) + np.diff(y) * np.cos(mid)
    straight = np.abs(np.angle(np.exp(1j * np.diff(yaw)))) < STRAIGHT
    ok = (np.abs(np.diff(free)) * r_e > MOVING) & straight
    # d|along_i| = sign(along_i) u_i . (e_{i+1} - e_i), u_i the interval's heading.
    u = np.column_stack([np.cos(mid), np.sin(mid)]) * np.sign(along)[:, None]
    c = np.zeros((x.size, 2))
    i = np.flatnonzero(ok)
    np.add.at(c, i + 1, u[i])
    np.add.at(c, i, -u[i])
    travel = float((np.abs(np.diff(free)) * r_e)[ok].sum())
    return float(np.sum(c * c)), travel, cross[straight]


def scale_noise(logs: list[DriveLog], r_e: float) -> tuple[float, int]:
    """(the standard error of :func:`travel_scale` over ``logs`` from the pose fixes' noise,
    the straight pose intervals that measured that noise). NaN when fewer than
    :data:`NOISE_SAMPLES` intervals measure it or nothing straight moves: a drive of turns
    reads its path over a few short straight bits, where a few millimetres of fix noise is
    per cent of the path (spent study 71000: one drive's clean spread 3 x three drives')."""
    parts = [pose_noise_parts(fixes(g.t, g.pose), g.phi, r_e) for g in logs]
    sens = sum(p[0] for p in parts)
    travel = sum(p[1] for p in parts)
    cross = np.concatenate([p[2] for p in parts]) if parts else np.zeros(0)
    if cross.size < NOISE_SAMPLES or travel <= 0:
        return math.nan, int(cross.size)
    sigma_inc = 1.4826 * float(np.median(np.abs(cross - np.median(cross))))
    return sigma_inc / math.sqrt(2.0) * math.sqrt(sens) / travel, int(cross.size)
