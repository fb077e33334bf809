"""The Proto-Explorer Gymnasium environment: simulation + sensors + one task (:mod:`rover_env.tasks`)."""

from __future__ import annotations

from typing import Any, Literal

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from rover_env.envs.episode import OBS_NAMES, RoverEpisode
from rover_env.envs.fast_step import FastSampleLoop
from rover_env.envs.settings import EnvOptions, EnvSettings
from rover_env.estimation.batch import BatchSlipEstimator
from rover_env.estimation.estimator import EstimatorConfig
from rover_env.estimation.fast import FastSlipEstimator
from rover_env.estimation.sensors import SensorModel
from rover_env.sim.readers import RoverIndex
from rover_env.sim.sample import SimRows, StepSample, run_samples
from rover_env.sim.simulator import RoverSim

__all__ = ["OBS_NAMES", "EnvSettings", "ProtoExplorerEnv"]

Array = NDArray[np.float64]


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
    Each step the task's reward of what the step did (:class:`rover_env.tasks.reward.StepResult`):
    ``reward_tracking`` (speed and yaw-rate tracking errors e_v, e_w, RMS over the step of
    commanded minus actual, middle segment), ``reward_slip`` (mean |S| of the driven wheels,
    the simulator's true slip or the estimate with ``slip_source="estimate"``) and
    ``reward_energy`` (the motors' electrical power), plus ``reward_progress``,
    ``reward_stall_energy`` and ``reward_sinkage`` when their weights are non-zero (the
    *mobility* reward); each term is one function of :mod:`rover_env.tasks.reward`, whose
    :class:`~rover_env.tasks.RewardWeights` (``reward_weights``) documents the formula.

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
    (rad/s; default 0.002, 0 with ``sensor_noise="none"``), ``timestep`` (physics substep in
    s, default the rover configuration's 1 ms; 2 ms and 5 ms are studied in docs/timestep.md;
    it must divide the 1 / ``estimator_rate`` sample period, and a step still lasts
    1 / ``control_frequency``), ``backend`` ("auto" | "plugin" |
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
        backend: Literal["auto", "plugin", "numpy"] = "auto",
        render_mode: str | None = None,
        width: int = 640,
        height: int = 480,
        **options: Any,
    ) -> None:
        """``options``: :class:`~rover_env.envs.settings.EnvOptions` (## Arguments)."""
        settings = EnvSettings.build(
            EnvOptions(**options), render_mode, self.metadata["render_modes"]
        )
        self.sim = RoverSim(settings.rover_cfg, settings.first_terrain(), backend=backend)
        self._configure(settings, self.sim.dt, self.sim.terrain_cfg.size)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.control_dt)}
        self.sensor_model = SensorModel(self.sensor_cfg, np.random.default_rng(0))
        self._index = RoverIndex(self.sim)
        self._rows = SimRows(self.sim, self._index)
        self.estimator: BatchSlipEstimator | FastSlipEstimator
        self._fast: FastSampleLoop | None = None
        if self.sim.backend == "plugin":
            # The compiled fast path: estimator and sample loop in C (rover_env.envs.fast_step).
            self.estimator = FastSlipEstimator(self.rover_cfg, 1, EstimatorConfig())
            self._fast = FastSampleLoop(self.sim, self._index, self.sensor_cfg, self.timing())
        else:
            self.estimator = BatchSlipEstimator(self.rover_cfg, 1, EstimatorConfig())
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
            self.sim, self._index, self.estimator, None, self.np_random, options
        )
        if self._renderer is not None and self.randomize_terrain:
            self._upload_terrain()
        return obs, info

    def step(
        self, action: NDArray[Any]
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        a4 = self.wheel_targets(action)
        sim, rows = self.sim, self._rows
        pos0 = rows.position()
        if self._fast is not None and not sim.has_command_effects:
            sample = self._samples_in_c(a4, pos0)
        else:
            sim.set_speed_targets(a4 * self.max_wheel_speed)
            sample = run_samples(
                rows,
                pos0,
                self.samples_per_step,
                self.substeps_per_sample,
                self._command[None],
                [self.sensor_model],
                self.estimator,
                None,
                self.copper,
                self.sample_dt,
            )
            self.last_estimate = self.estimator.estimate()[0]
        self.theta_meas = sample.theta[0].copy()
        rows.finish(sample)
        reward, terminated, info = self.finish_step(a4, sample, 0, self.np_random)
        if self.render_mode == "human":
            self.render()
        obs = self._obs_from(sim, self._index)
        return obs, reward, terminated, self.task.truncated(sim.time), info

    def _samples_in_c(self, a4: Array, pos0: Array) -> StepSample:
        """The step's samples by the compiled loop (same numbers, see fast_step)."""
        sim, fast = self.sim, self._fast
        assert fast is not None and isinstance(self.estimator, FastSlipEstimator)
        # set_speed_targets without its checks: a4 is finite and in [-1, 1] (wheel_targets).
        sim.speed_targets[:] = a4 * self.max_wheel_speed
        phi0 = self.sensor_model.counter_zero
        if phi0 is None:
            raise RuntimeError("step() before reset()")
        fast.draw_noise(self.sensor_model)
        fast.run(sim, self.estimator, sim.speed_targets, phi0, self._command)
        self.last_estimate = self.estimator.estimate_one(0)
        return StepSample.of_rows(fast.sums[None], fast.theta[None], pos0)

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
