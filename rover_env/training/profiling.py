"""Where the wall time of a training run goes: simulation, env and adapter Python, policy
inference, VecNormalize, rollout/replay buffer, gradient update.

:func:`profile_training` builds a run's vector env and model exactly as
:func:`rover_env.training.run.train` does (no run dir, no evaluations or checkpoints: the
steady state of ``model.learn``), wraps the calls of each stage in a timer, and trains for a
given number of env steps. Each timer records *exclusive* time (its own, less that of the
timed calls made inside it), so the rows add up to the wall time of ``learn``; what no timer
covers (SB3's loop, tensors, callbacks) is the ``other`` row.

Stages (what a row holds):

* ``physics``: ``BatchRoverSim.step`` (``mj_step`` with the C tire plugin on ``mujoco.batch``);
* ``env core (C sample loop)``: ``FastBatchSampler.sample`` (sensors, estimator push, sums);
* ``env Python (episodes)``: the rest of the vector env's ``step``/``reset`` (per rover:
  wheel targets, reward, info dict, observation; resets and settling);
* ``env workers (subprocess)``: ``SubprocVecEnv`` (single envs in worker processes): the main
  process waits for them and their pipes; ``DummyVecEnv`` the same in this process;
* ``adapter + VecMonitor``: :class:`~rover_env.training.vec_adapter.GymnasiumVecEnv` and
  ``VecMonitor`` around the vector env (same-step resets, per-env infos);
* ``VecNormalize``; ``policy inference`` (the policy's forward pass and value predictions
  while collecting, and off-policy action prediction); ``rollout/replay buffer`` (add,
  returns and advantages); ``gradient update`` (``model.train``, minibatches included).

The timers wrap attributes of the objects (instance attributes shadowing methods) and two
classes' methods (restored on exit); the numbers they change are the timers' own cost
(~1 us per call).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import (
    DummyVecEnv,
    SubprocVecEnv,
    VecEnv,
    VecEnvWrapper,
    VecMonitor,
    VecNormalize,
)

from rover_env.training.algos import build_model
from rover_env.training.config import AlgoConfig
from rover_env.training.envs import make_vec_env, training_env_seeds
from rover_env.training.vec_adapter import GymnasiumVecEnv

__all__ = ["STAGES", "Profile", "Timers", "profile_training"]

STAGES = (
    "physics",
    "env core (C sample loop)",
    "env Python (episodes)",
    "env workers (subprocess)",
    "adapter + VecMonitor",
    "VecNormalize",
    "policy inference",
    "rollout/replay buffer",
    "gradient update",
    "other",
)


class Timers:
    """Exclusive wall time per stage of nested timed calls (a stage's children are subtracted)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        self.calls: dict[str, int] = dict.fromkeys(STAGES, 0)
        self._stack: list[float] = []  # child time accumulated by each open call
        self.outer_s = 0.0
        """Inclusive seconds of the outermost timed calls: what the rows add up to."""

    def wrap(self, stage: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        """``fn`` with its exclusive time added to ``stage``."""
        if stage not in self.seconds:
            raise ValueError(f"unknown stage {stage!r}; stages: {', '.join(STAGES)}")

        @functools.wraps(fn)
        def timed(*args: Any, **kwargs: Any) -> Any:
            self._stack.append(0.0)
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                dt = time.perf_counter() - t0
                child = self._stack.pop()
                self.seconds[stage] += dt - child
                self.calls[stage] += 1
                if self._stack:
                    self._stack[-1] += dt
                else:
                    self.outer_s += dt

        return timed


@dataclasses.dataclass(frozen=True)
class Profile:
    """One profiled run: seconds per stage, totals and the machine's state."""

    label: str
    steps: int
    wall_s: float
    cpu_s: float
    """CPU seconds of this process (all its threads) and of its env worker processes."""
    seconds: dict[str, float]
    load_before: float
    load_after: float
    timed_s: float = float("nan")
    """Inclusive seconds inside the outermost timer (``learn``): the rows' sum. ``wall_s``
    exceeds it by the timer's start-up, and by any preemption between the two clocks."""

    @property
    def steps_per_s(self) -> float:
        return self.steps / self.wall_s

    @property
    def steps_per_cpu_s(self) -> float:
        return self.steps / self.cpu_s if self.cpu_s > 0 else float("nan")

    def ms_per_step(self, stage: str) -> float:
        return 1e3 * self.seconds[stage] / self.steps


def _worker_cpu(venv: VecEnv) -> float:
    """CPU seconds so far of ``SubprocVecEnv`` worker processes in the chain (Linux
    ``/proc``; 0 elsewhere or without workers)."""
    layer: Any = venv
    while isinstance(layer, VecEnvWrapper):
        layer = layer.venv
    total = 0.0
    for proc in getattr(layer, "processes", []) if isinstance(layer, SubprocVecEnv) else []:
        try:
            fields = Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            return 0.0
        total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return total


def _patch(obj: Any, name: str, timers: Timers, stage: str) -> None:
    """Time ``obj.name`` (a bound method) through an instance attribute."""
    setattr(obj, name, timers.wrap(stage, getattr(obj, name)))


@contextlib.contextmanager
def _class_timers(timers: Timers) -> Iterator[None]:
    """Time the batch physics and the C sample loop (class methods, restored on exit)."""
    from rover_env.envs.fast_step import FastBatchSampler
    from rover_env.sim.batch import BatchRoverSim

    saved = [(BatchRoverSim, "step"), (FastBatchSampler, "sample")]
    originals = [getattr(c, n) for c, n in saved]
    BatchRoverSim.step = timers.wrap("physics", BatchRoverSim.step)  # type: ignore[method-assign]
    FastBatchSampler.sample = timers.wrap("env core (C sample loop)", FastBatchSampler.sample)  # type: ignore[method-assign]
    try:
        yield
    finally:
        for (cls, name), fn in zip(saved, originals, strict=True):
            setattr(cls, name, fn)


def _instrument_env(venv: VecEnv, timers: Timers) -> None:
    """Timers on each layer of the wrapper chain, outermost first."""
    layer: Any = venv
    while True:
        if isinstance(layer, VecNormalize):
            stage = "VecNormalize"
        elif isinstance(layer, VecMonitor | GymnasiumVecEnv):
            stage = "adapter + VecMonitor"
        elif isinstance(layer, SubprocVecEnv | DummyVecEnv):
            stage = "env workers (subprocess)"
        else:
            stage = "other"
        for name in ("step_wait", "reset"):
            _patch(layer, name, timers, stage)
        if isinstance(layer, GymnasiumVecEnv):
            for name in ("step", "reset", "step_rows", "reset_rows"):
                if hasattr(layer.venv, name):
                    _patch(layer.venv, name, timers, "env Python (episodes)")
            return
        if not isinstance(layer, VecEnvWrapper):
            return
        layer = layer.venv


def _instrument_model(model: BaseAlgorithm, timers: Timers) -> None:
    if isinstance(model, OffPolicyAlgorithm):
        _patch(model, "predict", timers, "policy inference")  # the actor, past learning_starts
    else:
        for name in ("forward", "predict_values"):
            _patch(model.policy, name, timers, "policy inference")
    buffer = getattr(model, "rollout_buffer", None) or getattr(model, "replay_buffer", None)
    for name in ("add", "compute_returns_and_advantage"):
        if buffer is not None and hasattr(buffer, name):
            _patch(buffer, name, timers, "rollout/replay buffer")
    _patch(model, "train", timers, "gradient update")


def profile_training(
    env_id: str,
    cfg: AlgoConfig,
    steps: int,
    label: str = "",
    seed: int = 0,
    torch_threads: int = 1,
    warmup: int = 0,
    info_rows: bool = True,
) -> Profile:
    """Train ``cfg``'s algorithm for ``steps`` env steps with every stage timed.

    ``warmup`` env steps run first, untimed (process start-up, first rollout); SAC/TD3's
    ``learning_starts`` random steps are timed like any others, so give ``warmup`` beyond
    them. ``info_rows=False`` sends a batched env's infos through Gymnasium's info columns
    (split per env and deep-copied: the adapter's general path, as before ``step_rows``).
    """
    from rover_env.training.run import normalized

    torch.set_num_threads(torch_threads)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    set_random_seed(seed)
    seeds = [[s] for s in training_env_seeds(seed, cfg.n_envs)]
    venv = make_vec_env(env_id, cfg, cfg.n_envs, seeds, None, "train")
    layer: Any = venv
    while isinstance(layer, VecEnvWrapper):
        layer = layer.venv
    if isinstance(layer, GymnasiumVecEnv):
        layer.info_rows = layer.info_rows and info_rows
    timers = Timers()
    try:
        vn = normalized(venv, cfg, training=True)
        model = build_model(cfg, vn)
        # No output: left to itself, learn() opens a logger folder in the temp dir per call.
        model.set_logger(Logger(None, []))
        model.action_space.seed(seed)
        if warmup > 0:
            model.learn(total_timesteps=warmup, reset_num_timesteps=False)
        _instrument_env(vn, timers)
        _instrument_model(model, timers)
        first = model.num_timesteps
        with _class_timers(timers):
            load0 = os.getloadavg()[0]
            t0, c0, w0 = time.perf_counter(), time.process_time(), _worker_cpu(venv)
            learn = timers.wrap("other", model.learn)
            learn(total_timesteps=steps, reset_num_timesteps=False)
            wall = time.perf_counter() - t0
            cpu = time.process_time() - c0 + _worker_cpu(venv) - w0
        done = model.num_timesteps - first
    finally:
        venv.close()
    return Profile(
        label or cfg.vec_env,
        done,
        wall,
        cpu,
        dict(timers.seconds),
        load0,
        os.getloadavg()[0],
        timers.outer_s,
    )


def table(profiles: list[Profile]) -> list[str]:
    """A markdown table: ms per env step of each stage, one column per profile."""
    head = "| ms per env step | " + " | ".join(p.label for p in profiles) + " |"
    lines = [head, "|---|" + "---:|" * len(profiles)]
    for stage in STAGES:
        if all(p.seconds[stage] == 0.0 for p in profiles):
            continue
        cells = " | ".join(f"{p.ms_per_step(stage):.3f}" for p in profiles)
        lines.append(f"| {stage} | {cells} |")
    lines.append(
        "| **total** | " + " | ".join(f"**{1e3 / p.steps_per_s:.3f}**" for p in profiles) + " |"
    )
    lines.append(
        "| env steps / s | " + " | ".join(f"{p.steps_per_s:,.0f}" for p in profiles) + " |"
    )
    lines.append(
        "| env steps / CPU-s (process + env workers) | "
        + " | ".join(f"{p.steps_per_cpu_s:,.0f}" for p in profiles)
        + " |"
    )
    lines.append(
        "| load average before / after | "
        + " | ".join(f"{p.load_before:.2f} / {p.load_after:.2f}" for p in profiles)
        + " |"
    )
    return lines


def profile_main(argv: list[str] | None = None) -> int:
    """``train/profile_training.py``: where an env step's wall time goes in a config's run."""
    import argparse

    from rover_env.config import ConfigError
    from rover_env.training.config import ALGOS, load_algo_config

    ap = argparse.ArgumentParser(
        prog="train/profile_training.py",
        description="Train for --steps env steps (no run dir) and print ms per env step of "
        "each stage: physics, env core, env Python, adapter, VecNormalize, policy inference, "
        "buffer, gradient update.",
    )
    ap.add_argument("--algo", choices=ALGOS, default="ppo")
    ap.add_argument("--env-id", default="rover_env/ProtoExplorer-v0")
    ap.add_argument(
        "--config", default=None, help="hyperparameter file (default: configs/ALGO.yaml)"
    )
    ap.add_argument("--steps", type=int, default=8192, help="timed env steps")
    ap.add_argument(
        "--warmup",
        type=int,
        default=None,
        help="untimed env steps first (default: SAC/TD3's learning_starts, PPO none)",
    )
    ap.add_argument("--torch-threads", type=int, default=1)
    args = ap.parse_args(argv)
    try:
        cfg = load_algo_config(args.algo, args.config or args.algo, args.env_id)
    except ConfigError as exc:
        print(f"error: {exc}")
        return 2
    warmup = args.warmup
    if warmup is None:
        warmup = int(cfg["learning_starts"]) + cfg.n_envs if cfg.off_policy else 0
    label = f"{args.algo} {cfg.vec_env} {cfg.n_envs}"
    p = profile_training(
        args.env_id, cfg, args.steps, label, warmup=warmup, torch_threads=args.torch_threads
    )
    print("\n".join(table([p])))
    return 0
