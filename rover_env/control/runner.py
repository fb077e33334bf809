"""Run any :class:`Controller` on the bare :class:`RoverSim`, without the Gymnasium env.

This is the proof that controllers live below the environment (layer rule), and the loop the
gain tuner runs. It reproduces the environment's sensing and timing so that numbers agree
with the benchmark's: physics at 1 ms, encoders and potentiometers read through
:class:`SensorModel` and fed to :class:`SlipEstimator` at ``estimator_rate`` (50 Hz), the
controller called at ``control_frequency`` (10 Hz) with the newest estimate; tracking
errors, energy and slip are computed the way ``ProtoExplorerEnv.step`` computes them.
The benchmark judges a trace with :func:`rover_env.benchmark.metrics.trace_metrics`.
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
    "DriveCase",
    "DriveTrace",
    "motor_power",
    "run_on_sim",
]

Array = npt.NDArray[np.float64]


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
    slip_abs_step: list[Array] = field(default_factory=list)
    """Per step, each driven wheel's mean |S| over the step's samples (the env's
    ``info["slip_abs_step"]``)."""
    slip_estimate: list[Array] = field(default_factory=list)
    reliable: list[npt.NDArray[np.bool_]] = field(default_factory=list)
    tracking_error_speed: list[float] = field(default_factory=list)
    tracking_error_yaw_rate: list[float] = field(default_factory=list)
    energy: list[float] = field(default_factory=list)
    distance: list[float] = field(default_factory=list)
    position: list[Array] = field(default_factory=list)
    wheel_sinkage: list[Array] = field(default_factory=list)
    """Per step, the six wheels' sinkage into loose soil at the step's end (m)."""
    forward_speed: list[float] = field(default_factory=list)
    """True forward speed of the middle segment at the step end (m/s, signed)."""
    flipped: bool = False
    step_dt: float = 0.1


def motor_power(sim: RoverSim) -> float:
    """Electrical power (W) of the four motors, regeneration not recovered (the env's formula)."""
    motor = sim.cfg.motor
    k = motor.voltage / motor.no_load_speed
    copper = (k * motor.voltage / motor.stall_torque) / k**2  # R / K^2
    tau = sim.motor_torque()
    omega = sim.data.qvel[sim.index.driven_dof]
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
        trace.slip_abs_step.append(slip_acc / samples)
        trace.slip_estimate.append(np.asarray(estimate.slip_ratio).copy())
        trace.reliable.append(np.asarray(estimate.reliable).copy())
        trace.tracking_error_speed.append(math.sqrt(ev2 / samples))
        trace.tracking_error_yaw_rate.append(math.sqrt(ew2 / samples))
        trace.energy.append(energy)
        trace.distance.append(float(np.linalg.norm(pos[:2] - pos0[:2])))
        trace.position.append(pos)
        trace.wheel_sinkage.append(sim.wheel_truth().sinkage.copy())
        trace.forward_speed.append(float(sim.segment_truth().forward_speed[1]))
        if sim.flipped():
            trace.flipped = True
            break
    return trace
