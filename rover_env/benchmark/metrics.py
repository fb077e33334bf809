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

*Success* is what a user would sign: the goal reached while keeping the commanded pace
(:data:`PACE_TOLERANCE`; :func:`pace_ratio`). A controller that gets there at twice the
commanded speed has not done what it was asked; ``goal`` keeps the old meaning (goal
reached, at any pace). The pace line applies to every scenario alike: where the ground does
not let any controller keep the pace, every controller's success is low there.
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
    "PACE_TOLERANCE",
    "STEP_KEYS",
    "UNITS",
    "episode_metrics",
    "metrics_of_steps",
    "pace_ratio",
    "trace_metrics",
]

Array = npt.NDArray[np.float64]

METRICS: tuple[str, ...] = (
    "success",
    "goal",
    "pace_ok",
    "pace_ratio",
    "time_to_goal",
    "mean_abs_slip",
    "p95_abs_slip",
    "rms_speed_error",
    "rms_yaw_rate_error",
    "energy_per_metre",
    "distance_made_good",
    "flipped",
    "mean_sinkage",
    "max_sinkage",
    "time_stuck",
)
"""Per-episode metrics, in table order (see :func:`episode_metrics`)."""

UNITS: dict[str, str] = {
    "success": "share",
    "goal": "share",
    "pace_ok": "share",
    "pace_ratio": "1",
    "time_to_goal": "s",
    "mean_abs_slip": "1",
    "p95_abs_slip": "1",
    "rms_speed_error": "m/s",
    "rms_yaw_rate_error": "rad/s",
    "energy_per_metre": "J/m",
    "distance_made_good": "m",
    "flipped": "share",
    "mean_sinkage": "m",
    "max_sinkage": "m",
    "time_stuck": "s",
}
HIGHER_IS_BETTER = ("distance_made_good", "success", "goal", "pace_ok")
UNORDERED = frozenset({"pace_ratio"})
"""Metrics with no better side (the pace ratio is best at 1): a paired table says *differs*."""
LOWER_IS_BETTER = {m: m not in HIGHER_IS_BETTER for m in METRICS}

STEP_KEYS: tuple[str, ...] = (
    "slip_abs_step",
    "tracking_error_speed",
    "tracking_error_yaw_rate",
    "energy",
    "distance",
    "wheel_sinkage",
    "command",
    "speed",
    "yaw_rate",
)
"""The ``info`` entries of every step that the metrics need."""

STUCK_PROGRESS = 0.2
"""A control step is stuck when the rover makes less than this share of the commanded progress."""
MIN_PATH = 0.01
"""Path length (m) below which energy per metre is taken over this floor (no division by 0)."""
PACE_TOLERANCE = 0.25
"""The pace line: the episode's mean speed within +-25 % of its mean commanded speed."""
MIN_SPEED = 0.01
"""Mean commanded |forward speed| (m/s) below which an episode turns in place: its pace is
then the yaw rate's (:func:`pace_ratio`)."""
MIN_YAW_RATE = 0.01
"""Mean commanded |yaw rate| (rad/s) below which a turn in place is a stand-still (no pace)."""


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
    speed: Array | None = None,
    step_dt: float = 0.1,
    yaw_rate: Array | None = None,
) -> dict[str, float]:
    """The benchmark's metrics of one episode from per-step arrays (truth, as in ``info``).

    * ``success``: ``goal`` and ``pace_ok`` (module docstring);
    * ``goal``: 1 if no flip, still in the arena, and the path length reached
      ``goal_fraction`` of the commanded one (the rover was not stuck), else 0; given
      ``speed`` (the true forward speed at each step end) and ``command``, a step whose
      forward speed opposes the command counts its path *against* the goal (a rover sliding
      back down a loose slope while its wheels spin forward is not progressing);
    * ``pace_ok``: 1 if ``pace_ratio`` is within 1 +- :data:`PACE_TOLERANCE`;
    * ``pace_ratio``: mean speed over mean commanded speed over the whole episode
      (:func:`pace_ratio`);
    * ``time_to_goal``: seconds until the progress first reached the goal; an episode that
      misses its goal counts its whole played length (censored: at least that);

    * ``mean_abs_slip``, ``p95_abs_slip``: mean and 95th percentile of |S| of the driven
      wheels over the per-step, per-wheel means ``slip_abs_step`` (steps, 4) (module
      docstring);
    * ``rms_speed_error``, ``rms_yaw_rate_error``: RMS over the episode of commanded minus
      true forward speed and yaw rate of the middle segment (the env's step RMS, combined);
    * ``energy_per_metre``: motor electrical energy over the middle segment's path length
      (J/m), the path floored at :data:`MIN_PATH`;
    * ``distance_made_good``: straight-line displacement of the middle segment (m);
    * ``flipped``: 1 if a segment tipped beyond 75 deg;
    * ``mean_sinkage``, ``max_sinkage``: sinkage into loose soil (m) of the six wheels at
      the step ends (``wheel_sinkage``, steps x 6), mean over steps and wheels and the
      largest; 0 on hard ground;
    * ``time_stuck``: seconds of control steps (``step_dt``) whose path length was below
      :data:`STUCK_PROGRESS` of the commanded |speed| x step_dt (``command``, steps x 2),
      the path counted as for ``success``.
    """
    path = float(np.sum(distance))
    made_good = float(np.linalg.norm(np.asarray(end)[:2] - np.asarray(start)[:2]))
    progress = _progress(distance, command, speed)
    goal_path = goal_fraction * commanded_path
    ok = (not flipped) and (not out_of_arena) and float(np.sum(progress)) >= goal_path
    ratio = pace_ratio(progress, command, yaw_rate, step_dt)
    pace = abs(ratio - 1.0) <= PACE_TOLERANCE
    played = progress.size * step_dt
    reached = np.flatnonzero(np.cumsum(progress) >= goal_path)
    slip = np.asarray(slip_abs_step, dtype=np.float64)
    return {
        "success": float(ok and pace),
        "goal": float(ok),
        "pace_ok": float(pace),
        "pace_ratio": ratio,
        "time_to_goal": float(reached[0] + 1) * step_dt if ok and reached.size else played,
        "mean_abs_slip": float(np.mean(slip)),
        "p95_abs_slip": float(np.percentile(slip, 95)),
        "rms_speed_error": math.sqrt(float(np.mean(np.square(tracking_error_speed)))),
        "rms_yaw_rate_error": math.sqrt(float(np.mean(np.square(tracking_error_yaw_rate)))),
        "energy_per_metre": float(np.sum(energy)) / max(path, MIN_PATH),
        "distance_made_good": made_good,
        "flipped": float(flipped),
        "mean_sinkage": float(np.mean(wheel_sinkage)) if wheel_sinkage is not None else 0.0,
        "max_sinkage": float(np.max(wheel_sinkage)) if wheel_sinkage is not None else 0.0,
        "time_stuck": time_stuck(progress, command, step_dt),
    }


def pace_ratio(
    progress: Array, command: Array | None, yaw_rate: Array | None, step_dt: float
) -> float:
    """The episode's mean speed over its mean commanded speed (1: the commanded pace).

    Forward: the path made along the commanded direction (``progress``, see
    :func:`episode_metrics`) over the commanded path, both over the played steps, so periods
    of stand-still in a schedule count on both sides. An episode whose mean commanded
    |forward speed| is below :data:`MIN_SPEED` turns in place: its ratio is the mean yaw
    rate along the commanded sense over the mean commanded |yaw rate|; without ``yaw_rate``,
    or below :data:`MIN_YAW_RATE` too (a stand-still), there is no pace to keep and the
    ratio is 1. Without ``command`` the pace is not judged (1).
    """
    if command is None:
        return 1.0
    cmd = np.asarray(command, dtype=float).reshape(-1, 2)
    v_cmd = np.abs(cmd[:, 0])
    if float(np.mean(v_cmd)) >= MIN_SPEED:
        return float(np.sum(progress)) / (float(np.sum(v_cmd)) * step_dt)
    w_cmd = cmd[:, 1]
    if yaw_rate is None or float(np.mean(np.abs(w_cmd))) < MIN_YAW_RATE:
        return 1.0
    along = np.asarray(yaw_rate, dtype=float) * np.sign(w_cmd)
    return float(np.sum(along)) / float(np.sum(np.abs(w_cmd)))


def _progress(distance: Array, command: Array | None, speed: Array | None) -> Array:
    """Each step's path, negative where the rover moved against the commanded direction."""
    d = np.asarray(distance, dtype=float)
    if command is None or speed is None:
        return d
    v_cmd = np.asarray(command, dtype=float).reshape(-1, 2)[:, 0]
    against = np.asarray(speed, dtype=float) * v_cmd < 0
    return np.where(against, -d, d)


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
        speed=np.array(trace.forward_speed) if trace.forward_speed else None,
        step_dt=trace.step_dt,
    )
