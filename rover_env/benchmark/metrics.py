"""The benchmark's per-episode metrics, computed in this one place for every runner.

An episode is judged from the per-step ``info`` of the environment (or the same values from
the bare-simulator runner's :class:`rover_env.control.runner.DriveTrace`): :data:`STEP_KEYS`
per step, the position at the start and end, and the episode's end flags. A new metric is
added here (and to :data:`METRICS`, :data:`UNITS`, :data:`LOWER_IS_BETTER`), and every
table, plot, ledger and tuner gets it.

Slip statistics come from one set of samples: the mean |S| of each driven wheel over each
control step (its estimator samples averaged, ``info["slip_abs_step"]``), so the mean and
the 95th percentile describe the same distribution (a percentile of step-end snapshots
beside a mean of every sample could fall below the mean).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "LOWER_IS_BETTER",
    "METRICS",
    "MIN_PATH",
    "STEP_KEYS",
    "UNITS",
    "episode_metrics",
    "metrics_of_steps",
    "trace_metrics",
]

Array = npt.NDArray[np.float64]

METRICS: tuple[str, ...] = (
    "mean_abs_slip",
    "p95_abs_slip",
    "rms_speed_error",
    "rms_yaw_rate_error",
    "energy_per_metre",
    "distance_made_good",
    "success",
    "flipped",
    "mean_sinkage",
    "max_sinkage",
    "time_stuck",
)
"""Per-episode metrics, in table order (see :func:`episode_metrics`)."""

UNITS: dict[str, str] = {
    "mean_abs_slip": "1",
    "p95_abs_slip": "1",
    "rms_speed_error": "m/s",
    "rms_yaw_rate_error": "rad/s",
    "energy_per_metre": "J/m",
    "distance_made_good": "m",
    "success": "share",
    "flipped": "share",
    "mean_sinkage": "m",
    "max_sinkage": "m",
    "time_stuck": "s",
}
LOWER_IS_BETTER = {m: m not in ("distance_made_good", "success") for m in METRICS}

STEP_KEYS: tuple[str, ...] = (
    "slip_abs_step",
    "tracking_error_speed",
    "tracking_error_yaw_rate",
    "energy",
    "distance",
    "wheel_sinkage",
    "command",
)
"""The ``info`` entries of every step that the metrics need."""

STUCK_PROGRESS = 0.2
"""A control step is stuck when the rover makes less than this share of the commanded progress."""
MIN_PATH = 0.01
"""Path length (m) below which energy per metre is taken over this floor (no division by 0)."""


def episode_metrics(
    *,
    slip_abs_step: Array,
    tracking_error_speed: Array,
    tracking_error_yaw_rate: Array,
    energy: Array,
    distance: Array,
    start: Array,
    end: Array,
    flipped: bool,
    commanded_path: float,
    goal_fraction: float = 0.5,
    out_of_arena: bool = False,
    wheel_sinkage: Array | None = None,
    command: Array | None = None,
    step_dt: float = 0.1,
) -> dict[str, float]:
    """The benchmark's metrics of one episode from per-step arrays (truth, as in ``info``).

    * ``mean_abs_slip``, ``p95_abs_slip``: mean and 95th percentile of |S| of the driven
      wheels over the per-step, per-wheel means ``slip_abs_step`` (steps, 4) (module
      docstring);
    * ``rms_speed_error``, ``rms_yaw_rate_error``: RMS over the episode of commanded minus
      true forward speed and yaw rate of the middle segment (the env's step RMS, combined);
    * ``energy_per_metre``: motor electrical energy over the middle segment's path length
      (J/m), the path floored at :data:`MIN_PATH`;
    * ``distance_made_good``: straight-line displacement of the middle segment (m);
    * ``success``: 1 if no flip, still in the arena, and the path length reached
      ``goal_fraction`` of the commanded one (the rover was not stuck), else 0;
    * ``flipped``: 1 if a segment tipped beyond 75 deg;
    * ``mean_sinkage``, ``max_sinkage``: sinkage into loose soil (m) of the six wheels at
      the step ends (``wheel_sinkage``, steps x 6), mean over steps and wheels and the
      largest; 0 on hard ground;
    * ``time_stuck``: seconds of control steps (``step_dt``) whose path length was below
      :data:`STUCK_PROGRESS` of the commanded |speed| x step_dt (``command``, steps x 2).
    """
    path = float(np.sum(distance))
    made_good = float(np.linalg.norm(np.asarray(end)[:2] - np.asarray(start)[:2]))
    ok = (not flipped) and (not out_of_arena) and path >= goal_fraction * commanded_path
    slip = np.asarray(slip_abs_step, dtype=np.float64)
    return {
        "mean_abs_slip": float(np.mean(slip)),
        "p95_abs_slip": float(np.percentile(slip, 95)),
        "rms_speed_error": math.sqrt(float(np.mean(np.square(tracking_error_speed)))),
        "rms_yaw_rate_error": math.sqrt(float(np.mean(np.square(tracking_error_yaw_rate)))),
        "energy_per_metre": float(np.sum(energy)) / max(path, MIN_PATH),
        "distance_made_good": made_good,
        "success": float(ok),
        "flipped": float(flipped),
        "mean_sinkage": float(np.mean(wheel_sinkage)) if wheel_sinkage is not None else 0.0,
        "max_sinkage": float(np.max(wheel_sinkage)) if wheel_sinkage is not None else 0.0,
        "time_stuck": time_stuck(distance, command, step_dt),
    }


def time_stuck(distance: Array, command: Array | None, step_dt: float) -> float:
    """Seconds of steps that made less than STUCK_PROGRESS of the commanded progress."""
    if command is None:
        return 0.0
    want = np.abs(np.asarray(command, dtype=float).reshape(-1, 2)[:, 0]) * step_dt
    stuck = (want > 1e-3) & (np.asarray(distance) < STUCK_PROGRESS * want)
    return float(np.count_nonzero(stuck)) * step_dt


def metrics_of_steps(
    steps: Mapping[str, Sequence[Any]],
    *,
    start: Array,
    last_info: Mapping[str, Any],
    commanded_path: float,
    goal_fraction: float,
    step_dt: float = 0.1,
) -> dict[str, float]:
    """Metrics from the :data:`STEP_KEYS` lists of an env episode and its last ``info``."""
    return episode_metrics(
        **{k: np.asarray(steps[k]) for k in STEP_KEYS},
        start=start,
        end=np.asarray(last_info["position"]),
        flipped=bool(last_info.get("flipped", False)),
        out_of_arena=bool(last_info.get("out_of_arena", False)),
        commanded_path=commanded_path,
        goal_fraction=goal_fraction,
        step_dt=step_dt,
    )


def trace_metrics(
    trace: Any, commanded_path: float, goal_fraction: float = 0.5
) -> dict[str, float]:
    """Metrics of a bare-simulator drive (``rover_env.control.runner.DriveTrace``)."""
    return episode_metrics(
        slip_abs_step=np.array(trace.slip_abs_step),
        tracking_error_speed=np.array(trace.tracking_error_speed),
        tracking_error_yaw_rate=np.array(trace.tracking_error_yaw_rate),
        energy=np.array(trace.energy),
        distance=np.array(trace.distance),
        start=trace.position[0],
        end=trace.position[-1],
        flipped=trace.flipped,
        commanded_path=commanded_path,
        goal_fraction=goal_fraction,
        wheel_sinkage=np.array(trace.wheel_sinkage),
        command=np.array(trace.command),
        step_dt=trace.step_dt,
    )
