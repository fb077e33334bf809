"""A trained run on the benchmark: its agent as the ``ppo:RUN_DIR`` (``sac:``, ``td3:``) controller.

Validation seeds by default (selection, comparison of runs, ablations); the test seeds only
with ``final=True`` (``--final``), once per agent, recorded in the test ledger
(:mod:`rover_env.benchmark.ledger`).

The benchmark (``rover_env.benchmark``) owns the scenarios, the seed plan, the metrics and
the tables, so a trained agent is judged exactly like the hand-built controllers.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rover_env.benchmark.scenarios import load_scenario, scenario_names
from rover_env.benchmark.suite import run_benchmark
from rover_env.config import ConfigError, load_yaml
from rover_env.policies.ppo import resolve_model_path
from rover_env.policies.specs import parse_specs

# env_kwargs that change only the reward, not what the agent sees or how the rover moves.
# Also the ScenarioMixEnv's training-distribution keys; its action_residual is applied by the
# agent's controller itself (rover_env.policies.ppo), and so is its stall clock.
_REWARD_ONLY = {
    "reward_weights",
    "slip_source",
    "scenarios",
    "speed_scale",
    "yaw_scale",
    "action_residual",
    "residual_base",
    "residual_ramp",
    "action_schedule",
    "stall_clock",
}


def agent_spec(run_dir: str | Path, which: str = "best") -> str:
    """The controller spec of a run's agent (``{algo}:...``): ``best`` (validation-selected, if
    any) or ``final``."""
    from rover_env.training.run import run_algo

    run = Path(run_dir)
    if not (run / "config.yaml").is_file():
        raise FileNotFoundError(f"{run} is not a training run dir: no config.yaml")
    algo = run_algo(run)
    if which == "final":
        if not (run / "model.zip").is_file():
            raise FileNotFoundError(f"{run}: no model.zip (the run has not finished)")
        return f"{algo}:{run / 'model.zip'}"
    if which != "best":
        raise ConfigError(f"which must be 'best' or 'final', got {which!r}")
    data = load_yaml(run / "config.yaml") or {}
    entry: dict[str, Any] = next(iter(data.values()), {}) or {}
    other = sorted(set(entry.get("env_kwargs") or {}) - _REWARD_ONLY)
    if other:
        warnings.warn(
            f"{run} was trained with env_kwargs {other}; the benchmark runs the default env",
            stacklevel=2,
        )
    model, stats = resolve_model_path(run)
    best_stats = run / "best_vecnormalize.pkl"
    if model.name == "best_model.zip" and best_stats.is_file() and stats != best_stats:
        warnings.warn(
            f"the benchmark pairs {model.name} with {stats.name if stats else 'no statistics'}, "
            f"not with the statistics it was selected with ({best_stats.name}); "
            "use which='final' for a consistent pair",
            stacklevel=2,
        )
    return f"{algo}:{run}"


def evaluate(
    run_dir: str | Path,
    episodes: int | None = None,
    out: str | Path | None = None,
    scenarios: Sequence[str] | None = None,
    baselines: Sequence[str] = (),
    which: str = "best",
    duration: float | None = None,
    workers: int = 1,
    progress: bool = True,
    final: bool = False,
    force: bool = False,
    ledger: str | Path | None = None,
    command: str | None = None,
    question: str | None = None,
    questions: str | Path | None = None,
) -> str:
    """Benchmark the run's agent on the first ``episodes`` seeds (default 20) per scenario:
    validation seeds, or with ``final`` the test seeds as a look at the pre-registered
    ``question`` (refused for an agent already in the test ledger unless ``force``); without
    ``baselines`` a final run pairs the agent with the question's baseline.

    ``baselines`` (e.g. ``["open-loop"]``) run on the same seeds; the first is the reference
    of the paired differences. Writes the benchmark's tables and plots to ``out`` (default
    ``RUN_DIR/benchmark``, ``RUN_DIR/benchmark-final`` for a final run) and returns its
    Markdown report.
    """
    run = Path(run_dir)
    spec = agent_spec(run, which)
    names = list(scenarios) if scenarios else scenario_names()
    for n in names:
        load_scenario(n)  # a typo fails before any episode runs
    if final and question and not baselines:
        from rover_env.benchmark.questions import question as registered

        baselines = [registered(question, questions).baseline]
    controllers = parse_specs(",".join([*baselines, spec]))
    files = run_benchmark(
        controllers,
        names,
        20 if episodes is None else episodes,
        (run / ("benchmark-final" if final else "benchmark")) if out is None else out,
        split="validation",
        duration=duration,
        workers=workers,
        progress=progress,
        final=final,
        force=force,
        ledger=ledger,
        command=command,
        question=question,
        questions=questions,
    )
    return files["markdown"].read_text()
