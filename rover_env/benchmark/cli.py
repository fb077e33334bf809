"""``rover-env benchmark`` and ``rover-env tune-slip-pi``.

Wire into ``rover_env.cli`` with ``add_cli(subparsers)``; standalone:
``python -m rover_env.benchmark.cli benchmark ...``.
"""

from __future__ import annotations

import argparse
import csv
import os
import shlex
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["add_cli", "main", "run_benchmark", "run_tuning"]


def _scenarios(text: str, default_filter: str | None = None) -> list[str]:
    from rover_env.benchmark.scenarios import load_scenario, scenario_names

    if text == "all":
        names = scenario_names()
        if default_filter == "slip_wasted":
            names = [n for n in names if load_scenario(n).slip_wasted]
        return names
    names = [s.strip() for s in text.split(",") if s.strip()]
    for n in names:
        load_scenario(n)  # fail early on a typo
    return names


def run_benchmark(
    controllers: Sequence[str],
    scenarios: Sequence[str],
    episodes: int,
    out: str | Path,
    split: str = "test",
    duration: float | None = None,
    workers: int = 1,
    progress: bool = True,
    plots: bool = True,
    command: str | None = None,
    executor: str = "local",
    ray_address: str | None = None,
    resume: bool = False,
) -> dict[str, Path]:
    """Every controller on every scenario for the first ``episodes`` seeds of ``split``.

    Episodes go to ``out/episodes.jsonl`` as they finish; ``resume`` keeps those and runs
    the rest. ``executor``/``ray_address``: :func:`rover_env.executor.make_executor`.
    """
    from rover_env.benchmark.report import write_report
    from rover_env.benchmark.run import Job, _run_job
    from rover_env.benchmark.seeds import seeds as seed_split
    from rover_env.executor import make_executor, run_study

    seed_list = seed_split(split, episodes)
    # Scenario-major, seed, then controller: paired episodes finish close together.
    jobs = [Job(c, s, seed, duration) for s in scenarios for seed in seed_list for c in controllers]
    t0 = time.perf_counter()
    with make_executor(executor, workers, ray_address, start_method="spawn") as ex:
        where = ex.describe()
        rows = run_study(
            ex,
            _run_job,
            jobs,
            [job.key for job in jobs],
            Path(out) / "episodes.jsonl",
            resume=resume,
            desc="benchmark",
            unit="ep",
            progress=progress,
            postfix=lambda row: f"{row['controller']} {row['scenario']} {row['seed']}",
        )
    wall = time.perf_counter() - t0
    meta = {
        "command": f"`{command}`" if command else "(API call)",
        "controllers": ", ".join(controllers),
        "scenarios": ", ".join(scenarios),
        "seeds": f"{split} split, first {episodes} ({seed_list[0]}..{seed_list[-1]})",
        "episode length": (
            f"{duration:g} s (overridden)"
            if duration
            else "each scenario's own (configs/scenarios)"
        ),
        "control": "10 Hz through ProtoExplorerEnv (default sensor noise), estimator at 50 Hz",
        "wall time": f"{wall:.0f} s on the {where}, {len(jobs)} episodes"
        + (" (resumed)" if resume else ""),
    }
    return write_report(out, rows, meta, plots=plots)


def run_tuning(
    scenarios: Sequence[str],
    seeds_per_scenario: int,
    duration: float,
    out: str | Path,
    workers: int = 1,
    refine_evals: int = 8,
    report: str | Path | None = None,
    command: str | None = None,
) -> Path:
    """Tune (Kp, Ki) of the slip PI on tuning seeds and write the gains YAML."""
    import dataclasses

    from rover_env.benchmark.scenarios import load_scenario
    from rover_env.benchmark.seeds import seeds as seed_split
    from rover_env.control.slip_pi import SlipPIConfig, load_slip_pi_config
    from rover_env.control.tuning import tune, write_config

    seed_list = seed_split("tuning", seeds_per_scenario)
    cases = [
        load_scenario(s).episode(seed, duration).drive_case()
        for s in scenarios
        for seed in seed_list
    ]
    out_p = Path(out)
    base = load_slip_pi_config(out_p) if out_p.is_file() else SlipPIConfig()
    res = tune(cases, base=base, workers=workers, refine_evals=refine_evals)
    best = dataclasses.replace(base, kp=res.kp, ki=res.ki)
    header = (
        "Slip PI gains (rover_env.control.slip_pi.SlipPIConfig; the module docstring says why\n"
        "each field is there). Kp and Ki were tuned by rover_env.control.tuning (grid, then\n"
        "Nelder-Mead on the bare simulator); the other fields are design choices kept fixed.\n"
        f"Produced by: {command or '(API call)'}\n"
        f"Scenarios: {', '.join(scenarios)}; tuning seeds {', '.join(map(str, seed_list))};\n"
        f"{duration:g} s episodes; {len(res.evaluations)} gain pairs tried in {res.wall_s:.0f} s;\n"
        f"objective J = {res.score:.4f} (open loop = 1 + 0 penalties)."
    )
    path = write_config(out_p, best, header)
    if report is not None:
        rp = Path(report)
        rp.parent.mkdir(parents=True, exist_ok=True)
        with rp.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=["kp", "ki", "score"])
            w.writeheader()
            w.writerows(res.evaluations)
    print(f"best kp={res.kp:.4f} ki={res.ki:.4f} J={res.score:.4f}; wrote {path}")
    return path


def _command_line() -> str:
    return "rover-env " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def _bench_cli(args: argparse.Namespace) -> int:
    from rover_env.benchmark.controllers import parse_specs

    files = run_benchmark(
        parse_specs(args.controllers),
        _scenarios(args.scenarios),
        args.episodes,
        args.out,
        split=args.split,
        duration=args.duration,
        workers=args.workers,
        progress=not args.quiet,
        plots=not args.no_plots,
        command=_command_line(),
        executor=args.executor,
        ray_address=args.ray_address,
        resume=args.resume,
    )
    print(files["markdown"].read_text())
    print("wrote " + ", ".join(str(p) for p in files.values()))
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


def add_cli(subparsers: Any) -> None:
    """Register ``benchmark`` and ``tune-slip-pi``."""
    from rover_env.executor import add_executor_args

    workers = max(1, min(2, os.cpu_count() or 1))
    p = subparsers.add_parser(
        "benchmark", help="compare controllers on named scenarios (tables, paired CIs, plots)"
    )
    p.add_argument(
        "--controllers",
        default="open-loop,slip-pi",
        help="comma list of open-loop, slip-pi[:GAINS.yaml], ppo:PATH; the first is the "
        "baseline of the paired differences (default open-loop,slip-pi)",
    )
    p.add_argument(
        "--scenarios", default="all", help="comma list of names in configs/scenarios, or all"
    )
    p.add_argument("--episodes", type=int, default=20, help="seeds per scenario (default 20)")
    p.add_argument(
        "--split", default="test", help="seed split (rover_env.benchmark.seeds, default test)"
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


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="rover-env")
    add_cli(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
