"""``rover-env benchmark``, ``rover-env ablate``, ``rover-env tune-slip-pi`` and
``rover-env tune-baselines``.

Wire into ``rover_env.cli`` with ``add_cli(subparsers)``; standalone:
``python -m rover_env.benchmark.cli benchmark ...``.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from collections.abc import Sequence
from typing import Any

from rover_env.benchmark.suite import run_benchmark, run_tuning

__all__ = ["add_cli", "main", "run_benchmark", "run_tuning"]


def _scenarios(text: str, default_filter: str | None = None, shift: str | None = None) -> list[str]:
    from rover_env.benchmark.scenarios import load_scenario, scenario_names

    if text == "all":
        names = scenario_names()
        if default_filter == "slip_wasted":
            names = [n for n in names if load_scenario(n).slip_wasted]
    else:
        names = [s.strip() for s in text.split(",") if s.strip()]
    for n in names:
        load_scenario(n)  # fail early on a typo
    return names if shift is None else _variants(names, shift)


def _variants(names: list[str], shift: str) -> list[str]:
    """Each scenario's family under ``--shift``: ``train``, a comma list of shift names
    (``train`` among them or not) or ``all`` (training distribution and every shift)."""
    from rover_env.benchmark.scenarios import load_scenario

    want = [v.strip() for v in shift.split(",") if v.strip()]
    out: list[str] = []
    for n in names:
        have = load_scenario(n).variants
        if not have:
            raise ValueError(f"--shift: scenario {n} declares no family")
        pick = have if want == ["all"] else [v for v in want if v in have]
        if not pick:
            raise ValueError(f"--shift {shift}: scenario {n} has none of it; it has {have}")
        out += [f"{n}@{v}" for v in pick]
    return out


def _command_line() -> str:
    return "rover-env " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def _bench_cli(args: argparse.Namespace) -> int:
    from rover_env.benchmark.ledger import FinalRunRefused
    from rover_env.config import ConfigError
    from rover_env.policies.specs import parse_specs

    if args.force and not args.final:
        print("error: --force only applies to --final", file=sys.stderr)
        return 2
    if args.final and not args.question:
        print(
            "error: --final needs --question ID (a question of configs/benchmarks/questions.yaml)",
            file=sys.stderr,
        )
        return 2
    try:
        return _bench(args, parse_specs(args.controllers))
    except FinalRunRefused as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 3
    except (ConfigError, ValueError) as exc:
        if not args.final:
            raise
        print(f"error: {exc}", file=sys.stderr)
        return 2


def _bench(args: argparse.Namespace, specs: list[str]) -> int:
    try:
        scenarios = _scenarios(args.scenarios, shift=args.shift)
    except ValueError as exc:  # ConfigError too
        print(f"error: {exc}", file=sys.stderr)
        return 2
    files = run_benchmark(
        specs,
        scenarios,
        args.episodes,
        args.out,
        split=args.split,
        duration=args.duration,
        workers=args.workers,
        progress=not args.quiet,
        plots=not args.no_plots,
        command=_command_line(),
        final=args.final,
        force=args.force,
        ledger=args.ledger,
        executor=args.executor,
        ray_address=args.ray_address,
        resume=args.resume,
        question=args.question,
        questions=args.questions,
    )
    print(files["markdown"].read_text())
    print("wrote " + ", ".join(str(p) for p in files.values()))
    return 0


def _ablate_cli(args: argparse.Namespace) -> int:
    from rover_env.benchmark.ablation import run_ablation

    try:
        values = [float(v) for v in args.values.split(",") if v.strip()]
    except ValueError:
        print(f"error: --values must be numbers, got {args.values!r}", file=sys.stderr)
        return 2
    res = run_ablation(
        args.base,
        args.knob,
        values,
        _scenarios(args.scenarios),
        args.episodes,
        args.out,
        metric=args.metric,
        duration=args.duration,
        workers=args.workers,
        progress=not args.quiet,
        command=_command_line(),
    )
    print(res.files["ablation"].read_text())
    return 0


def _tune_cli(args: argparse.Namespace) -> int:
    run_tuning(
        _scenarios(args.scenarios, default_filter="slip_wasted"),
        args.seeds,
        args.duration,
        args.out,
        workers=args.workers,
        refine_evals=args.refine,
        report=args.report,
        command=_command_line(),
    )
    return 0


def _tune_baselines_cli(args: argparse.Namespace) -> int:
    from pathlib import Path

    from rover_env.benchmark import baselines as bl
    from rover_env.seeds import seeds

    objective = bl.objective_of(args.agent_config)
    out = Path(args.out)
    if args.from_episodes:
        rows = bl.read_episodes(out / "episodes.jsonl")
        res = bl.from_rows(objective, rows, duration=args.duration)
    else:
        res = bl.tune_baselines(
            objective,
            seeds("tuning", args.seeds_tune),
            seeds("validation", args.seeds_val),
            top=args.top,
            duration=args.duration,
            workers=args.workers,
        )
        bl.write_episodes(out / "episodes.jsonl", res)
    command = _command_line()
    bl.write_report(out / "baselines.md", res, command)
    bl.write_config(out / "baselines.yaml", res, command)
    if args.config:
        bl.write_config(args.config, res, command)
    if args.report:
        bl.write_report(args.report, res, command)
    print(f"best baseline: {res.best.baseline.name} -> {res.best.chosen.spec}; files in {out}")
    return 0


def add_cli(subparsers: Any) -> None:
    """Register ``benchmark``, ``ablate``, ``tune-slip-pi`` and ``tune-baselines``."""
    from rover_env.executor import add_executor_args

    workers = max(1, min(2, os.cpu_count() or 1))
    p = subparsers.add_parser(
        "benchmark", help="compare controllers on named scenarios (tables, paired CIs, plots)"
    )
    p.add_argument(
        "--controllers",
        default="open-loop,slip-pi",
        help="comma list of open-loop, slip-pi[:GAINS.yaml][@field=value...], ppo:PATH, "
        "sac:PATH, td3:PATH; the first is the baseline of the paired differences "
        "(default open-loop,slip-pi)",
    )
    p.add_argument(
        "--scenarios",
        default="all",
        help="comma list of names in configs/scenarios (NAME@train or NAME@SHIFT for a "
        "family's distribution), or all",
    )
    p.add_argument(
        "--shift",
        default=None,
        help="play the scenarios' families: train (the training distribution), shift names, "
        "or all (training and every declared shift, reported side by side)",
    )
    p.add_argument("--episodes", type=int, default=20, help="seeds per scenario (default 20)")
    p.add_argument(
        "--split",
        default="validation",
        choices=("tuning", "validation"),
        help="seed split for selection and tuning (rover_env.seeds, default validation); "
        "the test split needs --final",
    )
    p.add_argument(
        "--final",
        action="store_true",
        help="a look at the test block (4000-4999) for a registered --question: every "
        "controller recorded in the test ledger; a second run of an agent is refused",
    )
    p.add_argument(
        "--question",
        default=None,
        help="with --final (required): the id of the pre-registered question the run answers "
        "(configs/benchmarks/questions.yaml); its looks are counted and spend its alpha",
    )
    p.add_argument(
        "--questions",
        default=None,
        help="questions YAML (default configs/benchmarks/questions.yaml)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="with --final: run although refused (a repeat, a look beyond the plan); rows marked",
    )
    p.add_argument(
        "--ledger", default=None, help="test ledger CSV (default docs/benchmark/test_ledger.csv)"
    )
    p.add_argument("--duration", type=float, default=None, help="episode length override (s)")
    p.add_argument("--workers", type=int, default=workers, help=f"processes (default {workers})")
    add_executor_args(p)
    p.add_argument(
        "--resume",
        action="store_true",
        help="keep the episodes in OUT/episodes.jsonl, run the rest",
    )
    p.add_argument("--out", default="out/benchmark", help="output folder")
    p.add_argument("--no-plots", action="store_true", help="tables only")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_bench_cli)

    p = subparsers.add_parser(
        "ablate",
        help="the no-learning ablation: a grid of one fixed slip-PI setting on validation seeds",
    )
    p.add_argument("--base", default="slip-pi", help="slip-pi[:GAINS] controller (default slip-pi)")
    p.add_argument("--knob", required=True, help="SlipPIConfig field, e.g. stuck_retry_scale")
    p.add_argument("--values", required=True, help="comma list of values, e.g. 0.5,1,2")
    p.add_argument("--scenarios", default="all", help="comma list, or all")
    p.add_argument("--episodes", type=int, default=20, help="validation seeds per scenario (20)")
    p.add_argument("--metric", default="mean_abs_slip", help="ranking metric (mean_abs_slip)")
    p.add_argument("--duration", type=float, default=None, help="episode length override (s)")
    p.add_argument("--workers", type=int, default=workers, help=f"processes (default {workers})")
    p.add_argument("--out", default="out/ablation", help="output folder")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_ablate_cli)

    p = subparsers.add_parser(
        "tune-slip-pi", help="tune the slip PI's (Kp, Ki) on the tuning seeds, write its YAML"
    )
    p.add_argument(
        "--scenarios", default="all", help="comma list, or all scenarios marked slip_wasted"
    )
    p.add_argument("--seeds", type=int, default=2, help="tuning seeds per scenario (default 2)")
    p.add_argument("--duration", type=float, default=15.0, help="episode length (s, default 15)")
    p.add_argument("--refine", type=int, default=8, help="Nelder-Mead evaluations after the grid")
    p.add_argument("--workers", type=int, default=workers, help=f"processes (default {workers})")
    p.add_argument(
        "--out",
        default="configs/control/slip_pi.yaml",
        help="gains YAML to write (its other fields are kept when it exists)",
    )
    p.add_argument("--report", default=None, help="CSV of every gain pair tried")
    p.set_defaults(func=_tune_cli)

    _add_tune_baselines(subparsers)


def _add_tune_baselines(subparsers: Any) -> None:
    """Register ``tune-baselines`` (:mod:`rover_env.benchmark.baselines`)."""
    p = subparsers.add_parser(
        "tune-baselines",
        help="tune open loop, slip PI and set-point PI on an agent's objective (tuning seeds), "
        "choose on validation seeds",
    )
    p.add_argument("--agent-config", required=True, help="the agent's training YAML")
    p.add_argument("--seeds-tune", type=int, default=6, help="tuning seeds per family (6)")
    p.add_argument("--seeds-val", type=int, default=8, help="validation seeds per family (8)")
    p.add_argument("--top", type=int, default=3, help="finalists per baseline (3)")
    p.add_argument("--duration", type=float, default=None, help="episode length override (s)")
    p.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    p.add_argument("--out", default="out/baselines", help="output folder (episodes, report)")
    p.add_argument(
        "--config", default=None, help="also write the chosen settings here (shipped YAML)"
    )
    p.add_argument("--report", default=None, help="also write the report here (Markdown)")
    p.add_argument(
        "--from-episodes",
        action="store_true",
        help="play nothing: rebuild report and config from OUT/episodes.jsonl",
    )
    p.set_defaults(func=_tune_baselines_cli)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="rover-env")
    add_cli(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
