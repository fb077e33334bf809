"""Dead reckoning from the free wheels against the pose: a rolling radius read off the logs
alone (issue 47; SPEC §4's 50 s drive ended about 1 % off along the direction of travel).

On flat ground the two free wheels (3L, 3R) roll without drive, so on straight, moving
seconds the pose's path length over their travel at the nominal rolling radius r_e is
1 + f, f the rolling radius's change, plus whatever makes a free wheel slide (a rolling
resistance drags it, loose soil makes it bulldoze). Diagnose's 3 s windows see a rolling
radius only through the 1 Hz pose of each window (about 4 cm in 3 s at a 5 % change), under
the heading errors of every turn: on the independent generator's spent blocks it named
none of 10 radius singles at 2 x threshold or more. This script measures the statistic
per case of ``bench_independent.py`` blocks, per effect, against the generator's own radius
change, with a figure. It reads logs only (no replay, no model); diagnose's odometry stage
(:mod:`rover_env.calibration.diagnosis.odometry`) names a radius from the same statistic
against its model's twins.

    python benchmarks/odometry_scale.py /tmp/b50800 /tmp/b50900 --out docs/calibration/odometry

A block directory is ``bench_independent.py``'s ``--out`` with its ``--work`` under
``work/`` (regenerable: ``bench_independent.py --seed0 SEED``).
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path

import numpy as np
import yaml
from _report import write_report

from rover_env.config import load_rover
from rover_env.estimation.dead_reckoning import MOVING, STRAIGHT, travel_scale
from rover_env.estimation.estimator import static_rolling_radius
from rover_env.logs import DriveLog, read_log

R_E = static_rolling_radius(load_rover())
"""The model rover's nominal rolling radius at static load, d - k_re delta (0.0761 m)."""


def scale(logs: list[DriveLog]) -> float:
    """Path over free-wheel travel at :data:`R_E`, minus 1, over all drives."""
    return travel_scale(logs, R_E)


def cases(blocks: list[Path]) -> list[dict]:
    """Each case of ``blocks``: kind, effects, the generator's radius change, the statistic."""
    out = []
    for b in blocks:
        for case in sorted(p for p in (b / "work").iterdir() if (p / "logs").is_dir()):
            truth = yaml.safe_load((case / "logs" / "truth.yaml").read_text()) or {}
            effects = truth.get("effects") or {}
            drives = sorted((case / "logs").glob("drive_*.csv"))
            out.append(
                {
                    "case": case.name,
                    "kind": case.name.split("_", 1)[0],
                    "effects": sorted(effects),
                    "radius": float((effects.get("rolling_radius") or {}).get("fraction", 0.0)),
                    "scale": scale([read_log(p) for p in drives]),
                }
            )
    return out


def table(rows: list[dict]) -> list[str]:
    """Per single's effect and for clean cases: n, median, 5 % and 95 % quantiles."""
    groups: dict[str, list[float]] = defaultdict(list)
    for r in rows:
        if r["kind"] == "clean":
            groups["clean (nuisance only)"].append(r["scale"])
        elif r["kind"] == "single":
            groups[r["effects"][0]].append(r["scale"])
    lines = ["| case | n | median | q05 | q95 |", "|---|---|---|---|---|"]
    for name, v in sorted(groups.items()):
        q = np.quantile(v, [0.5, 0.05, 0.95])
        lines.append(f"| {name} | {len(v)} | {q[0]:+.4f} | {q[1]:+.4f} | {q[2]:+.4f} |")
    return lines


def radius_fit(rows: list[dict]) -> tuple[float, float, float, int]:
    """Radius singles: (slope, intercept, residual SD) of the statistic on the truth, n."""
    pts = np.array(
        [
            (r["radius"], r["scale"])
            for r in rows
            if r["kind"] == "single" and r["effects"] == ["rolling_radius"]
        ]
    )
    if len(pts) < 3:
        return np.nan, np.nan, np.nan, len(pts)
    k, c = np.polyfit(pts[:, 0], pts[:, 1], 1)
    return float(k), float(c), float(np.std(pts[:, 1] - (k * pts[:, 0] + c), ddof=2)), len(pts)


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.2))
    marks = {"rolling_radius": ("o", "C0"), "rolling_resistance": ("s", "C3"), "clean": ("x", "k")}
    for label, (m, col) in marks.items():
        if label == "clean":
            sel = [r for r in rows if r["kind"] == "clean"]
        else:
            sel = [r for r in rows if r["kind"] == "single" and r["effects"] == [label]]
        ax.plot([r["radius"] for r in sel], [r["scale"] for r in sel], m, color=col, label=label)
    lim = np.array([-0.2, 0.1])
    ax.plot(lim, lim, "k:", lw=0.8, label="statistic = truth")
    ax.set_xlabel("generator's rolling radius change f")
    ax.set_ylabel("pose path / free-wheel travel - 1")
    ax.set_title("Dead reckoning against the pose (straight, moving seconds)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("blocks", nargs="+", type=Path, help="bench_independent.py block dirs")
    ap.add_argument("--out", type=Path, required=True, help="folder for odometry.md and .png")
    a = ap.parse_args()
    rows = cases(a.blocks)
    k, c, sd, n = radius_fit(rows)
    text = [
        "# Dead reckoning against the pose (benchmarks/odometry_scale.py)",
        "",
        f"Cases of {', '.join(b.name for b in a.blocks)} (logs only). The statistic: the pose's"
        f" path along its heading over the free wheels' travel at r_e = {R_E} m, minus 1, on straight"
        f" (heading change < {STRAIGHT} rad), moving (travel > {MOVING} m) pose intervals.",
        "",
        *table(rows),
        "",
        f"Rolling radius singles (n {n}): statistic = {k:.3f} x truth {c:+.4f}, residual SD {sd:.4f}.",
        "",
        "![odometry](odometry.png)",
        "",
    ]
    a.out.mkdir(parents=True, exist_ok=True)
    write_report(a.out / "odometry.md", "\n".join(text))
    plot(rows, a.out / "odometry.png")
    print("\n".join(text))


if __name__ == "__main__":
    main()
