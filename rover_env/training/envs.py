"""Training and evaluation vector environments with planned seeds."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecMonitor

import rover_env
from rover_env.config import ConfigError
from rover_env.seeds import check_split
from rover_env.training.config import AlgoConfig


class SeedSchedule(gym.Wrapper[Any, Any, Any, Any]):
    """Takes the seed of each unseeded reset from a fixed list, then lets the env's stream run on.

    Vector envs reset themselves without a seed, so this is how a training env starts from its
    planned seed and how evaluation episode k always meets validation seed k (``rewind``
    before every evaluation makes successive evaluations comparable).
    """

    def __init__(
        self, env: gym.Env[Any, Any], seeds: Sequence[int] = (), split: str = "training"
    ) -> None:
        super().__init__(env)
        self.split = split
        self._seeds = check_split(seeds, split, "SeedSchedule")
        self._next = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        if seed is None and self._next < len(self._seeds):
            seed = self._seeds[self._next]
            self._next += 1
        elif seed is not None:
            check_split([seed], self.split, f"{self.split} env reset")
        return self.env.reset(seed=seed, options=options)

    def rewind(self) -> None:
        self._next = 0

    def rng_state(self) -> dict[str, Any]:
        """The env's generator state and place in the seed list, for checkpoints."""
        gen: np.random.Generator = self.env.unwrapped.np_random
        return {"bit_generator": gen.bit_generator.state, "next": self._next}

    def set_rng_state(self, state: dict[str, Any]) -> None:
        gen = np.random.default_rng()
        gen.bit_generator.state = state["bit_generator"]
        self.env.unwrapped.np_random = gen
        self._next = int(state["next"])


def make_env(
    env_id: str,
    cfg: AlgoConfig,
    seeds: Sequence[int] = (),
    monitor_file: Path | None = None,
    append: bool = False,
    split: str = "training",
) -> gym.Env[Any, Any]:
    """One env: registered id + YAML env_kwargs, planned seeds, Monitor (episode return/length)."""
    import torch

    torch.set_num_threads(1)  # a worker never needs more; SubprocVecEnv workers import torch too
    gym.register_envs(rover_env)
    kwargs: dict[str, Any] = dict(cfg.env_kwargs)
    if cfg.max_episode_steps is not None:
        kwargs["max_episode_steps"] = cfg.max_episode_steps
    env = gym.make(env_id, **kwargs)
    env = SeedSchedule(env, seeds, split)
    filename = None if monitor_file is None else str(monitor_file)
    override = not (append and monitor_file is not None and monitor_file.is_file())
    return Monitor(env, filename=filename, override_existing=override)


def check_env_kwargs(env_id: str, cfg: AlgoConfig, where: str) -> None:
    """Build one env in this process so a bad env_kwargs entry fails here, named, not in a worker."""
    try:
        env = make_env(env_id, cfg)
    except gym.error.Error as exc:
        raise ConfigError(f"{where}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where}.env_kwargs: {exc}") from None
    env.close()


def make_vec_env(
    env_id: str,
    cfg: AlgoConfig,
    n: int,
    seeds: Sequence[Sequence[int]],
    monitor_dir: Path | None,
    prefix: str,
    append: bool = False,
    split: str = "training",
) -> VecEnv:
    """``n`` envs, env ``i`` drawing its resets from ``seeds[i]``; subprocesses if configured and n > 1.

    Every seed must lie in ``split`` (:mod:`rover_env.seeds`): "training" for the training
    envs, "validation" for the evaluation envs.

    ``vec_env: batch`` steps all ``n`` rovers in this process on ``mujoco.batch`` (the env id's
    ``vector_entry_point``, :mod:`rover_env.envs.vector`) behind the same-step adapter
    :class:`rover_env.training.vec_adapter.GymnasiumVecEnv`, with one ``VecMonitor`` file.
    """
    if cfg.vec_env == "batch":
        return make_batch_vec_env(env_id, cfg, n, seeds, monitor_dir, prefix, split)
    fns: list[Callable[[], gym.Env[Any, Any]]] = []
    for i in range(n):
        mfile = None if monitor_dir is None else monitor_dir / f"{prefix}_{i}.monitor.csv"

        def fn(i: int = i, mfile: Path | None = mfile) -> gym.Env[Any, Any]:
            return make_env(env_id, cfg, seeds[i], mfile, append, split)

        fns.append(fn)
    if cfg.vec_env == "subproc" and n > 1:
        return SubprocVecEnv(fns)
    return DummyVecEnv(fns)


def make_batch_vec_env(
    env_id: str,
    cfg: AlgoConfig,
    n: int,
    seeds: Sequence[Sequence[int]],
    monitor_dir: Path | None,
    prefix: str,
    split: str = "training",
) -> VecEnv:
    """``n`` rovers of ``env_id``'s vector env (``gym.make_vec(..., "vector_entry_point")``)."""
    from rover_env.training.vec_adapter import GymnasiumVecEnv

    for i, ss in enumerate(seeds):
        check_split(ss, split, f"{prefix} env {i}")
    gym.register_envs(rover_env)
    kwargs: dict[str, Any] = dict(cfg.env_kwargs)
    if cfg.max_episode_steps is not None:
        kwargs["max_episode_steps"] = cfg.max_episode_steps
    try:
        venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    except gym.error.Error as exc:
        raise ConfigError(f"vec_env: batch: {env_id} has no batched vector env ({exc})") from None
    filename = None if monitor_dir is None else str(monitor_dir / f"{prefix}_batch")
    return VecMonitor(GymnasiumVecEnv(venv, seeds), filename)


def split_episodes(seeds: Sequence[int], n_episodes: int, n_envs: int) -> list[list[int]]:
    """Validation seeds per eval env, matching how ``evaluate_policy`` splits episodes over envs."""
    counts = [(n_episodes + i) // n_envs for i in range(n_envs)]
    if n_episodes > len(seeds):
        raise ConfigError(
            f"n_eval_episodes = {n_episodes} exceeds the {len(seeds)} validation seeds of the seed plan"
        )
    out, k = [], 0
    for c in counts:
        out.append([int(s) for s in seeds[k : k + c]])
        k += c
    return out


# --------------------------------------------------------------------------- the seed plan
# The plan is rover_env.seeds; these only name the parts training uses.


def training_env_seeds(run_seed: int, n_envs: int) -> list[int]:
    """First-reset seed of each training env: the plan's ``training_seed(run, i)``."""
    from rover_env.seeds import training_seed

    try:
        return [training_seed(run_seed, i) for i in range(n_envs)]
    except ValueError as exc:
        raise ConfigError(f"run seed {run_seed}: {exc}") from None


def validation_seeds() -> list[int]:
    from rover_env.seeds import seeds

    return seeds("validation")


def benchmark_test_seeds() -> list[int]:
    from rover_env.seeds import seeds

    return seeds("test")
