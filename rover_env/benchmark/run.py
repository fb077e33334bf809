"""Run controllers on scenarios through the environment and collect per-episode metrics.

The env draws a new random command every few seconds; a benchmark needs the scenario's fixed
schedule instead. :class:`ScenarioWrapper` (a ``gymnasium.Wrapper``, so the env itself is not
changed) overrides it: after every reset and step it writes the command due at the current
sim time into ``env.unwrapped._command``, sets ``_next_command_t`` to infinity so the env never
draws its own, and patches the command entries of the observation just returned. The command
seen by the controller for a step is therefore the one the env scores that step against.
It also places the rover at the episode's start pose (``reset`` options) and puts the
episode's jittered ground in with ``sim.set_terrain`` before the reset.

Jobs (controller, scenario, seed) are independent; with ``workers > 1`` they run in spawned
processes, each caching one env per (scenario, action layout) and one instance per controller.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from rover_env.benchmark.controllers import EnvController, make_controller
from rover_env.benchmark.scenarios import Episode, load_scenario
from rover_env.control.runner import episode_metrics
from rover_env.envs.proto_explorer import OBS_NAMES, ProtoExplorerEnv

__all__ = ["Job", "ScenarioWrapper", "run_episode", "run_jobs"]

Obs = npt.NDArray[np.float32]

_I_CMD = OBS_NAMES.index("command_speed")


class ScenarioWrapper(gym.Wrapper[Obs, Obs, Obs, Obs]):
    """Drives the env through one :class:`Episode`: start pose, ground, fixed commands."""

    def __init__(self, env: ProtoExplorerEnv) -> None:
        super().__init__(env)
        self.episode: Episode | None = None

    @property
    def base(self) -> ProtoExplorerEnv:
        env = self.env.unwrapped
        assert isinstance(env, ProtoExplorerEnv)
        return env

    def set_episode(self, episode: Episode) -> None:
        self.episode = episode

    def _command(self, obs: Obs) -> tuple[float, float]:
        assert self.episode is not None
        base = self.base
        v, w = self.episode.schedule.at(base.sim.time)
        base._command = np.array([v, w])
        base._next_command_t = math.inf
        obs[_I_CMD : _I_CMD + 2] = (v, w)
        return v, w

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        ep = self.episode
        if ep is None:
            raise RuntimeError("set_episode() before reset()")
        base = self.base
        if base.sim.terrain_cfg != ep.terrain:
            base.sim.set_terrain(ep.terrain)
        x, y, yaw = ep.start
        obs, info = self.env.reset(seed=ep.seed, options={"x": x, "y": y, "yaw": yaw})
        info["command"] = np.array(self._command(obs))
        return obs, info

    def step(self, action: Obs) -> tuple[Obs, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._command(obs)
        assert self.episode is not None
        done_time = self.base.sim.time >= self.episode.duration - 1e-9
        return obs, float(reward), terminated, truncated or done_time, info


def run_episode(
    wrapper: ScenarioWrapper, controller: EnvController, episode: Episode
) -> dict[str, float]:
    """One episode; the metrics of ``rover_env.control.runner.episode_metrics``."""
    wrapper.set_episode(episode)
    obs, info = wrapper.reset()
    controller.reset(wrapper.base)
    start = np.asarray(info["position"]).copy()
    keys = (
        "slip_true",
        "slip_true_mean_abs",
        "tracking_error_speed",
        "tracking_error_yaw_rate",
        "energy",
        "distance",
        "wheel_sinkage",
        "command",
        "speed",
    )
    acc: dict[str, list[Any]] = {k: [] for k in keys}
    last = info
    while True:
        action = controller.action(wrapper.base, obs)
        obs, _, terminated, truncated, last = wrapper.step(action)
        for k in keys:
            acc[k].append(last[k])
        if terminated or truncated:
            break
    return episode_metrics(
        slip_true=np.asarray(acc["slip_true"]),
        slip_true_mean_abs=np.asarray(acc["slip_true_mean_abs"]),
        tracking_error_speed=np.asarray(acc["tracking_error_speed"]),
        tracking_error_yaw_rate=np.asarray(acc["tracking_error_yaw_rate"]),
        energy=np.asarray(acc["energy"]),
        distance=np.asarray(acc["distance"]),
        start=start,
        end=np.asarray(last["position"]),
        flipped=bool(last.get("flipped", False)),
        out_of_arena=bool(last.get("out_of_arena", False)),
        commanded_path=episode.schedule.path_length(episode.duration),
        goal_fraction=episode.goal_fraction,
        sinkage=np.asarray(acc["wheel_sinkage"]),
        speed_command=np.asarray(acc["command"])[:, 0],
        step_dt=wrapper.base.control_dt,
        forward_speed=np.asarray(acc["speed"]),
    )


@dataclass(frozen=True)
class Job:
    controller: str
    scenario: str
    seed: int
    duration: float | None = None


# Per-process caches: building an env compiles a MuJoCo model; loading a policy loads torch.
_ENVS: dict[tuple[str, str], ScenarioWrapper] = {}
_CONTROLLERS: dict[str, EnvController] = {}


def _wrapper_for(scenario: str, layout: str, episode: Episode) -> ScenarioWrapper:
    key = (scenario, layout)
    if key not in _ENVS:
        env = ProtoExplorerEnv(terrain=episode.terrain, action_layout=layout)  # type: ignore[arg-type]
        _ENVS[key] = ScenarioWrapper(env)
    return _ENVS[key]


def _run_job(job: Job) -> dict[str, Any]:
    t0 = time.perf_counter()
    if job.controller not in _CONTROLLERS:
        _CONTROLLERS[job.controller] = make_controller(job.controller)
    ctrl = _CONTROLLERS[job.controller]
    episode = load_scenario(job.scenario).episode(job.seed, job.duration)
    wrapper = _wrapper_for(job.scenario, ctrl.action_layout, episode)
    metrics = run_episode(wrapper, ctrl, episode)
    return {
        "controller": job.controller,
        "scenario": job.scenario,
        "seed": job.seed,
        **metrics,
        "wall_s": time.perf_counter() - t0,
    }


def run_jobs(
    jobs: Sequence[Job],
    workers: int = 1,
    progress: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """All jobs, in their given order; ``progress`` is called as each one finishes."""
    if workers <= 1:
        rows = []
        for job in jobs:
            rows.append(_run_job(job))
            if progress is not None:
                progress(rows[-1])
        return rows
    out: dict[int, dict[str, Any]] = {}
    ctx = mp.get_context("spawn")  # no MuJoCo or torch state shared through fork
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        futures = {pool.submit(_run_job, job): i for i, job in enumerate(jobs)}
        for fut in as_completed(futures):
            out[futures[fut]] = fut.result()
            if progress is not None:
                progress(out[futures[fut]])
    return [out[i] for i in range(len(jobs))]
