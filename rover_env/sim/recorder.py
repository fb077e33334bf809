"""Record simulated drives as SPEC §6 logs, with the simulator's truth kept beside them.

A recorded log is what the estimators and calibration see, exactly as they would see a real
one; the privileged arrays (slip, tire forces, true speeds) are what they are scored against.
Both come from the same samples so they line up row for row.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rover_env.logs import DriveLog, LogMeta
from rover_env.sim.simulator import RoverSim

Array = NDArray[np.float64]

WHEEL_TRUTH_KEYS: tuple[str, ...] = ("S", "S_alpha", "F_x", "F_y", "F_z", "v_x", "v_w", "sinkage")


def _quat_to_mat(q: Array) -> Array:
    """(..., 4) unit quaternions (w, x, y, z) to (..., 3, 3) rotation matrices."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def relative_pose(pos: Array, quat: Array) -> Array:
    """Planar pose (x, y, yaw) of a body in its own frame at the first sample.

    SPEC §6 measures pose in segment 3's frame at t = 0, so position is rotated into that
    3-D frame and its x, y kept, and yaw is the heading of the current x axis within that
    frame's x-y plane, unwrapped so turns accumulate past ±pi. On flat ground this is the
    usual planar pose; on a slope it is distance along the slope, as the wheels measure it.
    """
    p = np.asarray(pos, dtype=np.float64)
    rot = _quat_to_mat(np.asarray(quat, dtype=np.float64))
    r0 = rot[0]
    rel_p = (p - p[0]) @ r0  # rows: r0.T @ (p - p0)
    rel_r = np.einsum("ji,njk->nik", r0, rot)  # r0.T @ R
    yaw = np.unwrap(np.arctan2(rel_r[:, 1, 0], rel_r[:, 0, 0]))
    out = np.column_stack([rel_p[:, 0], rel_p[:, 1], yaw])
    out[0] = 0.0  # exactly, not to rounding
    return out


class DriveRecorder:
    """Samples one ``RoverSim`` into a drive log plus truth arrays.

    Args:
        sim: the simulation to record; if None, the first ``record`` call attaches it.
        sample_rate_hz: nominal rate written to the log; if None, ``to_log`` takes it from
            the recorded times.
    """

    def __init__(self, sim: RoverSim | None = None, sample_rate_hz: float | None = None) -> None:
        if sample_rate_hz is not None and not (
            math.isfinite(sample_rate_hz) and sample_rate_hz > 0
        ):
            raise ValueError(f"sample_rate_hz must be finite and > 0, got {sample_rate_hz!r}")
        self.sim = sim
        self.sample_rate_hz = sample_rate_hz
        self._t0: float | None = None
        self._rows: dict[str, list[Array]] = {}
        self._t: list[float] = []

    def __len__(self) -> int:
        return len(self._t)

    def _add(self, key: str, value: ArrayLike) -> None:
        self._rows.setdefault(key, []).append(np.array(value, dtype=np.float64))

    def record(self, sim: RoverSim, cmd: ArrayLike | None = None) -> None:
        """Store one sample of ``sim`` now; ``cmd`` is what the motors were sent (4 rad/s).

        ``cmd`` defaults to the simulator's current (clipped) speed targets. The first sample
        sets t = 0 and the pose origin.
        """
        if self.sim is None:
            self.sim = sim
        elif sim is not self.sim:
            raise ValueError("this recorder is attached to a different RoverSim")
        c = np.array(sim.speed_targets if cmd is None else cmd, dtype=np.float64).reshape(-1)
        if c.shape != (4,):
            raise ValueError(f"cmd must hold 4 speed targets (1L 1R 2L 2R), got {c.shape}")
        if self._t0 is None:
            self._t0 = sim.time
        # Count substeps so t is k * dt exactly, without the clock's accumulated rounding.
        t = round((sim.time - self._t0) / sim.dt) * sim.dt
        if self._t and t <= self._t[-1]:
            raise ValueError(
                f"sim time did not advance ({self._t[-1]!r} then {t!r}); "
                "use a new recorder after a reset"
            )
        s = sim.sensors()
        seg = sim.segment_truth()
        self._t.append(t)
        self._add("cmd", c)
        self._add("phi", s.phi)
        self._add("theta", s.theta)
        self._add("seg_pos", seg.pos)
        self._add("seg_quat", seg.quat)
        self._add("forward_speed", seg.forward_speed)
        self._add("yaw_rate", seg.yaw_rate)
        self._add("motor_torque", sim.motor_torque())
        try:
            wt = sim.wheel_truth()
        except (RuntimeError, AttributeError):
            # No tire-layer substep yet (reset with settle=0): nothing true to report.
            for k in WHEEL_TRUTH_KEYS:
                self._add(k, np.full(6, np.nan))
        else:
            for k in WHEEL_TRUTH_KEYS:
                self._add(k, getattr(wt, k))

    def _stack(self, key: str) -> Array:
        return np.stack(self._rows[key])

    @property
    def t(self) -> Array:
        return np.array(self._t, dtype=np.float64)

    def pose(self) -> Array:
        """(N, 3) true x, y, yaw of segment 3 in its frame at the first sample, every sample."""
        if not self._t:
            return np.zeros((0, 3))
        pos = self._stack("seg_pos")[:, 2]
        quat = self._stack("seg_quat")[:, 2]
        return relative_pose(pos, quat)

    def truth(self) -> dict[str, Array]:
        """Privileged arrays, row k matching the log's row k.

        Keys: ``t`` (N,); per wheel in WHEELS order (N, 6): ``S``, ``S_alpha``, ``F_x``,
        ``F_y``, ``F_z``, ``v_x``, ``v_w``, ``sinkage`` (0 on hard ground) (from the last substep before the sample); per
        segment (N, 3): ``forward_speed``, ``yaw_rate``; ``seg_pos`` (N, 3, 3) and
        ``seg_quat`` (N, 3, 4) world frame; ``motor_torque`` (N, 4); ``pose`` (N, 3), the
        full-rate true pose of segment 3 that the log subsamples.
        """
        if not self._t:
            raise ValueError("nothing recorded yet")
        keys = (*WHEEL_TRUTH_KEYS, "forward_speed", "yaw_rate", "seg_pos", "seg_quat")
        out = {"t": self.t}
        out.update({k: self._stack(k) for k in keys})
        out["motor_torque"] = self._stack("motor_torque")
        out["pose"] = self.pose()
        return out

    def to_log(
        self,
        rover_name: str,
        terrain: str | dict[str, object] | None = None,
        notes: str | None = None,
        pose_rate_hz: float | None = 1.0,
        pose_end_only: bool = False,
        effort: bool = False,
    ) -> DriveLog:
        """The drive as a real rover would have logged it.

        Wheel angles start at zero (SPEC §6). The external pose reference is kept only at
        ``pose_rate_hz`` (the first sample at or after each multiple of its period; None keeps
        every sample), or with ``pose_end_only`` only at the last sample, as in the paper;
        NaN elsewhere. With ``effort`` the motors' torque is logged as the drivers would report
        it (:data:`rover_env.logs.EFFORT_COLUMNS`).
        """
        if len(self._t) < 2:
            raise ValueError(f"a log needs at least 2 samples, recorded {len(self._t)}")
        t = self.t
        phi = self._stack("phi")
        pose = self.pose()
        keep = np.zeros(len(t), dtype=bool)
        if pose_end_only:
            keep[-1] = True
        elif pose_rate_hz is None:
            keep[:] = True
        else:
            if not (math.isfinite(pose_rate_hz) and pose_rate_hz > 0):
                raise ValueError(f"pose_rate_hz must be finite and > 0, got {pose_rate_hz!r}")
            # Tolerance absorbs float rounding of t on an exact multiple of the period.
            period = np.floor(t * pose_rate_hz + 1e-6)
            keep[0] = True
            keep[1:] = period[1:] != period[:-1]
        pose[~keep] = np.nan
        rate = self.sample_rate_hz
        if rate is None:
            rate = (len(t) - 1) / float(t[-1] - t[0])
        meta = LogMeta(rover=rover_name, sample_rate_hz=rate, terrain=terrain, notes=notes)
        return DriveLog(
            t=t,
            cmd=self._stack("cmd"),
            phi=phi - phi[0],
            theta=self._stack("theta"),
            pose=pose,
            meta=meta,
            effort=self._stack("motor_torque") if effort else np.zeros((0, 4)),
        )


def run_drive(
    sim: RoverSim,
    schedule: Callable[[float], ArrayLike],
    duration: float,
    sample_rate_hz: float = 50.0,
    progress: bool = False,
) -> DriveRecorder:
    """Drive ``sim`` from its current state under ``schedule(t)`` and record it.

    Samples are taken at t = 0, 1/rate, ..., duration; at each the targets are set from the
    schedule (t counted from the start of the drive) and held until the next. The rate is
    rounded to a whole number of physics substeps; the recorder carries the rate achieved.
    """
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be finite and > 0, got {duration!r}")
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise ValueError(f"sample_rate_hz must be finite and > 0, got {sample_rate_hz!r}")
    substeps = round(1.0 / (sample_rate_hz * sim.dt))
    if substeps < 1:
        raise ValueError(
            f"sample_rate_hz {sample_rate_hz} exceeds the physics rate {1.0 / sim.dt:g} Hz"
        )
    rate = 1.0 / (substeps * sim.dt)
    if abs(rate - sample_rate_hz) > 1e-6 * sample_rate_hz:
        warnings.warn(
            f"sample rate {sample_rate_hz} Hz is not a whole number of {sim.dt} s substeps; "
            f"recording at {rate:.6g} Hz",
            stacklevel=2,
        )
    n = round(duration * rate) + 1
    rec = DriveRecorder(sim, sample_rate_hz=rate)
    samples: Iterable[int] = range(n)
    if progress:
        from tqdm import tqdm

        samples = tqdm(samples, total=n, desc="drive", unit="sample")
    for k in samples:
        sim.set_speed_targets(np.asarray(schedule(k * substeps * sim.dt), dtype=np.float64))
        rec.record(sim)
        if k < n - 1:
            sim.step(substeps)
    return rec
