"""Training sweeps: one ``train/{algo}.py`` run per (algorithm, seed), through an executor.

Each run is :func:`rover_env.training.run.train` in a worker (a local process or a Ray
task) and writes the same run folder as ``train/ppo.py``, at ``OUT/{algo}_s{seed}``, with the
single-run command that reproduces it in its ``command.txt``. ``OUT/sweep.jsonl`` gets one line
per finished run. ``resume`` skips finished runs; a run stopped mid-way (the sweep was killed,
or its worker died and the executor retried it) continues from its newest checkpoint, so no
step is trained twice beyond the last checkpoint. On a cluster ``OUT`` must be a folder every
node can write (a shared file system), since the workers write the run folders.
"""

from __future__ import annotations

import shutil
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rover_env.config import ConfigError
from rover_env.executor import make_executor, run_study

__all__ = ["ALGOS", "SweepRun", "default_env_id", "parse_seeds", "run_one", "sweep"]

ALGOS = ("ppo", "sac", "td3")
"""Algorithms a sweep can train. With several, ``config`` is a folder of ``{algo}.yaml`` files
(``configs/agents_soil``) or one file each of them can read."""


def parse_seeds(text: str) -> list[int]:
    """``"0-9"``, ``"0,3,5-7"`` -> the seeds, in order, each once."""
    out: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        try:
            if "-" in part[1:]:
                lo, hi = (int(x) for x in part.split("-", 1))
                if hi < lo:
                    raise ValueError
                out.extend(range(lo, hi + 1))
            else:
                out.append(int(part))
        except ValueError:
            raise ConfigError(
                f"--seeds {text!r}: {part!r} is not a seed or a range A-B (A <= B)"
            ) from None
    if len(set(out)) != len(out):
        raise ConfigError(f"--seeds {text!r}: a seed is listed twice")
    return out


def default_env_id(config: str | Path) -> str:
    """The env id of a hyperparameter file with exactly one entry (else an error naming them)."""
    from rover_env.training.config import entries

    path, data = entries(config)
    ids = list(data)
    if len(ids) != 1:
        raise ConfigError(f"{path}: entries for {ids}; choose one with --env-id")
    return ids[0]


@dataclass(frozen=True)
class SweepRun:
    algo: str
    env_id: str
    config: str
    seed: int
    run_dir: str
    total_timesteps: int | None = None

    @property
    def key(self) -> str:
        return f"{self.algo}|{self.env_id}|{self.seed}"

    def argv(self) -> list[str]:
        """The ``train/{algo}.py`` command line of this run alone."""
        a = [f"train/{self.algo}.py", "--env-id", self.env_id, "--config", self.config]
        a += ["--seed", str(self.seed), "--out", self.run_dir]
        if self.total_timesteps is not None:
            a += ["--total-timesteps", str(self.total_timesteps)]
        return a


def run_one(run: SweepRun) -> dict[str, Any]:
    """Train one run (continuing it from its newest checkpoint if it has one)."""
    from rover_env.training.callbacks import latest_checkpoint
    from rover_env.training.run import RUN_FILES, train

    d = Path(run.run_dir)
    resume = (d / "config.yaml").is_file() and latest_checkpoint(
        d / "checkpoints", run.algo
    ) is not None
    if not resume and any((d / f).exists() for f in RUN_FILES):
        shutil.rmtree(d)  # stopped before its first checkpoint: nothing in it to keep
    argv = sys.argv
    sys.argv = run.argv() + (["--resume"] if resume else [])  # what command.txt records
    try:
        res = train(
            run.env_id,
            None if resume else run.config,
            run.seed,
            d,
            resume=resume,
            total_timesteps=run.total_timesteps,
            progress=False,
            algo=run.algo,
        )
    finally:
        sys.argv = argv
    return {
        "algo": run.algo,
        "env_id": run.env_id,
        "seed": run.seed,
        "run_dir": str(d),
        "num_timesteps": res.num_timesteps,
        "best_mean_reward": res.best_mean_reward,
        "steps_per_second": res.steps_per_second,
        "resumed_from": res.resumed_from,
    }


def sweep(
    config: str | Path,
    seeds: Sequence[int],
    out: str | Path,
    env_id: str | None = None,
    algos: Sequence[str] = ("ppo",),
    total_timesteps: int | None = None,
    executor: str = "local",
    workers: int = 1,
    ray_address: str | None = None,
    resume: bool = False,
    progress: bool = True,
) -> list[dict[str, Any]]:
    """Every (algo, seed) run; their summaries, in (algo, seed) order."""
    from rover_env.training.config import config_for, load_algo_config, resolve_config_path

    for a in algos:
        if a not in ALGOS:
            raise ConfigError(f"--algos: unknown algorithm {a!r}; available: {', '.join(ALGOS)}")
    paths = {a: resolve_config_path(config_for(config, a)).resolve() for a in algos}
    env = env_id or default_env_id(paths[algos[0]])
    for a in algos:
        load_algo_config(a, paths[a], env)  # a bad file or env id fails here, not in a worker
    root = Path(out).resolve()
    runs = [
        SweepRun(a, env, str(paths[a]), s, str(root / f"{a}_s{s}"), total_timesteps)
        for a in algos
        for s in seeds
    ]
    if not resume:
        from rover_env.training.run import RUN_FILES

        for r in runs:
            if any((Path(r.run_dir) / f).exists() for f in RUN_FILES):
                raise ConfigError(
                    f"{r.run_dir} already holds a training run; --resume the sweep or choose"
                    " another --out"
                )
    with make_executor(executor, workers, ray_address, start_method="spawn") as ex:
        return run_study(
            ex,
            run_one,
            runs,
            [r.key for r in runs],
            root / "sweep.jsonl",
            resume=resume,
            desc="sweep",
            unit="run",
            progress=progress,
            postfix=lambda r: f"{r['algo']} seed {r['seed']}",
        )
