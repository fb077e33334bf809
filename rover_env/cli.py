"""The ``rover-env`` command line: one subcommand per job."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path


def _paper_sim(args: argparse.Namespace) -> int:
    from rover_env.experiments import paper_sim

    out = paper_sim.run(
        args.out,
        progress=not args.quiet,
        terrain=args.terrain,
        duration=args.duration,
        backend=args.backend,
    )
    print((out / "summary.md").read_text())
    extra = " sinkage.png," if (out / "sinkage.png").exists() and args.terrain else ""
    print(f"wrote {out}/trajectory.png, slip.png,{extra} drive.csv, drive.yaml, summary.md")
    return 0


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return v


def _build_assets(args: argparse.Namespace) -> int:
    from rover_env.config import assets_dir, load_rover
    from rover_env.sim.model import write_assets

    out = Path(args.out) if args.out else assets_dir()
    for p in write_assets(out, load_rover(args.rover)):
        print(f"wrote {p}")
    return 0


def _validate(args: argparse.Namespace) -> int:
    from rover_env.envs.checks import random_steps
    from rover_env.experiments import soil_validation, validation

    if args.only in (None, "core"):
        report = validation.run(args.out, quick=args.quick)
        r = random_steps(steps=500 if args.quick else 10_000)
        with report.open("a") as fh:
            fh.write(
                "\n## Environment endurance\n"
                f"- `rover_env/ProtoExplorerRough-v0`, {r['steps']} random-action steps (seed 0):"
                f" no NaN, no MuJoCo warning, no crash; {r['episodes']} episodes ended,"
                f" {r['flips']} flips, {r['exits']} arena exits. Wall time {r['wall_s']:.0f} s.\n"
            )
        print(report.read_text())
    if args.only in (None, "soil"):
        print(soil_validation.run(args.out, quick=args.quick).read_text())
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rover-env",
        description="Proto-Explorer rover: simulation, experiments and validation.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser(
        "paper-sim", help="the paper's simulation (Figs. 9, 10): trajectory and slip"
    )
    p.add_argument("--out", default="out/paper-sim", help="output folder (default: out/paper-sim)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--terrain",
        default=None,
        help="terrain name or YAML path (default: flat hard ground, the paper's); on loose soil,"
        " e.g. paper-sand, sinkage.png is drawn too",
    )
    p.add_argument(
        "--duration",
        type=_positive_float,
        default=None,
        help="shorten the drive to this many seconds (default: the whole 32 s schedule)",
    )
    p.add_argument(
        "--backend",
        choices=("numpy", "plugin", "auto"),
        default="numpy",
        help="simulator backend (same results; plugin is the fast compiled one)",
    )
    p.set_defaults(func=_paper_sim)

    p = sub.add_parser("build-assets", help="regenerate assets/*.xml from a rover configuration")
    p.add_argument("--rover", default="proto_explorer", help="shipped name or YAML path")
    p.add_argument("--out", default=None, help="folder (default: the package's assets/)")
    p.set_defaults(func=_build_assets)

    p = sub.add_parser(
        "validate",
        help="long physical checks (timestep convergence, 5-minute rough drive, loose soil)",
    )
    p.add_argument("--out", default="out/validation", help="output folder")
    p.add_argument("--quick", action="store_true", help="shortened runs (smoke test)")
    p.add_argument(
        "--only",
        choices=("core", "soil"),
        default=None,
        help="run one part: core (validation.md) or soil (soil.md and its rig curves);"
        " default both",
    )
    p.set_defaults(func=_validate)

    from rover_env.experiments import dead_reckoning

    dead_reckoning.add_cli(sub)
    from rover_env.envs.recording import add_cli as add_record_cli

    add_record_cli(sub)
    from rover_env.benchmark.cli import add_cli as add_benchmark_cli
    from rover_env.benchmark.video import add_cli as add_compare_cli

    add_benchmark_cli(sub)
    add_compare_cli(sub)
    from rover_env.calibration.diagnose import add_cli as add_diagnose_cli
    from rover_env.generators.make_logs import add_cli as add_make_logs_cli

    add_make_logs_cli(sub)
    add_diagnose_cli(sub)
    from rover_env.bags import add_cli as add_import_bag_cli
    from rover_env.calibration.drive_plan import add_cli as add_drive_plan_cli

    add_import_bag_cli(sub)
    add_drive_plan_cli(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    from rover_env.config import ConfigError

    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except ConfigError as exc:
        print(f"rover-env: configuration error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
