"""The Proto-Explorer Gymnasium environment."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any, Literal

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

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
from rover_env.estimation.estimator import EstimatorConfig, SlipEstimate, SlipEstimator
from rover_env.estimation.sensors import SensorConfig, SensorModel
from rover_env.sim.simulator import RoverSim

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


@dataclasses.dataclass(frozen=True)
class RewardWeights:
    """reward = tracking * (exp(-(e_v/sigma_v)^2) + exp(-(e_w/sigma_w)^2)) / 2
    - slip * mean |S| - energy * electrical power [W]."""

    tracking: float = 1.0
    slip: float = 1.0
    energy: float = 0.02
    sigma_speed: float = 0.05
    sigma_yaw_rate: float = 0.1

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"reward weight {f.name} must be finite and >= 0, got {v!r}")
        if self.sigma_speed <= 0 or self.sigma_yaw_rate <= 0:
            raise ValueError("reward sigmas must be > 0")


class ProtoExplorerEnv(gym.Env[NDArray[np.float32], NDArray[np.float32]]):
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
    or the estimate with ``slip_source="estimate"``) and ``reward_energy = -w_energy * P``
    with P the motors' electrical power (W). e_v, e_w: RMS over the step of commanded minus
    actual forward speed (m/s) and yaw rate (rad/s) of the middle segment. Weights:
    ``reward_weights`` (``RewardWeights``, default 1, 1, 0.02).

    ## Starting state
    At rest at the arena centre, heading uniform in [-pi, pi), joints straight, after 0.5 s
    of settling on the tires (``reset(options={"x": .., "y": .., "yaw": ..})`` overrides). The rough variant draws new relief, slope, friction patches and
    rock positions every episode from the env's seeded generator.

    ## Episode end
    Termination when a segment tilts beyond 75 deg (flip) or the middle segment leaves the
    arena. Truncation only by the time limit: 300 steps (30 s) by registration.

    ## Info
    ``reward_tracking``, ``reward_slip``, ``reward_energy``; ``slip_true`` and
    ``slip_estimate`` (4,); ``slip_estimate_reliable`` (4,); ``tracking_error_speed`` and
    ``tracking_error_yaw_rate`` (RMS over the step); ``command`` (2,); ``speed``,
    ``yaw_rate`` (true, middle segment); ``energy`` (J this step); ``distance`` (m this step);
    ``position`` (middle segment, world); ``wheel_F_z`` (6,), ``wheel_mu`` (6, 2) friction
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

    ## Version history
    * v0: initial release.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}  # noqa: RUF012

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
        self.rover_cfg = rover if isinstance(rover, RoverConfig) else load_rover(rover)
        base_terrain = terrain if isinstance(terrain, TerrainConfig) else load_terrain(terrain)
        self.base_terrain = base_terrain
        self.randomize_terrain = bool(randomize_terrain)
        if self.randomize_terrain and base_terrain.is_flat:
            raise ValueError("randomize_terrain needs a non-flat terrain (e.g. 'rough')")
        if slip_source not in ("true", "estimate"):
            raise ValueError(f"slip_source must be 'true' or 'estimate', got {slip_source!r}")
        if action_layout not in ("wheels", "sides"):
            raise ValueError(f"action_layout must be 'wheels' or 'sides', got {action_layout!r}")
        if not (math.isfinite(control_frequency) and control_frequency > 0):
            raise ValueError(f"control_frequency must be > 0, got {control_frequency!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}")
        self.slip_source = slip_source
        self.action_layout = action_layout
        self.reward_weights = (
            reward_weights
            if isinstance(reward_weights, RewardWeights)
            else RewardWeights(**(reward_weights or {}))
        )
        self.sensor_cfg = (
            sensor_noise
            if isinstance(sensor_noise, SensorConfig)
            else {"default": SensorConfig(), "none": SensorConfig.ideal()}[sensor_noise]
        )
        # IMU white noise (rad/s on rates, and on the unit gravity vector): MEMS-class.
        self.imu_noise = (
            (0.0 if sensor_noise == "none" else 0.002) if imu_noise is None else imu_noise
        )
        if not (math.isfinite(self.imu_noise) and self.imu_noise >= 0):
            raise ValueError(f"imu_noise must be finite and >= 0, got {imu_noise!r}")
        self.max_speed_command = float(max_speed_command)
        self.max_yaw_rate_command = float(max_yaw_rate_command)
        self.command_interval = (float(command_interval[0]), float(command_interval[1]))
        if not 0 < self.command_interval[0] <= self.command_interval[1]:
            raise ValueError(f"command_interval must be 0 < min <= max, got {command_interval}")

        first = self._envelope_terrain(base_terrain) if self.randomize_terrain else base_terrain
        self.sim = RoverSim(self.rover_cfg, first, backend=backend)
        dt = self.sim.dt
        self.substeps_per_sample = max(1, round(1.0 / (estimator_rate * dt)))
        self.samples_per_step = max(
            1, round(1.0 / (control_frequency * dt * self.substeps_per_sample))
        )
        self.control_dt = self.samples_per_step * self.substeps_per_sample * dt
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.control_dt)}
        self.estimator = SlipEstimator(self.rover_cfg, EstimatorConfig())
        self.sensor_model = SensorModel(self.sensor_cfg, np.random.default_rng(0))
        self.max_wheel_speed = self.rover_cfg.motor.max_wheel_speed
        motor = self.rover_cfg.motor
        k = motor.voltage / motor.no_load_speed
        self._copper = (k * motor.voltage / motor.stall_torque) / k**2  # R / K^2
        n_act = 4 if action_layout == "wheels" else 2
        self.action_space = spaces.Box(-1.0, 1.0, (n_act,), dtype=np.float32)
        self.observation_space = spaces.Box(-np.inf, np.inf, (len(OBS_NAMES),), dtype=np.float32)
        self.render_mode = render_mode
        self.width, self.height = int(width), int(height)
        self._renderer: mujoco.Renderer | None = None
        self._viewer: Any = None
        half = np.array(self.sim.terrain_cfg.size) / 2
        self._arena_half = half - 0.5
        self._prev_action = np.zeros(4)
        self._command = np.zeros(2)
        self._next_command_t = 0.0
        self._est: SlipEstimate | None = None
        self._theta_meas = np.zeros(5)
        self._imu_rng = np.random.default_rng(0)

    # ------------------------------------------------------------------ terrain randomisation
    MAX_SLOPE_DEG = 5.0

    def _envelope_terrain(self, base: TerrainConfig) -> TerrainConfig:
        """The steepest terrain the randomiser can draw: sizes the compiled heightfield."""
        rough = dataclasses.replace(base.roughness, rms=0.04)
        return dataclasses.replace(
            base, slope_deg=(self.MAX_SLOPE_DEG, self.MAX_SLOPE_DEG), roughness=rough
        )

    def _random_terrain(self, rng: np.random.Generator) -> TerrainConfig:
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

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        rng = self.np_random
        if self.randomize_terrain:
            self.sim.set_terrain(self._random_terrain(rng))
        opts = options or {}
        unknown = set(opts) - {"x", "y", "yaw"}
        if unknown:
            raise ValueError(f"reset options: unknown key(s) {sorted(unknown)}; allowed x, y, yaw")
        yaw = float(opts["yaw"]) if "yaw" in opts else float(rng.uniform(-np.pi, np.pi))
        self.sim.reset(x=float(opts.get("x", 0.0)), y=float(opts.get("y", 0.0)), yaw=yaw)
        if self._renderer is not None and self.randomize_terrain:
            self._upload_terrain()
        sensor_seed = int(rng.integers(2**63))
        self.sensor_model = SensorModel(self.sensor_cfg, np.random.default_rng(sensor_seed))
        self._imu_rng = np.random.default_rng(sensor_seed + 1)
        self.estimator.reset()
        self._prev_action = np.zeros(4)
        self._new_command(rng, 0.0)
        self._est = self._sample()
        info = self._info_static()
        return self._obs(), info

    def _new_command(self, rng: np.random.Generator, t: float) -> None:
        v = float(rng.uniform(0.3, 1.0)) * self.max_speed_command
        # A third of the commands go straight: the rover must also hold a heading.
        w = 0.0 if rng.random() < 1 / 3 else float(rng.uniform(-1, 1)) * self.max_yaw_rate_command
        self._command = np.array([v, w])
        self._next_command_t = t + float(rng.uniform(*self.command_interval))

    def _sample(self) -> SlipEstimate:
        s = self.sim.sensors()
        phi, theta = self.sensor_model.read(s.phi, s.theta)
        self._theta_meas = theta
        return self.estimator.update(s.t, phi, theta)

    def _targets(self, action: NDArray[Any]) -> Array:
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {a.shape}")
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

    def step(
        self, action: NDArray[Any]
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        a4 = self._targets(action)
        sim = self.sim
        sim.set_speed_targets(a4 * self.max_wheel_speed)
        pos0 = sim.segment_truth().pos[1].copy()
        err_v2 = err_w2 = 0.0
        energy = 0.0
        slip_true_acc = np.zeros(4)
        h = self.substeps_per_sample * sim.dt
        for _ in range(self.samples_per_step):
            sim.step(self.substeps_per_sample)
            self._est = self._sample()
            seg = sim.segment_truth()
            err_v2 += (self._command[0] - seg.forward_speed[1]) ** 2
            err_w2 += (self._command[1] - seg.yaw_rate[1]) ** 2
            tau = sim.motor_torque()
            omega = sim.data.qvel[sim._driven_dof]
            power = float(np.sum(np.maximum(tau * omega + self._copper * tau**2, 0.0)))
            energy += power * h
            slip_true_acc += np.abs(sim.wheel_truth().S[:4])
        n = self.samples_per_step
        e_v, e_w = math.sqrt(err_v2 / n), math.sqrt(err_w2 / n)
        slip_true = sim.wheel_truth().S[:4].copy()
        est = self._est
        assert est is not None
        mean_abs_slip = (
            float(np.mean(slip_true_acc / n))
            if self.slip_source == "true"
            else float(np.mean(np.abs(est.slip_ratio)))
        )
        w = self.reward_weights
        r_track = (
            w.tracking
            * 0.5
            * (math.exp(-((e_v / w.sigma_speed) ** 2)) + math.exp(-((e_w / w.sigma_yaw_rate) ** 2)))
        )
        r_slip = -w.slip * mean_abs_slip
        r_energy = -w.energy * energy / self.control_dt
        reward = r_track + r_slip + r_energy
        self._prev_action = a4
        pos = sim.segment_truth().pos[1]
        flipped = sim.flipped()
        out = bool(np.any(np.abs(pos[:2]) > self._arena_half))
        if sim.time >= self._next_command_t:
            self._new_command(self.np_random, sim.time)
        info = self._info_static()
        info.update(
            reward_tracking=r_track,
            reward_slip=r_slip,
            reward_energy=r_energy,
            tracking_error_speed=e_v,
            tracking_error_yaw_rate=e_w,
            slip_true=slip_true,
            slip_true_mean_abs=float(np.mean(slip_true_acc / n)),
            energy=energy,
            distance=float(np.linalg.norm(pos[:2] - pos0[:2])),
            flipped=flipped,
            out_of_arena=out,
        )
        if self.render_mode == "human":
            self.render()
        return self._obs(), float(reward), bool(flipped or out), False, info

    def _info_static(self) -> dict[str, Any]:
        est = self._est
        assert est is not None
        seg = self.sim.segment_truth()
        wt = self.sim.wheel_truth()
        mu_x, mu_y, _ = self.sim.terrain.friction(wt.contact_point[:, 0], wt.contact_point[:, 1])
        return {
            "command": self._command.copy(),
            "slip_estimate": est.slip_ratio.copy(),
            "slip_estimate_reliable": est.reliable.copy(),
            "speed": float(seg.forward_speed[1]),
            "yaw_rate": float(seg.yaw_rate[1]),
            "position": seg.pos[1].copy(),
            "wheel_F_z": wt.F_z.copy(),
            "wheel_mu": np.stack([mu_x, mu_y], axis=1),
        }

    # --- controller adapter (issue 6)
    def controller_input(self, obs: NDArray[np.floating[Any]] | None = None) -> Any:
        """The ``rover_env.control.ControllerInput`` a controller on the rover would see now.

        Built from the newest noisy sensor samples only: the estimator's last output
        (``self._est``), the joint angles as the potentiometers read them and the current task
        command; never the simulator's truth. The IMU is taken from ``obs``, the observation
        the env just returned, when given (else left out): the env draws IMU noise when it
        builds an observation, and drawing again here would shift that noise stream.
        """
        from rover_env.control.base import ControllerInput

        est = self._est
        assert est is not None
        gyro = gravity = None
        if obs is not None:
            o = np.asarray(obs, dtype=np.float64).reshape(-1)
            i_g, i_w = OBS_NAMES.index("gravity_seg1_x"), OBS_NAMES.index("gyro_seg1_x")
            gravity, gyro = o[i_g : i_g + 9].reshape(3, 3), o[i_w : i_w + 9].reshape(3, 3)
        return ControllerInput(
            t=float(est.t),
            estimate=est,
            theta=self._theta_meas.copy(),
            speed_command=float(self._command[0]),
            yaw_rate_command=float(self._command[1]),
            imu_gyro=gyro,
            imu_gravity=gravity,
        )

    def _obs(self) -> NDArray[np.float32]:
        est = self._est
        assert est is not None
        s = self.sim.sensors()
        d = self.sim.data
        seg_ids = self.sim._seg_body
        gravity = -d.xmat[seg_ids].reshape(3, 3, 3)[:, 2, :]  # world -z in each segment's axes
        gyro = s.imu_gyro
        if self.imu_noise > 0:
            gravity = gravity + self._imu_rng.normal(0.0, self.imu_noise, gravity.shape)
            gyro = gyro + self._imu_rng.normal(0.0, self.imu_noise, gyro.shape)
        obs = np.concatenate(
            [
                est.phi_rate,
                self._theta_meas,
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
