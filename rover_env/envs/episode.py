"""One rover's episode logic, shared by the single and the vector env: commands, actions,
sensors, reward (through the task), info and observation from what a step measured."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rover_env.config import DRIVEN_WHEELS
from rover_env.envs.settings import EnvSettings
from rover_env.estimation.batch import BatchSlipEstimator
from rover_env.estimation.estimator import SlipEstimate
from rover_env.estimation.fast import FastSlipEstimator
from rover_env.estimation.sensors import SensorModel
from rover_env.sim.readers import RoverIndex
from rover_env.sim.sample import SimRows, StepSample, wheel_friction
from rover_env.sim.simulator import RoverSim
from rover_env.tasks.base import Task
from rover_env.tasks.reward import StepResult
from rover_env.tasks.tracking import RandomTracking

__all__ = ["OBS_NAMES", "RoverEpisode"]

Array = NDArray[np.float64]

OBS_NAMES: tuple[str, ...] = (
    *(f"wheel_rate_{w}" for w in ("1L", "1R", "2L", "2R", "3L", "3R")),
    *(f"theta_{i}" for i in range(1, 6)),
    *(f"theta_{i}_rate" for i in range(1, 6)),
    *(f"gravity_seg{s}_{a}" for s in (1, 2, 3) for a in "xyz"),
    *(f"gyro_seg{s}_{a}" for s in (1, 2, 3) for a in "xyz"),
    *(f"slip_estimate_{w}" for w in DRIVEN_WHEELS),
    "speed_estimate",
    "yaw_rate_estimate",
    "command_speed",
    "command_yaw_rate",
    *(f"previous_action_{i}" for i in range(4)),
)


class RoverEpisode:
    """One rover's episode state and the env's logic on it: commands, actions, reward, info
    and observation from values read off the simulation. ``ProtoExplorerEnv`` is one; the
    vector env keeps one per rover, so both compute the same numbers the same way.
    """

    settings: EnvSettings
    sensor_model: SensorModel
    _command: Array
    _next_command_t: float
    _prev_action: Array
    last_estimate: SlipEstimate | None
    theta_meas: Array
    _imu_rng: np.random.Generator

    def _configure(self, settings: EnvSettings, dt: float, arena_size: tuple[float, float]) -> None:
        """Everything that follows from the settings and the simulator's timestep."""
        s = self.settings = settings
        self.rover_cfg = s.rover_cfg
        self.base_terrain = s.base_terrain
        self.randomize_terrain = s.randomize_terrain
        self.slip_source = s.slip_source
        self.action_layout = s.action_layout
        self.reward_weights = s.reward_weights
        self.sensor_cfg = s.sensor_cfg
        self.imu_noise = s.imu_noise
        self.max_speed_command = s.max_speed_command
        self.max_yaw_rate_command = s.max_yaw_rate_command
        self.command_interval = s.command_interval
        self.substeps_per_sample = max(1, round(1.0 / (s.estimator_rate * dt)))
        self.samples_per_step = max(
            1, round(1.0 / (s.control_frequency * dt * self.substeps_per_sample))
        )
        self.control_dt = self.samples_per_step * self.substeps_per_sample * dt
        self.sample_dt = self.substeps_per_sample * dt
        self.max_wheel_speed = s.rover_cfg.motor.max_wheel_speed
        motor = s.rover_cfg.motor
        k = motor.voltage / motor.no_load_speed
        self.copper = (k * motor.voltage / motor.stall_torque) / k**2  # R / K^2
        half = np.array(arena_size) / 2
        self._arena_half = half - 0.5
        self._prev_action = np.zeros(4)
        self._command = np.zeros(2)
        self._next_command_t = 0.0
        self.task: Task = RandomTracking(
            s.max_speed_command, s.max_yaw_rate_command, s.command_interval
        )
        self.last_estimate = None
        self.theta_meas = np.zeros(5)
        self._imu_rng = np.random.default_rng(0)

    def timing(self) -> tuple[int, int, float, float]:
        """What the compiled sample loops need: substeps per sample, samples per step, the
        motors' copper-loss factor R/K^2 and the time a sample stands for."""
        return self.substeps_per_sample, self.samples_per_step, self.copper, self.sample_dt

    @property
    def command(self) -> Array:
        """The task's current command (forward speed m/s, yaw rate rad/s), a copy."""
        return self._command.copy()

    def set_task(self, task: Task) -> None:
        """The task of the episodes from the next ``reset`` on (:mod:`rover_env.tasks`); its
        reward weights, when it has its own, replace the env's ``reward_weights``."""
        if not isinstance(task, Task):
            raise TypeError(f"set_task needs a rover_env.tasks.Task, got {type(task).__name__}")
        self.task = task

    # --- episode start
    def _start_pose(
        self,
        rng: np.random.Generator,
        options: dict[str, Any] | None,
        default: tuple[float, float, float] | None = None,
    ) -> tuple:
        opts = options or {}
        unknown = set(opts) - {"x", "y", "yaw"}
        if unknown:
            raise ValueError(f"reset options: unknown key(s) {sorted(unknown)}; allowed x, y, yaw")
        x0, y0, yaw0 = default if default is not None else (0.0, 0.0, None)
        if "yaw" in opts:
            yaw = float(opts["yaw"])
        elif yaw0 is not None:
            yaw = float(yaw0)
        else:
            yaw = float(rng.uniform(-np.pi, np.pi))
        return float(opts.get("x", x0)), float(opts.get("y", y0)), yaw

    def _reset_sim(
        self, sim: RoverSim, rng: np.random.Generator, options: dict[str, Any] | None
    ) -> None:
        """This episode's terrain and start pose (the task's, else drawn) and ``sim`` there."""
        self.reward_weights = self.task.reward_weights or self.settings.reward_weights
        setup = self.task.setup(rng)
        if setup.timestep is not None and abs(sim.dt - setup.timestep) > 1e-12:
            raise ValueError(
                f"the task's episode is played at a {setup.timestep:g} s physics step, the env "
                f"runs at {sim.dt:g} s: build the env with timestep={setup.timestep:g}"
            )
        if setup.terrain is not None:
            if sim.terrain_cfg != setup.terrain:
                sim.set_terrain(setup.terrain)
        elif self.randomize_terrain:
            sim.set_terrain(self.settings.random_terrain(rng))
        x, y, yaw = self._start_pose(rng, options, setup.start)
        sim.reset(x=x, y=y, yaw=yaw)

    def _start_episode(self, rng: np.random.Generator) -> None:
        """Sensors, IMU noise stream, previous action and first command of a new episode."""
        sensor_seed = int(rng.integers(2**63))
        self.sensor_model = SensorModel(self.sensor_cfg, np.random.default_rng(sensor_seed))
        self._imu_rng = np.random.default_rng(sensor_seed + 1)
        self._prev_action = np.zeros(4)
        self._new_command(rng, 0.0)

    def _new_command(self, rng: np.random.Generator, t: float) -> None:
        v, w, self._next_command_t = self.task.command(rng, t)
        self._command = np.array([v, w])

    def read_sensors(self, phi: Array, theta: Array) -> tuple[Array, Array]:
        """The rover's electronics on one sample; the joint reading is kept for controllers."""
        p, th = self.sensor_model.read(phi, theta)
        self.theta_meas = th
        return p, th

    # --- reading one simulator (the single env always, the vector env on reset)
    def _push_sample_from(
        self,
        sim: RoverSim,
        index: RoverIndex,
        est: BatchSlipEstimator | FastSlipEstimator,
        ids: ArrayLike | None,
    ) -> None:
        d = sim.data
        phi, theta = self.read_sensors(*index.phi_theta(d.sensordata))
        est.push(ids, d.time, phi, theta)

    def _info_from(self, sim: RoverSim, index: RoverIndex) -> dict[str, Any]:
        """The info of a new episode, read off ``sim``."""
        speed, yaw_rate = SimRows(sim, index).segment_velocity()
        wt = sim.wheel_truth()
        mu = wheel_friction(sim.terrain, wt.contact_point)
        return self._static_info(
            speed[0],
            yaw_rate[0],
            sim.data.xpos[index.seg_body[1]],
            wt.F_z.copy(),
            mu,
            wt.sinkage.copy(),
        )

    def _obs_from(self, sim: RoverSim, index: RoverIndex) -> NDArray[np.float32]:
        d = sim.data
        return self.observation(index.gravity(d.xmat), index.gyro_rates(d.sensordata))

    def begin_episode(
        self,
        sim: RoverSim,
        index: RoverIndex,
        est: BatchSlipEstimator | FastSlipEstimator,
        ids: ArrayLike | None,
        rng: np.random.Generator,
        options: dict[str, Any] | None,
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """A new episode on ``sim`` (rows ``ids`` of ``est``): terrain, start pose,
        sensors, first command and sample; returns the first observation and info."""
        self._reset_sim(sim, rng, options)
        self._start_episode(rng)
        est.reset(ids)
        self._push_sample_from(sim, index, est, ids)
        self.last_estimate = est.estimate(ids)[0]
        info = self._info_from(sim, index)
        info.update(self.task.reset_info())
        return self._obs_from(sim, index), info

    # --- actions
    def wheel_targets(self, action: NDArray[Any]) -> Array:
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        shape = (self.settings.n_act,)
        if a.shape != shape:
            raise ValueError(f"action must have shape {shape}, got {a.shape}")
        bad = ~np.isfinite(a)
        if bad.any():
            names = DRIVEN_WHEELS if self.action_layout == "wheels" else ("left", "right")
            raise ValueError(
                "action has non-finite entries: "
                + ", ".join(f"{names[i]}={a[i]}" for i in np.flatnonzero(bad))
            )
        a = np.clip(a, -1.0, 1.0)
        if self.action_layout == "sides":
            a = np.array([a[0], a[1], a[0], a[1]])
        return a

    # --- end of a step
    def finish_step(
        self, a4: Array, sample: StepSample, j: int, rng: np.random.Generator
    ) -> tuple[float, bool, dict[str, Any]]:
        """Reward, termination and info of row ``j`` of a step's ``sample``; draws the next
        command from ``rng`` when due. ``self.last_estimate`` must hold the step's last estimate."""
        n = self.samples_per_step
        e_v, e_w = math.sqrt(sample.err_v2[j] / n), math.sqrt(sample.err_w2[j] / n)
        est = self.last_estimate
        assert est is not None
        slip_abs_step = sample.slip_abs[j] / n
        x = slip_abs_step.tolist()
        slip_mean = (((x[0] + x[1]) + x[2]) + x[3]) / 4  # np.mean's sum and division, cheaper
        mean_abs_slip = (
            slip_mean if self.slip_source == "true" else float(np.mean(np.abs(est.slip_ratio)))
        )
        pos = sample.position[j]
        path = float(np.linalg.norm(pos[:2] - sample.position0[j][:2]))
        speed = sample.speed[j]
        result = StepResult(
            tracking_error_speed=e_v,
            tracking_error_yaw_rate=e_w,
            mean_abs_slip=mean_abs_slip,
            energy=float(sample.energy[j]),
            distance=path,
            against=bool(speed * float(self._command[0]) < 0),
            speed_command=float(self._command[0]),
            control_dt=self.control_dt,
            wheel_sinkage=sample.wheel_sinkage[j],
            flipped=bool(sample.flipped[j]),
            out_of_arena=bool(
                abs(pos[0]) > self._arena_half[0] or abs(pos[1]) > self._arena_half[1]
            ),
        )
        reward, terms = self.task.reward(self.reward_weights, result)
        self._prev_action = a4
        t = float(sample.time[j])
        if t >= self._next_command_t:
            self._new_command(rng, t)
        info = self._static_info(
            speed,
            sample.yaw_rate[j],
            pos,
            sample.wheel_F_z[j],
            sample.wheel_mu[j],
            sample.wheel_sinkage[j],
        )
        info.update((k, terms.pop(k)) for k in ("reward_tracking", "reward_slip", "reward_energy"))
        info.update(
            tracking_error_speed=e_v,
            tracking_error_yaw_rate=e_w,
            slip_true=sample.slip[j].copy(),
            slip_true_mean_abs=slip_mean,
            slip_abs_step=slip_abs_step,
            energy=result.energy,
            distance=path,
            flipped=result.flipped,
            out_of_arena=result.out_of_arena,
            **terms,
        )
        return float(reward), self.task.terminated(result), info

    def _static_info(
        self,
        speed: float,
        yaw_rate: float,
        position: Array,
        wheel_F_z: Array,
        wheel_mu: Array,
        wheel_sinkage: Array,
    ) -> dict[str, Any]:
        est = self.last_estimate
        assert est is not None
        return {
            "command": self._command.copy(),
            "slip_estimate": est.slip_ratio.copy(),
            "slip_estimate_reliable": est.reliable.copy(),
            "speed": float(speed),
            "yaw_rate": float(yaw_rate),
            "position": position.copy(),
            "wheel_F_z": wheel_F_z,
            "wheel_mu": wheel_mu,
            "wheel_sinkage": wheel_sinkage,
        }

    def observation(self, gravity: Array, gyro: Array) -> NDArray[np.float32]:
        """The observation vector from the IMU's attitude and rates (3, 3) and the estimate."""
        est = self.last_estimate
        assert est is not None
        if self.imu_noise > 0:
            gravity = gravity + self._imu_rng.normal(0.0, self.imu_noise, gravity.shape)
            gyro = gyro + self._imu_rng.normal(0.0, self.imu_noise, gyro.shape)
        obs = np.concatenate(
            [
                est.phi_rate,
                self.theta_meas,
                est.theta_rate,
                gravity.ravel(),
                gyro.ravel(),
                est.slip_ratio,
                [est.seg_velocity[1, 0], est.seg_yaw_rate[1]],
                self._command,
                self._prev_action,
            ]
        )
        return obs.astype(np.float32)
