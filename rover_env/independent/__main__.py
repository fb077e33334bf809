"""``python -m rover_env.independent --effect rolling_resistance=0.05 --drives 3 --seed 0 --out DIR``."""

from __future__ import annotations

import argparse
import sys

from rover_env.independent.drive import Schedule
from rover_env.independent.effects import EffectError, parse_cli
from rover_env.independent.generate import HEADINGS, make_independent_logs


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m rover_env.independent",
        description="Drive logs from the independent (SPEC-only) generator, with truth.yaml.",
    )
    ap.add_argument(
        "--effect",
        action="append",
        default=[],
        help="name=value[,key=value...], e.g. slope=10,heading_deg=90 (repeatable; none: nuisance only)",
    )
    ap.add_argument("--drives", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--duration", type=float, default=50.0)
    ap.add_argument("--out", required=True)
    ap.add_argument(
        "--no-nuisance", action="store_true", help="the nominal rover, built to drawing"
    )
    ap.add_argument(
        "--plan-csv",
        default=None,
        metavar="FILE",
        help="drive these targets instead of the seeded plans: t,cmd_1L,cmd_1R,cmd_2L,cmd_2R rows"
        " each held until the next (what `rover-env drive-plan` writes); the drive lasts until"
        " the last row",
    )
    ap.add_argument(
        "--first-index",
        type=int,
        default=0,
        help="number the drives (and draw their sensor noise) from here: a follow-up drive of"
        " the same rover (same --seed) is --first-index 3 after three drives",
    )
    ap.add_argument(
        "--effort",
        action="store_true",
        help="also log the drivers' reported motor torque (effort_1L ... effort_2R, N m)",
    )
    ap.add_argument(
        "--headings",
        choices=HEADINGS,
        default="same",
        help="where each drive starts facing: same (+x of the world, every log's frame alike),"
        " drawn (drawn per drive and written as start_heading_deg), unlogged (drawn, not"
        " written); a slope's heading_deg is in the world",
    )
    a = ap.parse_args(argv)
    try:
        effects = dict(parse_cli(s) for s in a.effect)
        paths = make_independent_logs(
            a.out,
            effects,
            drives=a.drives,
            seed=a.seed,
            duration=a.duration,
            nuisance=not a.no_nuisance,
            plan=Schedule.from_csv(a.plan_csv) if a.plan_csv else None,
            first_index=a.first_index,
            effort=a.effort,
            headings=a.headings,
        )
    except (EffectError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for p in paths:
        print(p)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
