"""The loose-soil table of a benchmark run: success with its Wilson 95 % interval, sinkage,
energy per metre, time stuck and speed error per controller and scenario.

The benchmark's own tables give Student-t intervals, which are empty for a success share of
0 or 1; a share needs the Wilson score interval. Reads ``OUT/episodes.csv`` of
``rover-env benchmark --out OUT`` and writes ``OUT/soil.md``.

    python benchmarks/soil_table.py docs/benchmark-soil
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

from rover_env.benchmark.report import t_interval


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score 95 % interval of a share k / n."""
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def _ci(x: list[float], scale: float = 1.0, digits: int = 1) -> str:
    m, _lo, hi = t_interval(x)
    return f"{m * scale:.{digits}f} ± {(hi - m) * scale:.{digits}f}"


def main(out: Path) -> None:
    with (out / "episodes.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    ctrls = list(dict.fromkeys(r["controller"] for r in rows))
    scens = list(dict.fromkeys(r["scenario"] for r in rows))
    seeds = sorted({int(r["seed"]) for r in rows})
    lines = [
        f"# Loose-soil benchmark: {out}",
        "",
        f"Seeds {seeds[0]}..{seeds[-1]} ({len(seeds)} per scenario). Success: episodes that "
        "reached the goal, with the Wilson 95 % interval. Other columns: mean ± half-width of "
        "the 95 % Student-t interval over episodes; max sinkage is the deepest wheel of each "
        "episode, averaged, with the deepest of all in brackets. Written by "
        "`python benchmarks/soil_table.py`.",
        "",
    ]
    for sc in scens:
        lines += [
            f"## {sc}",
            "",
            "| controller | success | 95 % interval | mean sinkage (mm) | max sinkage (mm) "
            "| energy (J/m) | time stuck (s) | RMS speed error (m/s) |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for c in ctrls:
            sel = [r for r in rows if r["controller"] == c and r["scenario"] == sc]
            if not sel:
                continue

            def col(key: str, sel: list[dict[str, str]] = sel) -> list[float]:
                return [float(r[key]) for r in sel]

            k, n = int(sum(col("success"))), len(sel)
            lo, hi = wilson(k, n)
            lines.append(
                f"| {c} | {k}/{n} | {lo:.2f}–{hi:.2f} | {_ci(col('mean_sinkage'), 1e3)} "
                f"| {_ci(col('max_sinkage'), 1e3)} ({max(col('max_sinkage')) * 1e3:.1f}) "
                f"| {_ci(col('energy_per_metre'))} | {_ci(col('time_stuck'))} "
                f"| {_ci(col('rms_speed_error'), 1.0, 3)} |"
            )
        lines.append("")
    (out / "soil.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
