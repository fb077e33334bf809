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
    split: str = "validation",
    duration: float | None = None,
    workers: int = 1,
    progress: bool = True,
    plots: bool = True,
    command: str | None = None,
    final: bool = False,
    force: bool = False,
    ledger: str | Path | None = None,
) -> dict[str, Path]:
    """Every controller on every scenario for the first ``episodes`` seeds of ``split``.

    The test split is touched once per agent (:mod:`rover_env.benchmark.ledger`): it needs
    ``final=True``, which runs the test seeds, refuses an agent the ledger already holds
    unless ``force`` and appends the run to ``ledger`` (default
    ``docs/benchmark/test_ledger.csv``).
    """
    from tqdm import tqdm

    from rover_env.benchmark import ledger as test_ledger
    from rover_env.benchmark.report import write_report
    from rover_env.benchmark.run import Job, run_jobs
    from rover_env.seeds import seeds as seed_split

    if final:
        split = "test"
    elif split == "test":
        raise ValueError(
            "the test split is touched once per agent: select and tune on validation, and "
            "run the test seeds with --final (final=True), which the test ledger records"
        )
    ledger_path = Path(ledger) if ledger is not None else test_ledger.default_ledger()
    checked = test_ledger.check_final(controllers, ledger_path, force) if final else {}
    seed_list = seed_split(split, episodes)
    # Scenario-major, seed, then controller: paired episodes finish close together.
    jobs = [Job(c, s, seed, duration) for s in scenarios for seed in seed_list for c in controllers]
    t0 = time.perf_counter()
    with tqdm(total=len(jobs), desc="benchmark", unit="ep", disable=not progress) as bar:

        def tick(row: dict[str, Any]) -> None:
            bar.set_postfix_str(f"{row['controller']} {row['scenario']} {row['seed']}")
            bar.update(1)

        rows = run_jobs(jobs, workers=workers, progress=tick)
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
        "wall time": f"{wall:.0f} s on {workers} worker(s), {len(jobs)} episodes",
    }
    if final:
        repeats = [a for a, (_, rep) in checked.items() if rep]
        meta["test ledger"] = f"final run recorded in {ledger_path}" + (
            f"; REPEATED final run (forced) of {', '.join(repeats)}" if repeats else ""
        )
    files = write_report(out, rows, meta, plots=plots)
    if final:
        config = {
            "controllers": list(controllers),
            "scenarios": list(scenarios),
            "episodes": episodes,
            "seeds": f"{seed_list[0]}..{seed_list[-1]}",
            "duration": duration,
        }
        test_ledger.record_final(
            ledger_path, checked, controllers, rows, config, command or "(API call)"
        )
    return files


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
    from rover_env.benchmark.tuning import tune, write_config
    from rover_env.control.slip_pi import SlipPIConfig, load_slip_pi_config
    from rover_env.seeds import seeds as seed_split

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
        "each field is there). Kp and Ki were tuned by rover_env.benchmark.tuning (grid, then\n"
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
    from rover_env.benchmark.ledger import FinalRunRefused
    from rover_env.policies.specs import parse_specs

    if args.force and not args.final:
        print("error: --force only applies to --final", file=sys.stderr)
        return 2
    try:
        return _bench(args, parse_specs(args.controllers))
    except FinalRunRefused as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 3


def _bench(args: argparse.Namespace, specs: list[str]) -> int:
    files = run_benchmark(
        specs,
        _scenarios(args.scenarios),
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


def add_cli(subparsers: Any) -> None:
    """Register ``benchmark``, ``ablate`` and ``tune-slip-pi``."""
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
        "--split",
        default="validation",
        choices=("tuning", "validation"),
        help="seed split for selection and tuning (rover_env.seeds, default validation); "
        "the test split needs --final",
    )
    p.add_argument(
        "--final",
        action="store_true",
        help="the one test-split run of an agent (every controller but the first baseline): "
        "recorded in the test ledger; a second one is refused",
    )
    p.add_argument(
        "--force", action="store_true", help="with --final: run again, the row marked a repeat"
    )
    p.add_argument(
        "--ledger", default=None, help="test ledger CSV (default docs/benchmark/test_ledger.csv)"
    )
    p.add_argument("--duration", type=float, default=None, help="episode length override (s)")
    p.add_argument("--workers", type=int, default=workers, help=f"processes (default {workers})")
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


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="rover-env")
    add_cli(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
