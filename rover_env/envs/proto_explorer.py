"""The Proto-Explorer Gymnasium environment: simulation + sensors + one task (:mod:`rover_env.tasks`)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar, Literal

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from rover_env.config import (
    DRIVEN_WHEELS,
    FrictionPatch,
    Obstacle,
    Roughness,
    RoverConfig,
    TerrainConfig,
    load_rover,
    load_terrain,
)
from rover_env.envs.fast_step import FastSampleLoop
from rover_env.estimation.batch import BatchSlipEstimator
from rover_env.estimation.estimator import EstimatorConfig, SlipEstimate
from rover_env.estimation.fast import FastSlipEstimator
from rover_env.estimation.sensors import SensorConfig, SensorModel
from rover_env.sim.batch import RoverIndex
from rover_env.sim.simulator import RoverSim
from rover_env.tasks.base import Task
from rover_env.tasks.reward import RewardWeights
from rover_env.tasks.tracking import RandomTracking
from rover_env.terrain import Terrain

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


# --------------------------------------------------------------------------- settings


@dataclasses.dataclass(frozen=True)
class EnvSettings:
    """The validated constructor arguments of the env, shared by its single and vector forms."""

    rover_cfg: RoverConfig
    base_terrain: TerrainConfig
    randomize_terrain: bool
    control_frequency: float
    reward_weights: RewardWeights
    slip_source: str
    sensor_cfg: SensorConfig
    imu_noise: float
    action_layout: str
    max_speed_command: float
    max_yaw_rate_command: float
    command_interval: tuple[float, float]
    estimator_rate: float

    MAX_SLOPE_DEG: ClassVar[float] = 5.0

    @classmethod
    def build(
        cls,
        rover: RoverConfig | str | Path = "proto_explorer",
        terrain: TerrainConfig | str | Path = "flat",
        control_frequency: float = 10.0,
        reward_weights: RewardWeights | dict[str, float] | None = None,
        slip_source: Literal["true", "estimate"] = "true",
        sensor_noise: Literal["default", "none"] | SensorConfig = "default",
        action_layout: Literal["wheels", "sides"] = "wheels",
        max_speed_command: float = 0.2,
        max_yaw_rate_command: float = 0.3,
        command_interval: tuple[float, float] = (4.0, 8.0),
        randomize_terrain: bool = False,
        estimator_rate: float = 50.0,
        imu_noise: float | None = None,
        render_mode: str | None = None,
        render_modes: Sequence[str] = (),
    ) -> EnvSettings:
        rover_cfg = rover if isinstance(rover, RoverConfig) else load_rover(rover)
        base_terrain = terrain if isinstance(terrain, TerrainConfig) else load_terrain(terrain)
        if randomize_terrain and base_terrain.is_flat:
            raise ValueError("randomize_terrain needs a non-flat terrain (e.g. 'rough')")
        if slip_source not in ("true", "estimate"):
            raise ValueError(f"slip_source must be 'true' or 'estimate', got {slip_source!r}")
        if action_layout not in ("wheels", "sides"):
            raise ValueError(f"action_layout must be 'wheels' or 'sides', got {action_layout!r}")
        if not (math.isfinite(control_frequency) and control_frequency > 0):
            raise ValueError(f"control_frequency must be > 0, got {control_frequency!r}")
        if render_mode is not None and render_mode not in render_modes:
            raise ValueError(f"render_mode must be one of {list(render_modes)}")
        weights = (
            reward_weights
            if isinstance(reward_weights, RewardWeights)
            else RewardWeights(**(reward_weights or {}))
        )
        sensor_cfg = (
            sensor_noise
            if isinstance(sensor_noise, SensorConfig)
            else {"default": SensorConfig(), "none": SensorConfig.ideal()}[sensor_noise]
        )
        # IMU white noise (rad/s on rates, and on the unit gravity vector): MEMS-class.
        imu = (0.0 if sensor_noise == "none" else 0.002) if imu_noise is None else imu_noise
        if not (math.isfinite(imu) and imu >= 0):
            raise ValueError(f"imu_noise must be finite and >= 0, got {imu_noise!r}")
        interval = (float(command_interval[0]), float(command_interval[1]))
        if not 0 < interval[0] <= interval[1]:
            raise ValueError(f"command_interval must be 0 < min <= max, got {command_interval}")
        return cls(
            rover_cfg=rover_cfg,
            base_terrain=base_terrain,
            randomize_terrain=bool(randomize_terrain),
            control_frequency=control_frequency,
            reward_weights=weights,
            slip_source=slip_source,
            sensor_cfg=sensor_cfg,
            imu_noise=imu,
            action_layout=action_layout,
            max_speed_command=float(max_speed_command),
            max_yaw_rate_command=float(max_yaw_rate_command),
            command_interval=interval,
            estimator_rate=estimator_rate,
        )

    @property
    def n_act(self) -> int:
        return 4 if self.action_layout == "wheels" else 2

    def first_terrain(self) -> TerrainConfig:
        """The terrain the simulator is compiled with (the envelope when randomising)."""
        base = self.base_terrain
        return self.envelope_terrain(base) if self.randomize_terrain else base

    def envelope_terrain(self, base: TerrainConfig) -> TerrainConfig:
        """The steepest terrain the randomiser can draw: sizes the compiled heightfield."""
        rough = dataclasses.replace(base.roughness, rms=0.04)
        return dataclasses.replace(
            base, slope_deg=(self.MAX_SLOPE_DEG, self.MAX_SLOPE_DEG), roughness=rough
        )

    def random_terrain(self, rng: np.random.Generator) -> TerrainConfig:
        base = self.base_terrain
        sx, sy = base.size
        patches = []
        for i in range(int(rng.integers(2, 5))):
            mu_x = float(rng.uniform(0.1, 0.45))
            patches.append(
                FrictionPatch(
                    name=f"patch{i}",
                    center=(
                        float(rng.uniform(-sx / 3, sx / 3)),
                        float(rng.uniform(-sy / 3, sy / 3)),
                    ),
                    size=(float(rng.uniform(1.0, 4.0)), float(rng.uniform(1.0, 4.0))),
                    mu_x=mu_x,
                    mu_y=mu_x * 1.25,
                )
            )
        obstacles = []
        for ob in base.obstacles:
            r = float(rng.uniform(2.0, min(sx, sy) / 2 - 1.0))
            a = float(rng.uniform(-np.pi, np.pi))
            obstacles.append(
                Obstacle(
                    name=ob.name,
                    pos=(r * math.cos(a), r * math.sin(a), ob.pos[2]),
                    size=ob.size,
                    yaw_deg=float(rng.uniform(-180, 180)),
                )
            )
        return dataclasses.replace(
            base,
            slope_deg=(
                float(rng.uniform(-self.MAX_SLOPE_DEG, self.MAX_SLOPE_DEG)),
                float(rng.uniform(-self.MAX_SLOPE_DEG, self.MAX_SLOPE_DEG)),
            ),
            roughness=Roughness(
                rms=float(rng.uniform(0.005, 0.04)),
                correlation_length=base.roughness.correlation_length,
                modes=base.roughness.modes,
                seed=int(rng.integers(2**31)),
            ),
            patches=tuple(patches),
            obstacles=tuple(obstacles),
        )


# --------------------------------------------------------------------------- step sums


class StepSums:
    """What a control step accumulates over its estimator samples, for ``n`` rovers."""

    def __init__(self, n: int) -> None:
        self.err_v2 = np.zeros(n)
        self.err_w2 = np.zeros(n)
        self.energy = np.zeros(n)
        self.slip = np.zeros((n, 4))

    @classmethod
    def of_rows(cls, rows: Array) -> StepSums:
        """Sums viewing ``rows`` (n, 7+) = (err_v2, err_w2, energy, slip x 4, ...) per rover."""
        out = cls.__new__(cls)
        out.err_v2, out.err_w2, out.energy = rows[:, 0], rows[:, 1], rows[:, 2]
        out.slip = rows[:, 3:7]
        return out

    def add(
        self,
        command: Array,
        speed: Array,
        yaw_rate: Array,
        tau: Array,
        omega: Array,
        slip: Array,
        copper: float,
        h: float,
    ) -> None:
        """One sample: commands (n, 2), true speed and yaw rate (n,), motor torque and speed
        (n, 4), true slip of the driven wheels (n, 4); h the time the sample stands for."""
        dv = command[:, 0] - speed
        dw = command[:, 1] - yaw_rate
        # Scalar powers, as the single env has always squared (libm pow, not x * x).
        for i in range(dv.shape[0]):
            self.err_v2[i] += dv[i] ** 2
            self.err_w2[i] += dw[i] ** 2
        power = np.sum(np.maximum(tau * omega + copper * tau**2, 0.0), axis=-1)
        self.energy += power * h
        self.slip += np.abs(slip)


# --------------------------------------------------------------------------- per-rover logic


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

    def _info_from(self, sim: RoverSim, index: RoverIndex, vel: Array) -> dict[str, Any]:
        """The info of a new episode, read off ``sim`` (``vel``: scratch of 6)."""
        speed, yaw_rate = segment_velocity(sim, index, vel)
        wt = sim.wheel_truth()
        mu = wheel_friction(sim.terrain, wt.contact_point)
        return self._static_info(
            speed, yaw_rate, sim.data.xpos[index.seg_body[1]], wt.F_z.copy(), mu, wt.sinkage.copy()
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
        vel: Array,
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """A new episode on ``sim`` (rows ``ids`` of ``est``): terrain, start pose,
        sensors, first command and sample; returns the first observation and info."""
        self._reset_sim(sim, rng, options)
        self._start_episode(rng)
        est.reset(ids)
        self._push_sample_from(sim, index, est, ids)
        self.last_estimate = est.estimate(ids)[0]
        info = self._info_from(sim, index, vel)
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
        self,
        a4: Array,
        sums: StepSums,
        row: int,
        slip_true: Array,
        pos0: Array,
        pos: Array,
        flipped: bool,
        t: float,
        rng: np.random.Generator,
        speed: float,
        yaw_rate: float,
        wheel_F_z: Array,
        wheel_mu: Array,
        wheel_sinkage: Array,
    ) -> tuple[float, bool, dict[str, Any]]:
        """Reward, termination and info of a step whose sums are ``sums[row]``; draws the next
        command from ``rng`` when due. ``self.last_estimate`` must hold the step's last estimate."""
        n = self.samples_per_step
        e_v, e_w = math.sqrt(sums.err_v2[row] / n), math.sqrt(sums.err_w2[row] / n)
        est = self.last_estimate
        assert est is not None
        slip_abs_step = sums.slip[row] / n
        x = slip_abs_step.tolist()
        slip_mean = (((x[0] + x[1]) + x[2]) + x[3]) / 4  # np.mean's sum and division, cheaper
        mean_abs_slip = (
            slip_mean if self.slip_source == "true" else float(np.mean(np.abs(est.slip_ratio)))
        )
        w = self.reward_weights
        k_w = math.exp(-((e_w / w.sigma_yaw_rate) ** 2))
        r_track = w.tracking * 0.5 * (math.exp(-((e_v / w.sigma_speed) ** 2)) + k_w)
        if w.yaw_tracking:
            r_track += w.yaw_tracking * k_w
        r_slip = -w.slip * w.slip_penalty(mean_abs_slip)
        energy = float(sums.energy[row])
        r_energy = -w.energy * energy / self.control_dt
        path = float(np.linalg.norm(pos[:2] - pos0[:2]))
        reward = r_track + r_slip + r_energy
        extra: dict[str, float] = {}
        against = speed * float(self._command[0]) < 0
        if w.progress:
            # The benchmark's progress: a step moving against the command counts negative.
            extra["reward_progress"] = w.progress * (-path if against else path) / self.control_dt
            reward += extra["reward_progress"]
        if w.stall_energy:
            v_cmd = abs(float(self._command[0]))
            p = (-path if against else path) / self.control_dt
            idle = min(max(1.0 - p / v_cmd, 0.0), 1.0) if v_cmd > 1e-6 else 0.0
            extra["reward_stall_energy"] = -w.stall_energy * idle * energy / self.control_dt
            reward += extra["reward_stall_energy"]
        if w.sinkage:
            extra["reward_sinkage"] = -w.sinkage * 1000.0 * float(np.mean(wheel_sinkage))
            reward += extra["reward_sinkage"]
        self._prev_action = a4
        out = bool(abs(pos[0]) > self._arena_half[0] or abs(pos[1]) > self._arena_half[1])
        if t >= self._next_command_t:
            self._new_command(rng, t)
        info = self._static_info(speed, yaw_rate, pos, wheel_F_z, wheel_mu, wheel_sinkage)
        info.update(
            reward_tracking=r_track,
            reward_slip=r_slip,
            reward_energy=r_energy,
            tracking_error_speed=e_v,
            tracking_error_yaw_rate=e_w,
            slip_true=slip_true,
            slip_true_mean_abs=slip_mean,
            slip_abs_step=slip_abs_step,
            energy=energy,
            distance=path,
            flipped=flipped,
            out_of_arena=out,
            **extra,
        )
        return float(reward), bool(flipped or out), info

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


def segment_velocity(sim: RoverSim, index: RoverIndex, vel: Array) -> tuple[Any, Any]:
    """Forward speed and yaw rate of the middle segment, as ``sim.segment_truth()`` has them
    (``vel``: a scratch array of 6)."""
    seg2 = int(index.seg_body[1])
    mujoco.mj_objectVelocity(sim.model, sim.data, mujoco.mjtObj.mjOBJ_BODY, seg2, vel, 1)
    return vel[3], vel[2]


def wheel_friction(terrain: Terrain, contact_point: Array) -> Array:
    """Ground friction (mu_x, mu_y) under each wheel's contact point, (..., 2)."""
    out = np.empty((*contact_point.shape[:-1], 2))
    out[..., 0], out[..., 1], _ = terrain.friction(contact_point[..., 0], contact_point[..., 1])
    return out


class ProtoExplorerEnv(RoverEpisode, gym.Env[NDArray[np.float32], NDArray[np.float32]]):
    """Drive the Proto-Explorer rover at a commanded speed and yaw rate while wasting little slip.

    ## Description
    The rover of Yoshida & Shiwa (1998): three segments chained by passive roll/yaw and
    roll/pitch/yaw joints with leaf springs, four driven wheels (front and middle segments)
    with DC motors under PI speed control, two free-rolling rear wheels used for odometry.
    The ground acts through the Gim–Nikravesh tire-slip model on every 1 ms physics substep.
    The task is to follow a commanded forward speed and yaw rate of the middle segment that
    change within an episode, with little wheel slip and little electrical energy.

    ## Action space
    ``Box(-1, 1, (4,), float32)``: speed targets of the driven wheels ``1L 1R 2L 2R``, scaled
    to the motor's maximum wheel speed (4 rad/s by default). With ``action_layout="sides"``,
    ``Box(-1, 1, (2,))``: (left, right), applied to both wheels of a side. Out-of-range
    actions are clipped to [-1, 1]; NaN or inf raises ``ValueError`` naming the entries.

    ## Observation space
    ``Box(-inf, inf, (46,), float32)``: only what the real rover senses, plus the task:

    | index | observation | unit |
    |---|---|---|
    | 0-5 | wheel rates 1L 1R 2L 2R 3L 3R (differentiated encoder angles) | rad/s |
    | 6-10 | joint angles theta_1..theta_5 (potentiometers) | rad |
    | 11-15 | joint rates theta_1..theta_5 (differentiated) | rad/s |
    | 16-24 | gravity direction in each segment's axes (IMU attitude), seg1..seg3 x y z | 1 |
    | 25-33 | IMU angular rates of each segment, seg1..seg3 x y z | rad/s |
    | 34-37 | estimated slip ratio of 1L 1R 2L 2R (kinematic estimator, SPEC §2) | 1 |
    | 38 | estimated forward speed of the middle segment | m/s |
    | 39 | estimated yaw rate of the middle segment | rad/s |
    | 40 | commanded forward speed | m/s |
    | 41 | commanded yaw rate | rad/s |
    | 42-45 | previous action (padded with zeros for the 2-entry layout) | 1 |

    Names in ``rover_env.envs.proto_explorer.OBS_NAMES``. Privileged truth (true slip,
    contact forces, ground friction under each wheel) is only in ``info``.

    ## Rewards
    Each step: ``reward = reward_tracking + reward_slip + reward_energy`` with
    ``reward_tracking = w_track * (exp(-(e_v/0.05)^2) + exp(-(e_w/0.1)^2)) / 2``,
    ``reward_slip = -w_slip * mean |S|`` over the driven wheels (the simulator's true slip,
    or the estimate with ``slip_source="estimate"``; with ``slip_scale`` s > 0 the penalty is
    ``-w_slip * s * ln(1 + mean |S| / s)``, linear below s and logarithmic above) and
    ``reward_energy = -w_energy * P``
    with P the motors' electrical power (W). With non-zero ``progress``, ``yaw_tracking`` or
    ``sinkage`` weights (the *mobility* reward, :class:`rover_env.tasks.RewardWeights`) the
    reward adds ``w_yaw * exp(-(e_w/0.1)^2)``, ``reward_progress = w_progress * p`` (p the
    step's path speed, m/s, negative against the command) and ``reward_sinkage = -w_sink *``
    mean sinkage (mm); these two terms are then in ``info``. ``stall_energy`` adds
    ``reward_stall_energy = -w_stall * P * clip(1 - p / |v_cmd|, 0, 1)``: the power not
    turned into progress at the commanded pace (zero for a command without speed). e_v, e_w: RMS over the step of
    commanded minus actual forward speed (m/s) and yaw rate (rad/s) of the middle segment. Weights:
    ``reward_weights`` (``RewardWeights``, default 1, 1, 0.02; slip_scale 0: linear).

    ## Starting state
    At rest at the arena centre, heading uniform in [-pi, pi), joints straight, after 0.5 s
    of settling on the tires (``reset(options={"x": .., "y": .., "yaw": ..})`` overrides). The rough variant draws new relief, slope, friction patches and
    rock positions every episode from the env's seeded generator.

    ## Episode end
    Termination when a segment tilts beyond 75 deg (flip) or the middle segment leaves the
    arena. Truncation only by the time limit: 300 steps (30 s) by registration.

    ## Info
    ``reward_tracking``, ``reward_slip``, ``reward_energy``; ``slip_true`` and
    ``slip_estimate`` (4,); ``slip_estimate_reliable`` (4,); ``slip_abs_step`` (4,): each
    driven wheel's true |S| averaged over the step's samples (``slip_true_mean_abs`` is their
    mean); ``tracking_error_speed`` and
    ``tracking_error_yaw_rate`` (RMS over the step); ``command`` (2,); ``speed``,
    ``yaw_rate`` (true, middle segment); ``energy`` (J this step); ``distance`` (m this step);
    ``position`` (middle segment, world); ``wheel_F_z`` (6,), ``wheel_sinkage`` (6,) sinkage into loose soil (m, 0 on hard
    ground), ``wheel_mu`` (6, 2) friction
    under each wheel; ``flipped``, ``out_of_arena``.

    ## Arguments
    ``gym.make("rover_env/ProtoExplorer-v0", **kwargs)`` with keyword arguments:
    ``rover`` (config name/path/RoverConfig, default "proto_explorer"), ``terrain``
    (default "flat"), ``control_frequency`` (Hz, 10), ``reward_weights`` (RewardWeights or
    dict), ``slip_source`` ("true" | "estimate"), ``sensor_noise`` ("default" | "none" |
    SensorConfig), ``action_layout`` ("wheels" | "sides"), ``max_speed_command`` (m/s, 0.2),
    ``max_yaw_rate_command`` (rad/s, 0.3), ``command_interval`` ((min, max) s between command
    changes, (4, 8)), ``randomize_terrain`` (bool), ``estimator_rate`` (Hz, 50), ``imu_noise``
    (rad/s; default 0.002, 0 with ``sensor_noise="none"``), ``backend`` ("auto" | "plugin" |
    "numpy": the compiled tire plugin where it builds, else the numpy reference layer; the
    two agree to ~1e-16 m over a drive, see ``rover_env.sim.fast``),
    ``render_mode`` (None | "rgb_array" | "human"), ``width``, ``height``.

    ## Vector environment
    ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")`` (both ids) gives
    :class:`rover_env.envs.vector.ProtoExplorerVectorEnv`: N rovers stepped together on
    ``mujoco.batch`` with the compiled tire plugin, equal rover for rover to N of these envs
    with ``backend="plugin"`` (next-step autoreset, time limit included). For
    stable-baselines3: ``rover_env.training.vec_adapter.GymnasiumVecEnv``.

    ## Task
    What an episode asks (commands, start, ground, length, reward weights) is the env's
    :class:`rover_env.tasks.Task`, :class:`rover_env.tasks.RandomTracking` by default;
    ``set_task`` gives another one (a benchmark scenario, :class:`rover_env.tasks.ScenarioTask`)
    from the next reset on. A task with a time limit truncates the episode at it.

    ## Version history
    * v0: initial release. (Issue 17 moved the command drawing into the task layer, draw for
      draw, and added ``info["slip_abs_step"]``; the episodes of every seed are unchanged.)
    * ``ProtoExplorerSoil-v1`` (stop 41): the loose soil's rut map writes and reads the
      wheel's whole footprint on 5 mm cells (``rover_env.rut``), so ruts no longer depend on
      the grid or the heading (docs/soil.md 3.4b). Episodes on soil differ from v0's; the
      hard-ground ids are unchanged.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}  # noqa: RUF012

    MAX_SLOPE_DEG = EnvSettings.MAX_SLOPE_DEG

    def __init__(
        self,
        rover: RoverConfig | str | Path = "proto_explorer",
        terrain: TerrainConfig | str | Path = "flat",
        control_frequency: float = 10.0,
        reward_weights: RewardWeights | dict[str, float] | None = None,
        slip_source: Literal["true", "estimate"] = "true",
        sensor_noise: Literal["default", "none"] | SensorConfig = "default",
        action_layout: Literal["wheels", "sides"] = "wheels",
        max_speed_command: float = 0.2,
        max_yaw_rate_command: float = 0.3,
        command_interval: tuple[float, float] = (4.0, 8.0),
        randomize_terrain: bool = False,
        estimator_rate: float = 50.0,
        imu_noise: float | None = None,
        backend: Literal["auto", "plugin", "numpy"] = "auto",
        render_mode: str | None = None,
        width: int = 640,
        height: int = 480,
    ) -> None:
        settings = EnvSettings.build(
            rover=rover,
            terrain=terrain,
            control_frequency=control_frequency,
            reward_weights=reward_weights,
            slip_source=slip_source,
            sensor_noise=sensor_noise,
            action_layout=action_layout,
            max_speed_command=max_speed_command,
            max_yaw_rate_command=max_yaw_rate_command,
            command_interval=command_interval,
            randomize_terrain=randomize_terrain,
            estimator_rate=estimator_rate,
            imu_noise=imu_noise,
            render_mode=render_mode,
            render_modes=self.metadata["render_modes"],
        )
        self.sim = RoverSim(settings.rover_cfg, settings.first_terrain(), backend=backend)
        self._configure(settings, self.sim.dt, self.sim.terrain_cfg.size)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.control_dt)}
        self.sensor_model = SensorModel(self.sensor_cfg, np.random.default_rng(0))
        self._index = RoverIndex(self.sim)
        self.estimator: BatchSlipEstimator | FastSlipEstimator
        self._fast: FastSampleLoop | None = None
        if self.sim.backend == "plugin":
            # The compiled fast path: estimator and sample loop in C (rover_env.envs.fast_step).
            self.estimator = FastSlipEstimator(self.rover_cfg, 1, EstimatorConfig())
            self._fast = FastSampleLoop(self.sim, self._index, self.sensor_cfg, self.timing())
        else:
            self.estimator = BatchSlipEstimator(self.rover_cfg, 1, EstimatorConfig())
        self._vel = np.zeros(6)  # scratch of mj_objectVelocity
        self.action_space = spaces.Box(-1.0, 1.0, (settings.n_act,), dtype=np.float32)
        self.observation_space = spaces.Box(-np.inf, np.inf, (len(OBS_NAMES),), dtype=np.float32)
        self.render_mode = render_mode
        self.width, self.height = int(width), int(height)
        self._renderer: mujoco.Renderer | None = None
        self._viewer: Any = None

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        obs, info = self.begin_episode(
            self.sim, self._index, self.estimator, None, self.np_random, options, self._vel
        )
        if self._renderer is not None and self.randomize_terrain:
            self._upload_terrain()
        return obs, info

    def _sample(self) -> SlipEstimate:
        """Read the sensors now, feed the estimator and return its estimate."""
        self._push_sample_from(self.sim, self._index, self.estimator, None)
        return self.estimator.estimate()[0]

    def _driven_slip(self) -> Array:
        if self._index.plugin is not None:
            return self._index.driven_slip(self.sim.data.plugin_state)
        return self.sim.wheel_truth().S[:4]

    def step(
        self, action: NDArray[Any]
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        a4 = self.wheel_targets(action)
        if self._fast is not None and not self.sim.has_command_effects:
            return self._step_fast(a4)
        sim, index, est, vel = self.sim, self._index, self.estimator, self._vel
        d = sim.data
        sim.set_speed_targets(a4 * self.max_wheel_speed)
        seg2 = index.seg_body[1]
        pos0 = d.xpos[seg2].copy()
        sums = StepSums(1)
        command = self._command[None]
        speed = yaw_rate = np.float64(0.0)
        slip = np.zeros(4)
        for _ in range(self.samples_per_step):
            sim.step(self.substeps_per_sample)
            self._push_sample_from(sim, index, est, None)
            speed, yaw_rate = segment_velocity(sim, index, vel)
            slip = self._driven_slip()
            sums.add(
                command,
                np.array([speed]),
                np.array([yaw_rate]),
                d.actuator_force[None, :4],
                d.qvel[None, index.driven_dof],
                slip[None],
                self.copper,
                self.sample_dt,
            )
        self.last_estimate = est.estimate()[0]
        wt = sim.wheel_truth()
        reward, terminated, info = self.finish_step(
            a4,
            sums,
            0,
            slip.copy(),
            pos0,
            d.xpos[seg2].copy(),
            sim.flipped(),
            sim.time,
            self.np_random,
            speed,
            yaw_rate,
            wt.F_z.copy(),
            wheel_friction(sim.terrain, wt.contact_point),
            wt.sinkage.copy(),
        )
        if self.render_mode == "human":
            self.render()
        return self._obs(), reward, terminated, self.task.truncated(sim.time), info

    def _step_fast(
        self, a4: Array
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        """``step`` after the action, with the sample loop in C (same numbers, see fast_step)."""
        sim, index, fast = self.sim, self._index, self._fast
        assert fast is not None and isinstance(self.estimator, FastSlipEstimator)
        d = sim.data
        # set_speed_targets without its checks: a4 is finite and in [-1, 1] (wheel_targets).
        sim.speed_targets[:] = a4 * self.max_wheel_speed
        pos0 = d.xpos[index.seg_body[1]].copy()
        phi0 = self.sensor_model.counter_zero
        if phi0 is None:
            raise RuntimeError("step() before reset()")
        fast.draw_noise(self.sensor_model)
        fast.run(sim, self.estimator, sim.speed_targets, phi0, self._command)
        self.theta_meas = fast.theta.copy()
        s = fast.sums
        self.last_estimate = self.estimator.estimate_one(0)
        f_z, contact = index.wheel_load(d.plugin_state)
        reward, terminated, info = self.finish_step(
            a4,
            StepSums.of_rows(s[None]),
            0,
            s[9:13].copy(),
            pos0,
            d.xpos[index.seg_body[1]].copy(),
            bool((d.xmat[index.seg_body, 8] < index.max_tilt_cos).any()),
            sim.time,
            self.np_random,
            s[7],
            s[8],
            f_z,
            wheel_friction(sim.terrain, contact),
            index.wheel_sinkage(d.plugin_state),
        )
        if self.render_mode == "human":
            self.render()
        return self._obs(), reward, terminated, self.task.truncated(sim.time), info

    def _info_static(self) -> dict[str, Any]:
        return self._info_from(self.sim, self._index, self._vel)

    def _obs(self) -> NDArray[np.float32]:
        return self._obs_from(self.sim, self._index)

    # --- controller adapter (issue 6)
    def controller_input(self, obs: NDArray[np.floating[Any]] | None = None) -> Any:
        """The ``rover_env.control.ControllerInput`` a controller on the rover would see now.

        Built from the newest noisy sensor samples only: the estimator's last output
        (``self.last_estimate``), the joint angles as the potentiometers read them and the current task
        command; never the simulator's truth. The IMU is taken from ``obs``, the observation
        the env just returned, when given (else left out): the env draws IMU noise when it
        builds an observation, and drawing again here would shift that noise stream.
        """
        from rover_env.control.base import ControllerInput

        est = self.last_estimate
        assert est is not None
        gyro = gravity = None
        if obs is not None:
            o = np.asarray(obs, dtype=np.float64).reshape(-1)
            i_g, i_w = OBS_NAMES.index("gravity_seg1_x"), OBS_NAMES.index("gyro_seg1_x")
            gravity, gyro = o[i_g : i_g + 9].reshape(3, 3), o[i_w : i_w + 9].reshape(3, 3)
        return ControllerInput(
            t=float(est.t),
            estimate=est,
            theta=self.theta_meas.copy(),
            speed_command=float(self._command[0]),
            yaw_rate_command=float(self._command[1]),
            imu_gyro=gyro,
            imu_gravity=gravity,
        )

    # ------------------------------------------------------------------ rendering
    def _upload_terrain(self) -> None:
        if self._renderer is not None and not self.sim.terrain_cfg.is_flat:
            ctx = getattr(self._renderer, "_mjr_context", None)
            if ctx is not None:
                mujoco.mjr_uploadHField(self.sim.model, ctx, 0)

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode == "rgb_array":
            if self._renderer is None:
                self._renderer = mujoco.Renderer(self.sim.model, self.height, self.width)
            self._renderer.update_scene(self.sim.data, camera="track")
            return self._renderer.render()
        if self.render_mode == "human":
            if self._viewer is None:
                from mujoco import viewer

                self._viewer = viewer.launch_passive(self.sim.model, self.sim.data)
            self._viewer.sync()
        return None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
