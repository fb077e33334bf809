"""A bag whose wheel messages are stamped off an even grid, imported on the grid and on the
wheels' own clock: what each does to the encoder counts and to the noise diagnose reads.

Why (stop 100): ``import-bag`` resamples every state onto an even grid by linear
interpolation. A real driver's messages are never on that grid, so each imported wheel angle
is a blend of two whole counts: diagnose then finds no quantisation step and reads the
wheels' noise from smoothed angles. ``import_bag(..., clock="wheels")`` (``--clock wheels``)
takes the rows at the wheel topic's stamps instead. This writes one case's drives (the
independent generator, its build drawn from ``--seed``) with their stamps jittered by up to
``--jitter-ms`` (the angles read at the new stamp, within a count: ``log_variants.py``'s
jitter), publishes them as a driver would (``bag_round_trip.write_bag``), imports them both
ways and prints, per way and beside the jittered logs themselves, the wheel resolution found
and the wheels' noise as diagnose reads it; ``--diagnose`` also diagnoses each.

    python benchmarks/bag_clock.py --seed 70874 --out out/bag_clock [--diagnose]

Writes ``OUT/bag_clock.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from _report import write_report
from bag_round_trip import topic_map, write_bag
from log_variants import variant

from rover_env.bags import import_bag, load_topic_map
from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnose import Options, diagnose
from rover_env.calibration.replay import ReplaySettings, prepare
from rover_env.config import load_rover
from rover_env.independent.generate import make_independent_logs
from rover_env.logs import DriveLog, read_log, write_log

WAYS = ("logs", "grid", "wheels")
"""The jittered logs as written, imported on the even grid, imported on the wheels' clock."""


def noise(logs: list[DriveLog]) -> dict[str, Any]:
    """The wheel resolution found and the driven wheels' noise as diagnose reads them."""
    cfg = load_rover()
    prepared = [prepare(g, cfg, f"d{i}", ReplaySettings()) for i, g in enumerate(logs)]
    floor = rs.noise_floor(prepared)
    return {
        "resolution": rs.resolutions(prepared)[0],
        "wheel_noise": [floor[f"wheel_{w}"] for w in ("1L", "1R", "2L", "2R")],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=70874)
    ap.add_argument("--drives", type=int, default=2)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--jitter-ms", type=float, default=3.0)
    ap.add_argument("--diagnose", action="store_true")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("out/bag_clock"))
    a = ap.parse_args(argv)
    out = a.out
    src = sorted((out / "generated").glob("drive_*.csv")) or make_independent_logs(
        out / "generated", {}, drives=a.drives, seed=a.seed, duration=a.duration
    )
    mp = topic_map(out)
    tmap = load_topic_map(mp)
    logs: dict[str, list[DriveLog]] = {w: [] for w in WAYS}
    for i, p in enumerate(src):
        jit = variant("jitter3", read_log(p), a.seed + i) if a.jitter_ms > 0 else read_log(p)
        bag = out / "bags" / p.stem
        if not bag.exists():
            write_bag(jit, bag, tmap)
        logs["logs"].append(jit)
        logs["grid"].append(import_bag(bag, mp))
        logs["wheels"].append(import_bag(bag, mp, clock="wheels"))
    rows = []
    for way in WAYS:
        row = {"way": way, **noise(logs[way])}
        if a.diagnose:
            paths = [
                write_log(g, out / way / f"drive_{i:02d}.csv", overwrite=True)
                for i, g in enumerate(logs[way])
            ]
            t0 = time.perf_counter()
            res = diagnose([str(p) for p in paths], out / f"diagnose_{way}", Options(
                workers=a.workers, progress=False
            ))  # fmt: skip
            row.update(named=res["named"], seconds=time.perf_counter() - t0)
        rows.append(row)
        print(row, flush=True)
    (out / "bag_clock.json").write_text(json.dumps(rows, indent=1))
    lines = [
        "# A bag's wheel messages off the grid: imported on the grid and on the wheels' clock",
        "",
        f"Independent generator, seed {a.seed} (clean), {len(src)} drives of {a.duration:g} s,"
        f" stamps jittered by up to {a.jitter_ms:g} ms (`benchmarks/bag_clock.py`).",
        "",
        "| logs | wheel resolution found (mrad) | driven wheels' noise read (mrad) | named |",
        "| --- | --- | --- | --- |",
    ]
    for r in rows:
        lines.append(
            f"| {r['way']} | {1e3 * r['resolution']:.3f} | "
            + ", ".join(f"{1e3 * x:.2f}" for x in r["wheel_noise"])
            + f" | {', '.join(r.get('named', [])) or ('-' if 'named' in r else 'not run')} |"
        )
    write_report(out / "bag_clock.md", "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
