"""Run controllers on scenarios through the environment and collect per-episode metrics.

A benchmark episode is the env with a scenario's task (:class:`rover_env.tasks.ScenarioTask`:
the episode's ground, start pose, fixed command schedule and length) in place of its random
commands. :class:`ScenarioWrapper` gives the env that task (``env.set_task``) and resets it
with the episode's seed; the env itself then commands, observes, scores and truncates the
episode, so the command a controller sees for a step is the one the env scores it against.

Jobs (controller, scenario, seed) are independent; they run through an executor
(:mod:`rover_env.executor`: this process, spawned local processes or Ray workers), each worker
caching one env per (scenario, action layout) and one instance per controller.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from rover_env.benchmark.metrics import STEP_KEYS, metrics_of_steps
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.executor import Executor, make_executor
from rover_env.policies.controllers import EnvController
from rover_env.policies.specs import make_controller
from rover_env.seeds import refuse_final_only
from rover_env.tasks.reward import RewardWeights
from rover_env.tasks.scenario import ScenarioTask
from rover_env.tasks.scenarios import Episode, load_scenario

__all__ = ["Job", "ScenarioWrapper", "run_episode", "run_jobs", "wrapper_for"]

Obs = npt.NDArray[np.float32]


class ScenarioWrapper(gym.Wrapper[Obs, Obs, Obs, Obs]):
    """Drives the env through one :class:`Episode` (its :class:`ScenarioTask`, its seed)."""

    def __init__(self, env: ProtoExplorerEnv) -> None:
        super().__init__(env)
        self.episode: Episode | None = None

    @property
    def base(self) -> ProtoExplorerEnv:
        env = self.env.unwrapped
        assert isinstance(env, ProtoExplorerEnv)
        return env

    def set_episode(
        self, episode: Episode | ScenarioTask, reward_weights: RewardWeights | None = None
    ) -> None:
        """The episode of the next reset (an :class:`Episode`, or its task); the env scores
        it with ``reward_weights`` when given (with an Episode only), else its own."""
        if isinstance(episode, ScenarioTask):
            if reward_weights is not None:
                raise ValueError("set_episode: reward_weights go with an Episode, not a task")
            task = episode
        else:
            task = ScenarioTask(episode, reward_weights)
        self.episode = task.episode
        self.base.set_task(task)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        ep = self.episode
        if ep is None:
            raise RuntimeError("set_episode() before reset()")
        if seed is not None and int(seed) != ep.seed:
            raise ValueError(
                f"ScenarioWrapper.reset(seed={seed}): the episode is {ep.scenario} seed "
                f"{ep.seed}; set_episode() chooses the seed, so it stays in its split"
            )
        return self.env.reset(seed=ep.seed, options=options)


def run_episode(
    wrapper: ScenarioWrapper,
    controller: EnvController,
    episode: Episode,
    observer: Callable[[], None] | None = None,
    reward_weights: RewardWeights | None = None,
) -> dict[str, float]:
    """One episode; the metrics of :func:`rover_env.benchmark.metrics.episode_metrics`.

    ``observer`` is called after the reset and after every step (e.g. to render a frame).
    With ``reward_weights`` the env scores the episode with them and the metrics add
    ``return``: the sum of the env's rewards, what an agent trained with those weights
    maximises (:mod:`rover_env.benchmark.baselines` tunes the baselines on it).
    """
    wrapper.set_episode(episode, reward_weights)
    obs, info = wrapper.reset()
    controller.reset(wrapper.base)
    if observer is not None:
        observer()
    start = np.asarray(info["position"]).copy()
    steps: dict[str, list[Any]] = {k: [] for k in STEP_KEYS}
    last = info
    total = 0.0
    while True:
        action = controller.action(wrapper.base, obs)
        obs, reward, terminated, truncated, last = wrapper.step(action)
        total += float(reward)
        for k in STEP_KEYS:
            steps[k].append(last[k])
        if observer is not None:
            observer()
        if terminated or truncated:
            break
    metrics = metrics_of_steps(
        steps,
        start=start,
        last_info=last,
        commanded_path=episode.schedule.path_length(episode.duration),
        goal_fraction=episode.goal_fraction,
        step_dt=wrapper.base.control_dt,
    )
    if reward_weights is not None:
        metrics["return"] = total
    return metrics


@dataclass(frozen=True)
class Job:
    controller: str
    scenario: str
    seed: int
    duration: float | None = None
    reward_weights: tuple[tuple[str, float], ...] | None = None
    """RewardWeights fields as (name, value) pairs: the episode's ``return`` under them
    (:func:`run_episode`); None: no return recorded."""

    @property
    def key(self) -> str:
        """Names the episode in a study's results file (``--resume`` matches on it)."""
        key = f"{self.controller}|{self.scenario}|{self.seed}|{self.duration}"
        return key if self.reward_weights is None else f"{key}|{dict(self.reward_weights)}"


# Per-process caches: building an env compiles a MuJoCo model; loading a policy loads torch.
_ENVS: dict[tuple[str, str], ScenarioWrapper] = {}
_CONTROLLERS: dict[str, EnvController] = {}


def wrapper_for(scenario: str, layout: str, episode: Episode) -> ScenarioWrapper:
    """This process's env for ``scenario`` with the given action layout (built once; a
    family's is compiled with its envelope terrain, so every world of it fits)."""
    key = (scenario, layout)
    if key not in _ENVS:
        env = ProtoExplorerEnv(**episode.env_kwargs(), action_layout=layout)
        _ENVS[key] = ScenarioWrapper(env)
    return _ENVS[key]


def run_job(job: Job) -> dict[str, Any]:
    t0 = time.perf_counter()
    if job.controller not in _CONTROLLERS:
        _CONTROLLERS[job.controller] = make_controller(job.controller)
    ctrl = _CONTROLLERS[job.controller]
    episode = load_scenario(job.scenario).episode(job.seed, job.duration)
    wrapper = wrapper_for(job.scenario, ctrl.action_layout, episode)
    weights = None if job.reward_weights is None else RewardWeights(**dict(job.reward_weights))
    metrics = run_episode(wrapper, ctrl, episode, reward_weights=weights)
    return {
        "controller": job.controller,
        "scenario": job.scenario,
        "seed": job.seed,
        **metrics,
        **{f"world.{k}": v for k, v in episode.world.items()},
        "wall_s": time.perf_counter() - t0,
    }


def run_jobs(
    jobs: Sequence[Job],
    workers: int = 1,
    progress: Callable[[dict[str, Any]], None] | None = None,
    final: bool = False,
    executor: Executor | None = None,
) -> list[dict[str, Any]]:
    """All jobs, in their given order; ``progress`` is called as each one finishes.

    Test seeds need ``final=True``: only a final run (``run_benchmark(final=True)``, which
    the test ledger records) may play them; spent seeds are refused always. ``executor`` defaults to ``workers`` spawned local
    processes (no MuJoCo or torch state shared through fork); ``workers <= 1`` runs them in
    this process.
    """
    refuse_final_only([j.seed for j in jobs], "benchmark jobs", final=final)
    ex = executor or make_executor("local", workers, start_method="spawn")
    tick = None if progress is None else (lambda _i, row: progress(row))
    return ex.map(run_job, list(jobs), on_result=tick)
