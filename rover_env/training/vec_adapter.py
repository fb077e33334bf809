"""A Gymnasium ``VectorEnv`` as a stable-baselines3 ``VecEnv``.

Gymnasium 1.x vector envs reset a finished sub-env on the *next* ``step`` (next-step
autoreset: that step ignores the action and returns the reset observation with reward 0).
SB3 expects the *same-step* form: the step that ends an episode already returns the new
episode's first observation, with the last one in ``infos[i]["terminal_observation"]``,
``infos[i]["TimeLimit.truncated"]`` set for time-limit ends, and the reset's info in
``reset_infos[i]`` (what ``DummyVecEnv`` does around single envs).

:class:`GymnasiumVecEnv` converts: after each step it resets the finished sub-envs at once
through ``reset(options={"reset_mask": done})``, which Gymnasium's vector envs (and
:class:`rover_env.envs.vector.ProtoExplorerVectorEnv`) provide, so the vector env never
sees a next-step autoreset. Vector envs in same-step mode (``final_obs``/``final_info``)
are passed through. Episode boundaries, observations and infos then equal those of
``DummyVecEnv`` over the corresponding single envs (``tests/test_vector.py``).

Planned seeds: ``seeds[i]`` lists the seeds of sub-env ``i``'s first unseeded resets, as
:class:`rover_env.training.envs.SeedSchedule` does for single envs; ``env_method`` serves
that class's ``rewind``, ``rng_state`` and ``set_rng_state`` for checkpoints.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from copy import deepcopy
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

__all__ = ["GymnasiumVecEnv", "split_infos"]


def split_infos(infos: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """Gymnasium's vector info (arrays plus ``_key`` masks) as one dict per sub-env."""
    out: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, value in infos.items():
        if key.startswith("_") and key[1:] in infos:
            continue
        mask = infos.get(f"_{key}")
        if mask is None:
            continue
        if isinstance(value, dict):
            for i, sub in enumerate(split_infos(value, n)):
                if mask[i]:
                    out[i][key] = sub
            continue
        for i in np.flatnonzero(mask).tolist():
            out[i][key] = value[i]
    return out


class GymnasiumVecEnv(VecEnv):
    """SB3 ``VecEnv`` over a Gymnasium ``VectorEnv`` with same-step resets (module docstring).

    Args:
        venv: the Gymnasium vector env (e.g. ``gym.make_vec(id, num_envs=N,
            vectorization_mode="vector_entry_point")``).
        seeds: per sub-env, seeds for its first unseeded resets (then its own stream).
    """

    def __init__(
        self, venv: gym.vector.VectorEnv[Any, Any, Any], seeds: Sequence[Iterable[int]] = ()
    ):
        self.venv = venv
        n = venv.num_envs
        super().__init__(n, venv.single_observation_space, venv.single_action_space)
        self.autoreset_mode = venv.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
        if seeds and len(seeds) != n:
            raise ValueError(f"seeds: one list per sub-env ({n}), got {len(seeds)}")
        self._schedules = [[int(s) for s in ss] for ss in seeds] or [[] for _ in range(n)]
        self._next = [0] * n
        self._actions: np.ndarray | None = None
        # A vector env with step_rows/reset_rows (ProtoExplorerVectorEnv) hands out one info
        # dict per sub-env: no round trip through Gymnasium's info columns.
        self.info_rows = callable(getattr(venv, "step_rows", None)) and callable(
            getattr(venv, "reset_rows", None)
        )
        """Infos come per sub-env from ``step_rows``/``reset_rows`` (False: through
        Gymnasium's info columns, split here and deep-copied as ``DummyVecEnv`` does)."""

    # ------------------------------------------------------------------ seeds
    def _planned(self, i: int, given: int | None) -> int | None:
        if given is not None:
            return given
        sched = self._schedules[i]
        if self._next[i] < len(sched):
            self._next[i] += 1
            return sched[self._next[i] - 1]
        return None

    def _reset(
        self, seeds: list[int | None], options: dict[str, Any] | None
    ) -> tuple[np.ndarray, list[dict[str, Any]]]:
        """Reset through the vector env; infos one dict per sub-env."""
        # Gymnasium's vector envs take one seed per sub-env (VectorEnv.reset is typed int).
        if self.info_rows:
            obs, rows = self.venv.reset_rows(seed=seeds, options=options)  # type: ignore[attr-defined]
            return np.asarray(obs), rows
        obs, infos = self.venv.reset(seed=seeds, options=options)  # type: ignore[arg-type]
        return np.asarray(obs), split_infos(infos, self.num_envs)

    def _step(self, actions: np.ndarray) -> tuple[Any, ...]:
        """The vector env's step; infos one dict per sub-env, the step's own (not shared)."""
        if self.info_rows:
            return self.venv.step_rows(actions)  # type: ignore[attr-defined]
        obs, rewards, terminated, truncated, infos = self.venv.step(actions)
        return obs, rewards, terminated, truncated, deepcopy(split_infos(infos, self.num_envs))

    # ------------------------------------------------------------------ VecEnv API
    def reset(self) -> VecEnvObs:
        seeds = [self._planned(i, self._seeds[i]) for i in range(self.num_envs)]
        options = self._options[0] if self._options and self._options[0] else None
        obs, self.reset_infos = self._reset(seeds, options)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        assert self._actions is not None, "step_async() first"
        obs, rewards, terminated, truncated, info_list = self._step(self._actions)
        self._actions = None
        n = self.num_envs
        obs = np.array(obs)
        dones = np.logical_or(terminated, truncated)
        ended = np.flatnonzero(dones).tolist()
        same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        if same_step:
            for i in ended:
                # The vector env already reset: its info is the reset's, final_* the step's.
                reset_info = info_list[i]
                info_list[i] = dict(reset_info.pop("final_info", {}))
                info_list[i]["terminal_observation"] = reset_info.pop("final_obs")
                self.reset_infos[i] = reset_info
        time_limit = (np.asarray(truncated) & ~np.asarray(terminated)).tolist()
        for i in range(n):
            info_list[i]["TimeLimit.truncated"] = time_limit[i]
        if ended and not same_step:
            for i in ended:
                info_list[i]["terminal_observation"] = obs[i].copy()
            seeds = [self._planned(i, None) if dones[i] else None for i in range(n)]
            reset_obs, per_env = self._reset(seeds, {"reset_mask": dones})
            for i in ended:
                obs[i] = reset_obs[i]
                self.reset_infos[i] = per_env[i]
        return obs, np.asarray(rewards, dtype=np.float32), dones, info_list

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs

    # --- per sub-env attributes and methods
    def _sub_attr(self, name: str) -> list[Any]:
        return list(self.venv.get_attr(name))  # type: ignore[attr-defined]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        if attr_name == "render_mode":  # one for the whole vector env
            return [getattr(self.venv, "render_mode", None) for _ in self._get_indices(indices)]
        values = self._sub_attr(attr_name)
        return [values[i] for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        values = self._sub_attr(attr_name)
        for i in self._get_indices(indices):
            values[i] = value
        self.venv.set_attr(attr_name, values)  # type: ignore[attr-defined]

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        idx = list(self._get_indices(indices))
        own = getattr(self, f"_method_{method_name}", None)
        if own is not None:
            return [own(i, *method_args, **method_kwargs) for i in idx]
        results = self.venv.call(method_name, *method_args, **method_kwargs)  # type: ignore[attr-defined]
        return [results[i] for i in idx]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper[Any, Any, Any, Any]], indices: VecEnvIndices = None
    ) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    # --- SeedSchedule's methods, per sub-env
    def _method_rewind(self, i: int) -> None:
        self._next[i] = 0

    def _method_rng_state(self, i: int) -> dict[str, Any]:
        gen: np.random.Generator = self._sub_attr("np_random")[i]
        return {"bit_generator": gen.bit_generator.state, "next": self._next[i]}

    def _method_set_rng_state(self, i: int, state: dict[str, Any]) -> None:
        gen = np.random.default_rng()
        gen.bit_generator.state = state["bit_generator"]
        gens = self._sub_attr("np_random")
        gens[i] = gen
        self.venv.set_attr("np_random", gens)  # type: ignore[attr-defined]
        self._next[i] = int(state["next"])
