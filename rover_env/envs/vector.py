"""``ProtoExplorerEnv`` for N rovers stepped together: a Gymnasium ``VectorEnv`` on ``mujoco.batch``.

``gymnasium.make_vec("rover_env/ProtoExplorer-v0", num_envs=N,
vectorization_mode="vector_entry_point")`` (and ``ProtoExplorerRough-v0``) builds
:class:`ProtoExplorerVectorEnv`. It gives, rover for rover, what ``N`` separate
``ProtoExplorerEnv(backend="plugin")`` in a ``SyncVectorEnv`` give for the same seeds and
actions: observations, rewards, terminations, truncations (the registered time limit) and
infos, bit for bit (``tests/test_vector.py``), with Gymnasium's next-step autoreset.

How:

* Physics: one :class:`~rover_env.sim.batch.BatchRoverSim` steps every running rover on a
  thread pool (the tire plugin inside each ``mj_step``), one estimator sample at a time.
* Everything per episode (terrain draw, start pose, settling, sensor and IMU noise streams,
  commands, reward, info, observation) is :class:`~rover_env.envs.episode.RoverEpisode`
  logic, the very code ``ProtoExplorerEnv`` runs, one object per rover. Resets run on one
  template ``RoverSim`` whose settled state (plugin state included) is copied into the
  rover's batch row; with per-episode terrain (``randomize_terrain``, the rough variant)
  each rover keeps a copy of the template's model with its own ground
  (``mujoco.batch.Batch.set_models``); so does each rover once a task gives it a ground of
  its own (a scenario family's world: ``set_attr("task", [ScenarioTask(...), ...])``, the
  simulator compiled with the family's envelope terrain, ``Episode.envelope``).
* What costs per sample is done for all rovers at once on the batch's bound arrays:
  sensors, segment velocity (``mj_objectVelocity``'s arithmetic), true slip, motor power,
  and the slip estimator (``FastSlipEstimator``, the compiled estimator the single env
  also runs, so both give the same bits). Only noise draws and scalar bookkeeping loop
  over rovers.
"""

from __future__ import annotations

import copy
from typing import Any, Literal

import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from rover_env.config import TerrainConfig
from rover_env.envs.episode import OBS_NAMES, RoverEpisode
from rover_env.envs.fast_step import FastBatchSampler
from rover_env.envs.settings import EnvOptions, EnvSettings
from rover_env.estimation.estimator import EstimatorConfig
from rover_env.estimation.fast import FastSlipEstimator
from rover_env.estimation.sensors import SensorModel
from rover_env.seeds import check_split, split_of
from rover_env.sim.batch import BatchRoverSim
from rover_env.sim.build import resolve_auto_backend
from rover_env.sim.readers import RoverIndex
from rover_env.sim.sample import BatchRows, StepSample, run_samples
from rover_env.sim.simulator import RoverSim
from rover_env.terrain import Terrain

__all__ = ["ProtoExplorerVectorEnv"]

Obs = NDArray[np.float32]

# Derived MjData fields read after each sample (bound once: a field bound later stays zero
# until the batch's next call on a rover).
_DERIVED = ("xpos", "xmat", "xipos", "ximat", "cvel", "subtree_com", "actuator_force")


class _Episode(RoverEpisode):
    """One rover's episode state inside the vector env (its own seeded generator)."""

    def __init__(self, settings: EnvSettings, dt: float, arena: tuple[float, float]) -> None:
        self._configure(settings, dt, arena)
        self.sensor_model = SensorModel(settings.sensor_cfg, np.random.default_rng(0))
        self._np_random: np.random.Generator | None = None
        self._np_random_seed: int | None = None

    def seed(self, seed: int | None) -> None:
        """As ``gymnasium.Env.reset(seed=...)`` seeds ``np_random``."""
        if seed is not None:
            self._np_random, self._np_random_seed = seeding.np_random(seed)

    @property
    def np_random(self) -> np.random.Generator:
        if self._np_random is None:
            self._np_random, self._np_random_seed = seeding.np_random()
        return self._np_random

    @np_random.setter
    def np_random(self, value: np.random.Generator) -> None:
        self._np_random = value
        self._np_random_seed = -1


class ProtoExplorerVectorEnv(VectorEnv[Obs, Obs, NDArray[Any]]):
    """``num_envs`` Proto-Explorer rovers stepped together (module docstring).

    Args:
        num_envs: number of rovers.
        max_episode_steps: truncation after this many steps (None: never), as the
            ``TimeLimit`` ``gymnasium.make`` adds to the single env.
        nthread: threads of the physics batch (0: all CPUs).
        backend: ``"auto"`` or ``"plugin"``: ``mujoco.batch`` needs the compiled tire plugin
            (Python physics callbacks are refused there), so ``"numpy"`` is refused.
        render_mode: None only.
        **options: :class:`~rover_env.envs.settings.EnvOptions`, the single env's (rover, terrain,
            control_frequency, reward_weights, slip_source, sensor_noise, ...).
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        nthread: int = 0,
        backend: Literal["auto", "plugin"] = "auto",
        render_mode: str | None = None,
        width: int = 640,
        height: int = 480,
        **options: Any,
    ) -> None:
        if int(num_envs) < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        if max_episode_steps is not None and int(max_episode_steps) < 1:
            raise ValueError(f"max_episode_steps must be >= 1 or None, got {max_episode_steps}")
        del width, height  # rendering is not supported here
        settings = EnvSettings.build(
            EnvOptions(**options), render_mode, self.metadata["render_modes"]
        )
        if backend not in ("auto", "plugin"):
            raise ValueError(
                f"ProtoExplorerVectorEnv runs on mujoco.batch, which needs backend='plugin' or "
                f"'auto', got {backend!r}; use vectorization_mode='sync' for the numpy layer"
            )
        if backend == "auto" and resolve_auto_backend(settings.rover_cfg) != "plugin":
            raise RuntimeError(
                "ProtoExplorerVectorEnv needs the compiled tire plugin, unavailable here (see "
                "the warning above); use vectorization_mode='sync' or 'async' instead"
            )
        n = int(num_envs)
        self.num_envs = n
        self.settings = settings
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        self.render_mode = None

        # The template simulator settles every reset; its state is copied into the rows.
        self.sim = RoverSim(settings.rover_cfg, settings.first_terrain(), backend="plugin")
        self.batch = BatchRoverSim(n, template=self.sim, nthread=nthread, derived=_DERIVED)
        self.index = RoverIndex(self.sim)
        self.estimator = FastSlipEstimator(settings.rover_cfg, n, EstimatorConfig())
        arena = self.sim.terrain_cfg.size
        self.episodes = [_Episode(settings, self.sim.dt, arena) for _ in range(n)]
        e0 = self.episodes[0]
        self._sampler: FastBatchSampler | None = FastBatchSampler(
            self.batch, self.index, settings.sensor_cfg, e0.timing()
        )
        """The 50 Hz sample loop in C; None runs the numpy loop (the reference, same bits)."""
        self.terrains: list[Terrain] = [self.sim.terrain] * n
        self._models: list[mujoco.MjModel] | None = None
        if settings.randomize_terrain:
            self._models = [copy.copy(self.sim.model) for _ in range(n)]
            self.batch.set_models(self._models)
        ep = self.episodes[0]
        self.control_dt = ep.control_dt
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.control_dt)}

        self.single_action_space = spaces.Box(-1.0, 1.0, (settings.n_act,), dtype=np.float32)
        self.single_observation_space = spaces.Box(
            -np.inf, np.inf, (len(OBS_NAMES),), dtype=np.float32
        )
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)

        self._observations = np.zeros((n, len(OBS_NAMES)), dtype=np.float32)
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._autoreset = np.zeros(n, dtype=bool)
        self._pos = np.zeros((n, 3))
        self._ran_reset = False

    # ------------------------------------------------------------------ reset
    def _reset_one(
        self, i: int, seed: int | None, options: dict[str, Any] | None
    ) -> tuple[Obs, dict[str, Any]]:
        """Episode start of rover ``i``, exactly as ``ProtoExplorerEnv.reset``."""
        ep = self.episodes[i]
        ep.seed(seed)
        sim = self.sim
        before = sim.terrain_cfg
        obs, info = ep.begin_episode(sim, self.index, self.estimator, [i], ep.np_random, options)
        if self._models is None and sim.terrain_cfg != before:
            self._own_models(before)
        if self._models is not None:
            self._models[i] = copy.copy(sim.model)
            self.terrains[i] = sim.terrain
        self.batch.load([i], sim)
        self._pos[i] = sim.data.xpos[self.index.seg_body[1]]
        self._elapsed[i] = 0
        self._autoreset[i] = False
        return obs, info

    def _own_models(self, before: TerrainConfig) -> None:
        """From now on every rover runs on its own copy of the model: a task set a ground of
        its own (a scenario family's world) on the template, whose model the rovers shared.
        The others keep the ground they run on (``before``)."""
        sim = self.sim
        now = sim.terrain_cfg
        sim.set_terrain(before)
        self._models = [copy.copy(sim.model) for _ in range(self.num_envs)]
        self.terrains = [sim.terrain] * self.num_envs
        sim.set_terrain(now)

    def _reset_many(
        self, ids: list[int], seeds: list[int | None], options: dict[str, Any] | None
    ) -> list[dict[str, Any]]:
        infos = []
        for i in ids:
            self._observations[i], info = self._reset_one(i, seeds[i], options)
            infos.append(info)
        if self._models is not None and ids:
            self.batch.set_models(self._models)
        return infos

    def _reset_rovers(
        self, seed: int | list[int | None] | None, options: dict[str, Any] | None
    ) -> tuple[list[int], list[dict[str, Any]]]:
        """The rovers :meth:`reset` resets, and their infos."""
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, int | np.integer):
            block = [int(seed) + i for i in range(n)]
            # seed + i must not run out of the seed's split into the next block.
            check_split(block, split_of(int(seed)), f"reset(seed={int(seed)}) of {n} rovers")
            seeds = list(block)
        else:
            seeds = list(seed)
        if len(seeds) != n:
            raise ValueError(
                f"If seeds are passed as a list the length must match num_envs={n} "
                f"but got length={len(seeds)}."
            )
        opts = dict(options) if options is not None else None
        mask = np.ones(n, dtype=bool)
        if opts is not None and "reset_mask" in opts:
            mask = opts.pop("reset_mask")
            if not isinstance(mask, np.ndarray) or mask.shape != (n,) or mask.dtype != np.bool_:
                raise ValueError(
                    f"options['reset_mask'] must be a bool numpy array of shape ({n},)"
                )
            if not mask.any():
                raise ValueError("options['reset_mask'] must contain at least one True value")
            if not opts:
                opts = None
        ids = np.flatnonzero(mask).tolist()
        infos = self._reset_many(ids, seeds, opts)
        self._ran_reset = True
        return ids, infos

    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[Obs, dict[str, Any]]:
        """Reset every rover (``SyncVectorEnv``'s seeding: ``seed + i``, or one seed each),
        or those of ``options["reset_mask"]`` (a bool array)."""
        ids, infos = self._reset_rovers(seed, options)
        return self._observations.copy(), self._merge_infos(ids, infos)

    def reset_rows(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[Obs, list[dict[str, Any]]]:
        """:meth:`reset` with one info dict per rover (empty for rovers not reset) instead
        of Gymnasium's columns: what an SB3 ``VecEnv`` hands on, without the round trip
        through arrays (:class:`rover_env.training.vec_adapter.GymnasiumVecEnv`)."""
        ids, infos = self._reset_rovers(seed, options)
        return self._observations.copy(), self._rows(ids, infos)

    def _rows(self, ids: list[int], infos: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """Per-rover info dicts (each a new dict of new values: no later step changes it)."""
        out: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for i, info in zip(ids, infos, strict=True):
            out[i] = info
        return out

    # ------------------------------------------------------------------ step
    def step(
        self, actions: NDArray[Any]
    ) -> tuple[Obs, NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        obs, rewards, terminations, truncations, ids, infos = self._step_all(actions)
        return obs, rewards, terminations, truncations, self._merge_infos(ids, infos)

    def step_rows(
        self, actions: NDArray[Any]
    ) -> tuple[
        Obs, NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], list[dict[str, Any]]
    ]:
        """:meth:`step` with one info dict per rover instead of Gymnasium's columns (see
        :meth:`reset_rows`); every rover has one (its step's, or its autoreset's)."""
        obs, rewards, terminations, truncations, ids, infos = self._step_all(actions)
        return obs, rewards, terminations, truncations, self._rows(ids, infos)

    def _step_all(
        self, actions: NDArray[Any]
    ) -> tuple[
        Obs,
        NDArray[np.float64],
        NDArray[np.bool_],
        NDArray[np.bool_],
        list[int],
        list[dict[str, Any]],
    ]:
        """One step of every rover: observations, rewards, ends, and the infos of rovers
        ``ids`` (ascending)."""
        if not self._ran_reset:
            raise RuntimeError("call reset() before step()")
        n = self.num_envs
        acts = np.asarray(actions)
        if acts.shape[:1] != (n,):
            raise ValueError(f"actions must have a leading axis of {n}, got {acts.shape}")
        rewards = np.zeros(n)
        terminations = np.zeros(n, dtype=bool)
        truncations = np.zeros(n, dtype=bool)
        done_before = np.flatnonzero(self._autoreset).tolist()
        active = np.flatnonzero(~self._autoreset)
        step_infos: dict[int, dict[str, Any]] = {}
        # Next-step autoreset: rovers whose episode ended last step start a new one now.
        reset_infos = self._reset_many(done_before, [None] * n, None)
        if active.size:
            step_infos = self._step_rovers(active, acts, rewards, terminations)
            self._elapsed[active] += 1
            if self.max_episode_steps is not None:
                truncations[active] = self._elapsed[active] >= self.max_episode_steps
        self._autoreset = terminations | truncations
        infos_by_env = dict(zip(done_before, reset_infos, strict=True))
        infos_by_env.update(step_infos)
        ids = sorted(infos_by_env)
        infos = [infos_by_env[i] for i in ids]
        return self._observations.copy(), rewards, terminations, truncations, ids, infos

    def _step_rovers(
        self,
        active: NDArray[np.intp],
        acts: NDArray[Any],
        rewards: NDArray[np.float64],
        terminations: NDArray[np.bool_],
    ) -> dict[int, dict[str, Any]]:
        b, ix, est = self.batch, self.index, self.estimator
        eps = [self.episodes[i] for i in active.tolist()]
        k = active.size
        every = k == self.num_envs
        a4 = np.stack(
            [ep.wheel_targets(acts[i]) for ep, i in zip(eps, active.tolist(), strict=True)]
        )
        lim = self.settings.rover_cfg.motor.max_wheel_speed
        b.speed_targets[active] = np.clip(a4 * eps[0].max_wheel_speed, -lim, lim)
        pos0 = self._pos[active]
        command = np.stack([ep.command for ep in eps])
        ep0 = eps[0]
        rows = BatchRows(b, ix, active, every)
        if self._sampler is not None:
            bufs = self._sampler.begin(active, [ep.sensor_model for ep in eps], command)
            for smp in range(ep0.samples_per_step):
                b.step(ep0.substeps_per_sample, ids=rows.ids)
                self._sampler.sample(smp, est, bufs)
            sample = StepSample.of_rows(bufs[6], bufs[5], pos0)
        else:
            sample = run_samples(
                rows,
                pos0,
                ep0.samples_per_step,
                ep0.substeps_per_sample,
                command,
                [ep.sensor_model for ep in eps],
                est,
                rows.ids,
                ep0.copper,
                ep0.sample_dt,
            )
        rows.finish(sample, [self.terrains[i] for i in active.tolist()])
        estimates = est.estimate(active)
        gravity = ix.gravity(b.field("xmat")[active])
        gyro = ix.gyro_rates(b.sensordata[active])
        infos: dict[int, dict[str, Any]] = {}
        for j, (i, ep) in enumerate(zip(active.tolist(), eps, strict=True)):
            ep.theta_meas = sample.theta[j].copy()
            ep.last_estimate = estimates[j]
            rewards[i], terminations[i], infos[i] = ep.finish_step(a4[j], sample, j, ep.np_random)
            self._observations[i] = ep.observation(gravity[j], gyro[j])
        self._pos[active] = sample.position
        return infos

    # ------------------------------------------------------------------ infos
    def _merge_infos(self, ids: list[int], infos: list[dict[str, Any]]) -> dict[str, Any]:
        """``VectorEnv._add_info`` over ``infos`` (rovers ``ids``, ascending), column-wise."""
        out: dict[str, Any] = {}
        if not ids:
            return out
        keys: dict[str, None] = {}
        for info in infos:
            keys.update(dict.fromkeys(info))
        n = self.num_envs
        for key in keys:
            have = [(i, info[key]) for i, info in zip(ids, infos, strict=True) if key in info]
            first = have[0][1]
            if isinstance(first, dict):
                # Nested dicts are rare here: fall back to Gymnasium's own routine.
                sub: dict[str, Any] = {}
                for i, v in have:
                    sub = self._add_info(sub, v, i)
                array: Any = sub
            elif type(first) in (int, float, bool) or isinstance(first, np.number):
                array = np.zeros(n, dtype=type(first))
                array[[i for i, _ in have]] = [v for _, v in have]
            elif isinstance(first, np.ndarray):
                array = np.zeros((n, *first.shape), dtype=first.dtype)
                array[[i for i, _ in have]] = np.stack([v for _, v in have])
            else:
                array = np.full(n, fill_value=None, dtype=object)
                for i, v in have:
                    array[i] = v
            mask = np.zeros(n, dtype=np.bool_)
            mask[[i for i, _ in have]] = True
            out[key], out[f"_{key}"] = array, mask
        return out

    # ------------------------------------------------------------------ per-rover access
    def get_attr(self, name: str) -> tuple[Any, ...]:
        """An attribute of every rover's episode (``np_random``, ``command``, ...), as
        ``SyncVectorEnv.get_attr`` gives the sub-envs'."""
        return tuple(getattr(ep, name) for ep in self.episodes)

    def set_attr(self, name: str, values: list[Any] | tuple[Any, ...] | Any) -> None:
        """Set an attribute of every rover's episode: one value each, or one for all."""
        if not isinstance(values, list | tuple):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"set_attr: {len(values)} values for {self.num_envs} rovers")
        for ep, v in zip(self.episodes, values, strict=True):
            setattr(ep, name, v)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call (or read) ``name`` on every rover's episode."""
        out = []
        for ep in self.episodes:
            attr = getattr(ep, name)
            out.append(attr(*args, **kwargs) if callable(attr) else attr)
        return tuple(out)

    def close_extras(self, **kwargs: Any) -> None:
        self._models = None
