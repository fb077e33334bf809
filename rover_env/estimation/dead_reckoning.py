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


MIN_CHORD = 1.0
"""Shortest displacement (m) from the start to a drive's last fix that the end-fix statistic
reads: a centimetre of fix noise is a per cent of a metre, and a drive that comes back near
its start (out and back) measures nothing."""

STRAIGHT_COMMAND = 0.01
"""Largest difference between the left and the right wheels' mean speed targets, as a share
of the largest target, of a drive commanded straight (a skid-steer turn is commanded by
unequal sides; a logged straight drive sends equal numbers). Stricter than the replay's
turn regime (``replay.regimes``: 0.15 rad/s between the sides): a gentle turn that a 3 s
window may call straight bends a whole drive's path."""


def commanded_straight(cmd: NDArray[np.float64]) -> bool:
    """Whether every row of ``cmd`` (N, 4: 1L 1R 2L 2R) asks both sides for the same speed."""
    left, right = cmd[:, [0, 2]].mean(axis=1), cmd[:, [1, 3]].mean(axis=1)
    top = float(np.max(np.abs(cmd))) if cmd.size else 0.0
    return top > 0 and float(np.max(np.abs(left - right))) <= STRAIGHT_COMMAND * top


def end_fix_parts(
    pose: NDArray[np.float64],
    phi: NDArray[np.float64],
    cmd: NDArray[np.float64],
    r_e: float,
    wheels: tuple[int, ...] = FREE,
) -> tuple[float, float]:
    """(the path from the start to the drive's last pose fix, the net travel of ``wheels``
    (the free ones) at ``r_e`` up to it) on a drive commanded straight (m, m); (0, 0)
    otherwise, without a fix, or under :data:`MIN_CHORD`.

    The paper's case (SPEC §6: the pose at the end of the run only) leaves no interval between
    fixes for :func:`path_and_travel_of`; the start is a fix by definition (the frame is
    segment 3's at t = 0). On a straight drive the displacement is the net travel (forward
    and back alike); the heading drift that the fix's yaw shows bends it into an arc, whose
    length is the chord times (yaw/2) / sin(yaw/2) (constant curvature). A drive of turns
    says nothing here: its path is not known from two points, and dead reckoning through
    turns reads each implementation's own scrub (exploratory seeds 70892-70951: clean drives
    off by up to 6 % that way). A fix without a yaw is read as its chord."""
    have = np.flatnonzero(np.all(np.isfinite(pose[:, :2]), axis=1))
    if have.size == 0 or have[-1] == 0:
        return 0.0, 0.0
    k = int(have[-1])
    chord = float(np.hypot(*pose[k, :2]))
    if chord < MIN_CHORD or not commanded_straight(cmd[:k]):
        return 0.0, 0.0
    half = 0.5 * float(pose[k, 2]) if np.isfinite(pose[k, 2]) else 0.0
    arc = chord * (half / math.sin(half) if abs(half) > 1e-9 else 1.0)
    net = phi[k] - phi[0]
    return arc, abs(float(np.mean(net[list(wheels)]))) * r_e


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
