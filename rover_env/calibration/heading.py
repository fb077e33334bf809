"""The rover's heading on logs whose pose has too few fixes (SPEC §6's, the pose at the end
only, or none), for the force balance's runs (:mod:`rover_env.calibration.balance`).

Segment 3's free wheels roll with the ground, so their turn apart times the rolling radius
over the track is the segment's yaw from zero at the log's start (its frame, SPEC §6). Two
things bend that: the wheels scrub through a turn (a share ``a`` of each log's turn more or
less) and the two wheels differ in size (a drift ``c`` per metre of travel, the same on
every log of one rover: a 1 % radius apart is 0.022 rad a metre on this track). So

    yaw(t) = (1 + a_i) kin(t) + c travel(t)

fitted to each log's one fix (its last), ``a_i`` and ``c`` drawn toward zero by what builds
of another implementation show (:data:`SCALE_SD`, :data:`DRIFT_SD`). On 44 logs of the
independent generator with the pose at 1 Hz (spent block 53600, exploratory) those two terms
left 0.8° of the heading unexplained (median of each log's worst row; 90 % under 1.1°)
where the free wheels alone were off by up to 8-31°. Why the free wheels: the driven ones
slip through a pivot (read 420° where the rover turned 17-118°, exploratory seeds
74801-74802). The fit's own uncertainty goes with it (:meth:`Headings.steps`): the balance
reads the tilt again with the headings moved along each of the fit's principal directions,
and what the tilt moves by widens its interval.

Each log's heading is in its own frame (segment 3 at its start, SPEC §6). Where the logs'
YAML gives ``start_heading_deg`` (:func:`start_yaw`), every heading is turned by it into the
frame the drives share, so the ground's tilt has one direction over drives that started
facing different ways.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rover_env.config import RoverConfig
from rover_env.estimation.dead_reckoning import FREE
from rover_env.estimation.estimator import static_rolling_radius
from rover_env.logs import DriveLog, LogError

Array = NDArray[np.float64]

SCALE_SD = 0.2
"""Prior standard deviation of a log's scale error ``a`` of the free wheels' turn: the 44
exploratory logs' fitted errors ran -0.31 to +0.32 (5-95 %), median -0.06."""
DRIFT_SD = 0.03
"""Prior standard deviation (rad per metre of travel) of the drift ``c`` the free wheels'
sizes make: the 44 logs ran -0.046 to +0.057 (5-95 %), each case's logs alike; the build
tolerance issue 47 lists (each radius +-1 %) allows 0.045."""
FIX_SD = 0.03
"""Standard deviation (rad) of a fix against the two-term heading: the pose's own noise and
what the two terms leave (0.8° median, up to 5° on the 44 logs)."""
SOURCES = ("pose", "end fix", "free wheels")
"""Where a log's heading comes from: its pose's fixes (two or more), the free wheels fitted
to one fix, or the free wheels with no fix (the priors alone)."""


def has_heading(log: DriveLog) -> bool:
    """Whether the log's pose gives a heading by itself: two fixes with a yaw or more (SPEC
    §6's pose at the end only has one)."""
    return int(np.isfinite(log.pose[:, 2]).sum()) >= 2


def start_yaw(log: DriveLog) -> float:
    """Segment 3's heading at the log's start in the frame the drives share (rad): the YAML's
    ``start_heading_deg``, 0 where it is absent (the drives started facing the same way)."""
    head = log.meta.start_heading_deg
    return 0.0 if head is None else math.radians(head)


def check_frames(logs: list[DriveLog], names: Sequence[str | Path]) -> None:
    """One clear error where some logs give ``start_heading_deg`` and others do not: their
    frames could not be placed in one (the missing ones would be taken as 0)."""
    given = [log.meta.start_heading_deg is not None for log in logs]
    if any(given) and not all(given):
        have = Path(names[given.index(True)]).name
        lack = [Path(n) for n, g in zip(names, given, strict=True) if not g]
        raise LogError(
            f"key 'start_heading_deg' is absent here but given for {have}: give every drive's"
            f" start heading in the frame they share, or none (all started facing the same way;"
            f" also absent for: {', '.join(n.name for n in lack)})",
            lack[0],
        )


def free_wheels(log: DriveLog, cfg: RoverConfig) -> tuple[Array, Array]:
    """Segment 3's yaw (rad) as its free wheels turn apart, and their mean travel (m), both
    from zero at the log's start."""
    free = log.phi[:, list(FREE)] - log.phi[0, list(FREE)]
    r = static_rolling_radius(cfg)
    kin = r * (free[:, 1] - free[:, 0]) / (2.0 * cfg.geometry.half_track)
    return np.asarray(kin, dtype=np.float64), np.asarray(r * free.mean(axis=1), dtype=np.float64)


@dataclass(frozen=True)
class Headings:
    """Every log's heading: the pose's where it has two fixes or more (``pose_yaw``), else
    the free wheels' two-term fit. ``theta`` is ``(a_1 .. a_m, c)`` over the ``m`` logs
    without the pose's heading, ``cov`` its covariance."""

    pose_yaw: list[Array | None]
    basis: list[tuple[Array, Array] | None]
    """Per log: the free wheels' (kin, travel), None where the pose gives the heading; the
    k-th log with a basis has its ``a`` at ``theta[k]``."""
    source: list[str]
    theta: Array
    cov: Array
    start: list[float]
    """Per log: its frame's turn into the shared one (rad, :func:`start_yaw`)."""

    def yaw(self, shift: Array | None = None) -> list[Array | None]:
        """Every log's heading in the shared frame, with ``theta`` moved by ``shift``."""
        th = self.theta if shift is None else self.theta + shift
        out: list[Array | None] = []
        k = 0
        for pose, basis, s0 in zip(self.pose_yaw, self.basis, self.start, strict=True):
            if basis is None:
                out.append(None if pose is None else pose + s0)
                continue
            kin, travel = basis
            out.append((1.0 + th[k]) * kin + th[-1] * travel + s0)
            k += 1
        return out

    def steps(self) -> list[Array]:
        """``theta``'s principal standard deviations as shifts (none where every log has
        the pose's heading): moving the headings by each, both ways, and reading again
        shows what the heading's uncertainty does to a reading."""
        if len(self.theta) == 0:
            return []
        vals, vecs = np.linalg.eigh(self.cov)
        return [math.sqrt(max(v, 0.0)) * vecs[:, j] for j, v in enumerate(vals) if v > 0.0]


def headings(logs: list[DriveLog], cfg: RoverConfig, pose_yaw: list[Array | None]) -> Headings:
    """Each log's heading (``pose_yaw``: the pose's, None where it has fewer than two
    fixes), the others' fitted as the module says: the fix's branch (whole turns) nearest
    the free wheels' own turn, then one least-squares fit of ``a_i`` and the shared ``c``
    with their priors."""
    basis: list[tuple[Array, Array] | None] = []
    source: list[str] = []
    rows: list[tuple[int, float, float, float]] = []  # (its a's index, kin, travel, fix)
    for log, pose in zip(logs, pose_yaw, strict=True):
        if pose is not None:
            basis.append(None)
            source.append("pose")
            continue
        kin, travel = free_wheels(log, cfg)
        k = sum(b is not None for b in basis)
        basis.append((kin, travel))
        have = np.flatnonzero(np.isfinite(log.pose[1:, 2])) + 1  # the start's is the frame
        if len(have) == 0:
            source.append("free wheels")
            continue
        j = int(have[-1])
        fix = float(log.pose[j, 2])
        fix += 2.0 * math.pi * round((kin[j] - fix) / (2.0 * math.pi))
        rows.append((k, float(kin[j]), float(travel[j]), fix))
        source.append("end fix")
    m = sum(b is not None for b in basis)
    start = [start_yaw(log) for log in logs]
    if m == 0:
        return Headings(pose_yaw, basis, source, np.zeros(0), np.zeros((0, 0)), start)
    # Least squares with the priors as rows: fix residuals over FIX_SD, theta over its SD.
    prior = np.r_[np.full(m, SCALE_SD), DRIFT_SD]
    A = [np.diag(1.0 / prior)]
    b = [np.zeros(m + 1)]
    for k, kin_j, travel_j, fix in rows:
        row = np.zeros(m + 1)
        row[k], row[-1] = kin_j, travel_j
        A.append(row[None, :] / FIX_SD)
        b.append(np.array([(fix - kin_j) / FIX_SD]))
    AA, bb = np.vstack(A), np.concatenate(b)
    theta, *_ = np.linalg.lstsq(AA, bb, rcond=None)
    cov = np.linalg.inv(AA.T @ AA)
    return Headings(pose_yaw, basis, source, theta, cov, start)
