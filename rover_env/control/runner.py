"""Run any :class:`Controller` on the bare :class:`RoverSim`, without the Gymnasium env.

This is the proof that controllers live below the environment (layer rule), and the loop the
gain tuner runs. It reproduces the environment's sensing and timing so that numbers agree
with the benchmark's: physics at 1 ms, encoders and potentiometers read through
:class:`SensorModel` and fed to :class:`SlipEstimator` at ``estimator_rate`` (50 Hz), the
controller called at ``control_frequency`` (10 Hz) with the newest estimate; tracking
errors, energy and slip are computed the way ``ProtoExplorerEnv.step`` computes them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from rover_env.config import TerrainConfig
from rover_env.control.base import CommandSchedule, Controller, ControllerInput
from rover_env.estimation.estimator import EstimatorConfig, SlipEstimate, SlipEstimator
from rover_env.estimation.sensors import SensorConfig, SensorModel
from rover_env.sim.simulator import RoverSim

__all__ = [
    "METRICS",
    "DriveCase",
    "DriveTrace",
    "episode_metrics",
    "motor_power",
    "run_on_sim",
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

STUCK_PROGRESS = 0.2
"""A control step is stuck when the rover makes less than this share of the commanded progress."""
MIN_PATH = 0.01
"""Path length (m) below which energy per metre is taken over this floor (no division by 0)."""


@dataclass(frozen=True)
class DriveCase:
    """One drive: ground, start pose, command schedule, length and the seed of its noise."""

    terrain: TerrainConfig
    schedule: CommandSchedule
    duration: float
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """x, y (m) and heading (rad) of the front axle at rest (``RoverSim.reset``)."""
    seed: int = 0
    goal_fraction: float = 0.5
    """Success needs at least this share of the commanded path length (and no flip)."""


@dataclass
class DriveTrace:
    """Per control step, what the environment's ``info`` would report (truth included)."""

    t: list[float] = field(default_factory=list)
    targets: list[Array] = field(default_factory=list)
    command: list[tuple[float, float]] = field(default_factory=list)
    slip_true: list[Array] = field(default_factory=list)
    slip_true_mean_abs: list[float] = field(default_factory=list)
    slip_estimate: list[Array] = field(default_factory=list)
    reliable: list[npt.NDArray[np.bool_]] = field(default_factory=list)
    tracking_error_speed: list[float] = field(default_factory=list)
    tracking_error_yaw_rate: list[float] = field(default_factory=list)
    energy: list[float] = field(default_factory=list)
    distance: list[float] = field(default_factory=list)
    position: list[Array] = field(default_factory=list)
    sinkage: list[Array] = field(default_factory=list)
    forward_speed: list[float] = field(default_factory=list)
    """True forward speed of the middle segment at the step end (m/s, signed)."""
    flipped: bool = False
    step_dt: float = 0.1

    def metrics(self, commanded_path: float, goal_fraction: float = 0.5) -> dict[str, float]:
        return episode_metrics(
            slip_true=np.array(self.slip_true),
            slip_true_mean_abs=np.array(self.slip_true_mean_abs),
            tracking_error_speed=np.array(self.tracking_error_speed),
            tracking_error_yaw_rate=np.array(self.tracking_error_yaw_rate),
            energy=np.array(self.energy),
            distance=np.array(self.distance),
            start=self.position[0],
            end=self.position[-1],
            flipped=self.flipped,
            commanded_path=commanded_path,
            goal_fraction=goal_fraction,
            sinkage=np.array(self.sinkage),
            speed_command=np.array([c[0] for c in self.command]),
            step_dt=self.step_dt,
            forward_speed=np.array(self.forward_speed) if self.forward_speed else None,
        )


def episode_metrics(
    *,
    slip_true: Array,
    slip_true_mean_abs: Array,
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
    sinkage: Array | None = None,
    speed_command: Array | None = None,
    step_dt: float = 0.1,
    forward_speed: Array | None = None,
) -> dict[str, float]:
    """The benchmark's metrics of one episode from per-step arrays (truth, as in ``info``).

    * ``mean_abs_slip``: mean |S| of the driven wheels over every estimator sample (the
      env's ``slip_true_mean_abs``, averaged over steps);
    * ``p95_abs_slip``: 95th percentile of |S| over the step-end samples of all four wheels;
    * ``rms_speed_error``, ``rms_yaw_rate_error``: RMS over the episode of commanded minus
      true forward speed and yaw rate of the middle segment (the env's step RMS, combined);
    * ``energy_per_metre``: motor electrical energy over the middle segment's path length
      (J/m), the path floored at :data:`MIN_PATH`;
    * ``distance_made_good``: straight-line displacement of the middle segment (m);
    * ``success``: 1 if no flip, still in the arena, and the path length reached
      ``goal_fraction`` of the commanded one (the rover was not stuck), else 0; given
      ``forward_speed`` (the true forward speed at each step end) and ``speed_command``, a
      step whose forward speed opposes the command counts its path *against* the goal (a
      rover sliding back down a loose slope while its wheels spin forward is not progressing);
    * ``flipped``: 1 if a segment tipped beyond 75 deg;
    * ``mean_sinkage``, ``max_sinkage``: sinkage into loose soil (m) of the six wheels at
      the step ends (``sinkage``, steps x 6), mean over steps and wheels and the largest;
      0 on hard ground;
    * ``time_stuck``: seconds of control steps (``step_dt``) whose path length was below
      :data:`STUCK_PROGRESS` of the commanded |speed| x step_dt (``speed_command``), the
      path counted as for ``success``.
    """
    path = float(np.sum(distance))
    progress = _progress(distance, speed_command, forward_speed)
    made_good = float(np.linalg.norm(np.asarray(end)[:2] - np.asarray(start)[:2]))
    ok = (
        (not flipped)
        and (not out_of_arena)
        and float(np.sum(progress)) >= goal_fraction * commanded_path
    )
    return {
        "mean_abs_slip": float(np.mean(slip_true_mean_abs)),
        "p95_abs_slip": float(np.percentile(np.abs(slip_true), 95)),
        "rms_speed_error": math.sqrt(float(np.mean(np.square(tracking_error_speed)))),
        "rms_yaw_rate_error": math.sqrt(float(np.mean(np.square(tracking_error_yaw_rate)))),
        "energy_per_metre": float(np.sum(energy)) / max(path, MIN_PATH),
        "distance_made_good": made_good,
        "success": float(ok),
        "flipped": float(flipped),
        "mean_sinkage": float(np.mean(sinkage)) if sinkage is not None else 0.0,
        "max_sinkage": float(np.max(sinkage)) if sinkage is not None else 0.0,
        "time_stuck": time_stuck(progress, speed_command, step_dt),
    }


def _progress(distance: Array, speed_command: Array | None, forward_speed: Array | None) -> Array:
    """Each step's path, negative where the rover moved against the commanded direction."""
    d = np.asarray(distance, dtype=float)
    if speed_command is None or forward_speed is None:
        return d
    against = np.asarray(forward_speed, dtype=float) * np.asarray(speed_command, dtype=float) < 0
    return np.where(against, -d, d)


def time_stuck(distance: Array, speed_command: Array | None, step_dt: float) -> float:
    """Seconds of steps that made less than STUCK_PROGRESS of the commanded progress."""
    if speed_command is None:
        return 0.0
    want = np.abs(np.asarray(speed_command, dtype=float)) * step_dt
    stuck = (want > 1e-3) & (np.asarray(distance) < STUCK_PROGRESS * want)
    return float(np.count_nonzero(stuck)) * step_dt


def motor_power(sim: RoverSim) -> float:
    """Electrical power (W) of the four motors, regeneration not recovered (the env's formula)."""
    motor = sim.cfg.motor
    k = motor.voltage / motor.no_load_speed
    copper = (k * motor.voltage / motor.stall_torque) / k**2  # R / K^2
    tau = sim.motor_torque()
    omega = sim.data.qvel[sim._driven_dof]
    return float(np.sum(np.maximum(tau * omega + copper * tau**2, 0.0)))


def run_on_sim(
    controller: Controller,
    case: DriveCase,
    sim: RoverSim | None = None,
    *,
    control_frequency: float = 10.0,
    estimator_rate: float = 50.0,
    sensors: SensorConfig | None = None,
    estimator: EstimatorConfig | None = None,
) -> DriveTrace:
    """Drive ``case`` with ``controller`` on a bare simulator; returns the per-step trace.

    ``sim`` is reused when given (its terrain is swapped with ``set_terrain`` when it
    differs, which needs the same arena structure); otherwise one is built for the case.
    Sensor noise is drawn from ``np.random.default_rng(case.seed)``.
    """
    if sim is None:
        sim = RoverSim(terrain=case.terrain, backend="auto")
    elif sim.terrain_cfg != case.terrain:
        sim.set_terrain(case.terrain)
    sim.reset(x=case.start[0], y=case.start[1], yaw=case.start[2])
    est = SlipEstimator(sim.cfg, estimator or EstimatorConfig())
    sensor_model = SensorModel(sensors or SensorConfig(), np.random.default_rng(case.seed))
    sub = max(1, round(1.0 / (estimator_rate * sim.dt)))
    samples = max(1, round(1.0 / (control_frequency * sim.dt * sub)))
    h = sub * sim.dt
    n_steps = round(case.duration / (samples * h))

    def sample() -> tuple[SlipEstimate, Array]:
        s = sim.sensors()
        phi, theta = sensor_model.read(s.phi, s.theta)
        return est.update(s.t, phi, theta), theta

    controller.reset()
    estimate, theta = sample()
    trace = DriveTrace(step_dt=samples * h)
    for _ in range(n_steps):
        v_cmd, w_cmd = case.schedule.at(sim.time)
        obs = ControllerInput(
            t=sim.time,
            estimate=estimate,
            theta=theta,
            speed_command=v_cmd,
            yaw_rate_command=w_cmd,
        )
        targets = np.asarray(controller.act(obs), dtype=np.float64).reshape(4)
        sim.set_speed_targets(targets)
        pos0 = sim.segment_truth().pos[1].copy()
        if not trace.position:
            trace.position.append(pos0)
        ev2 = ew2 = energy = 0.0
        slip_acc = np.zeros(4)
        for _ in range(samples):
            sim.step(sub)
            estimate, theta = sample()
            seg = sim.segment_truth()
            ev2 += (v_cmd - seg.forward_speed[1]) ** 2
            ew2 += (w_cmd - seg.yaw_rate[1]) ** 2
            energy += motor_power(sim) * h
            slip_acc += np.abs(sim.wheel_truth().S[:4])
        pos = sim.segment_truth().pos[1].copy()
        trace.t.append(sim.time)
        trace.targets.append(targets)
        trace.command.append((v_cmd, w_cmd))
        trace.slip_true.append(sim.wheel_truth().S[:4].copy())
        trace.slip_true_mean_abs.append(float(np.mean(slip_acc / samples)))
        trace.slip_estimate.append(np.asarray(estimate.slip_ratio).copy())
        trace.reliable.append(np.asarray(estimate.reliable).copy())
        trace.tracking_error_speed.append(math.sqrt(ev2 / samples))
        trace.tracking_error_yaw_rate.append(math.sqrt(ew2 / samples))
        trace.energy.append(energy)
        trace.distance.append(float(np.linalg.norm(pos[:2] - pos0[:2])))
        trace.position.append(pos)
        trace.sinkage.append(sim.wheel_truth().sinkage.copy())
        trace.forward_speed.append(float(sim.segment_truth().forward_speed[1]))
        if sim.flipped():
            trace.flipped = True
            break
    return trace
