"""What the force balance (``rover_env.calibration.balance``) reads on clean builds and on
slopes, rolling resistances and soils of the independent generator, its logs carrying the
drivers' reported torque (``effort_*``).

Why (stop 120): a slope is named from the windows only beyond the 2.4° clean builds lean
there (the clean-fit allowance); the balance's own clean tilt (``CLEAN_TILT``) is what a
slope must clear to be named from the torque. This prints one line a case (the tilt, its
interval, its heading; the resistance as a coefficient of the weight) and, over the clean
builds, the tilts' quantiles: the measurement behind ``CLEAN_TILT``. Magnitudes are drawn
log-uniform from each case's seed: slopes 0.2-3° toward any heading, rolling resistances
0.003-0.05, soils k_phi 0.3-3 x the regolith's.

    python benchmarks/balance_reads.py --seed0 74661 --clean 20 --slopes 20 --rr 6 --soils 4 \\
        --work out/balance --workers 2

Seeds 74644 and up (to the registered blocks' next range) are this project's exploratory
seeds. Writes ``WORK/balance_reads.json``, ``.md`` and ``.png`` (read tilt against the
truth); a case whose logs exist is not generated again.
"""

from __future__ import annotations

import argparse
import json
import math
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from rover_env.calibration.balance import CLEAN_TILT, SCALE, read_balance
from rover_env.config import load_rover
from rover_env.independent import make_independent_logs
from rover_env.logs import read_log

RANGES = {"slope": (0.2, 3.0), "rolling_resistance": (0.003, 0.05), "loose_soil": (0.3, 3.0)}


def draw(kind: str, seed: int) -> dict[str, dict[str, float]]:
    """The case's effect, its magnitude log-uniform over :data:`RANGES` from its seed."""
    if kind == "clean":
        return {}
    rng = np.random.default_rng([47, 120, seed])
    lo, hi = RANGES[kind]
    v = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    if kind == "slope":
        return {"slope": {"deg": v, "heading_deg": float(rng.uniform(-180.0, 180.0))}}
    key = "c_rr" if kind == "rolling_resistance" else "k_phi"
    return {kind: {key: v}}


def case(work: Path, kind: str, seed: int) -> dict[str, Any]:
    """One case's logs (generated once) and the balance read on them."""
    effects = draw(kind, seed)
    d = work / f"{kind}_{seed}"
    if not (d / "drive_02.csv").exists():
        make_independent_logs(d, effects, drives=3, seed=seed, effort=True)
    logs = [read_log(p) for p in sorted(d.glob("drive_*.csv"))]
    r, runs = read_balance(logs, load_rover(), SCALE)
    row: dict[str, Any] = {"kind": kind, "seed": seed, "effects": effects, "runs": len(runs)}
    if r is not None:
        row.update(r.as_json())
    return row


def line(row: dict[str, Any]) -> str:
    truth = (
        next(iter(next(iter(row["effects"].values())).items()), ("", 0.0))
        if row["effects"]
        else ("", 0.0)
    )
    head = f"{row['kind']:18s} {row['seed']} {truth[0]:>7s} {truth[1]:7.4f}  runs {row['runs']:2d}"
    if "tilt" not in row:
        return head + "  not read"
    lo, hi = row["tilt_interval"]
    clo, chi = row["c_rr_interval"]
    return (
        head + f"  tilt {row['tilt']:5.2f} [{lo:5.2f}, {hi:5.2f}] toward {row['heading']:6.0f}"
        f"  c_rr {row['c_rr']:.4f} [{clo:.4f}, {chi:.4f}]  inflation {row['inflation']:.0f}"
    )


def summary(rows: list[dict[str, Any]]) -> list[str]:
    """The clean builds' tilt quantiles and the slopes' reads against the truth."""
    out = []
    clean = [r for r in rows if r["kind"] == "clean" and "tilt" in r]
    if clean:
        t = np.array([r["tilt"] for r in clean])
        lows = np.array([r["tilt_interval"][0] for r in clean])
        out.append(
            f"clean builds: {len(clean)} read; tilt median {np.median(t):.2f}°, 95 % quantile"
            f" {np.quantile(t, 0.95):.2f}°, largest {t.max():.2f}°; interval's low end above"
            f" {CLEAN_TILT:g}° (would be named) in {int(np.sum(lows > CLEAN_TILT))}"
        )
    slopes = [r for r in rows if r["kind"] == "slope" and "tilt" in r]
    if slopes:
        truth = [r["effects"]["slope"]["deg"] for r in slopes]
        cover = sum(
            r["tilt_interval"][0] - CLEAN_TILT <= t <= r["tilt_interval"][1]
            for r, t in zip(slopes, truth, strict=True)
        )
        named = [r for r in slopes if r["tilt_interval"][0] > CLEAN_TILT]
        out.append(
            f"slopes: {len(slopes)} read; named (low end above {CLEAN_TILT:g}°) {len(named)};"
            f" truth in [low - {CLEAN_TILT:g}, high] {cover}/{len(slopes)}; read over truth"
            f" median {np.median([r['tilt'] / t for r, t in zip(slopes, truth, strict=True)]):.2f}"
        )
    return out


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    for r in rows:
        if "tilt" not in r or r["kind"] not in ("clean", "slope"):
            continue
        t = r["effects"]["slope"]["deg"] if r["kind"] == "slope" else 0.0
        lo, hi = r["tilt_interval"]
        c = "tab:blue" if r["kind"] == "slope" else "tab:gray"
        ax.errorbar(t, r["tilt"], yerr=[[r["tilt"] - lo], [hi - r["tilt"]]], fmt="o", color=c, ms=4)
    ax.plot([0, 3.2], [0, 3.2], "k:", lw=1)
    ax.axhline(CLEAN_TILT, color="tab:red", lw=1, label=f"CLEAN_TILT {CLEAN_TILT:g}°")
    ax.set_xlabel("true tilt (°; clean builds at 0)")
    ax.set_ylabel("balance's tilt and 95 % interval (°)")
    ax.set_ylim(0, 4)
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed0", type=int, required=True)
    for kind in ("clean", "slopes", "rr", "soils"):
        ap.add_argument(f"--{kind}", type=int, default=0, help=f"cases of {kind}")
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    kinds = (
        ["clean"] * a.clean
        + ["slope"] * a.slopes
        + ["rolling_resistance"] * a.rr
        + ["loose_soil"] * a.soils
    )
    jobs = [(a.work, k, a.seed0 + i) for i, k in enumerate(kinds)]
    a.work.mkdir(parents=True, exist_ok=True)
    rows = []
    with ProcessPoolExecutor(a.workers) as ex:
        for row in ex.map(case, *zip(*jobs, strict=True)):
            rows.append(row)
            print(line(row), flush=True)
    text = [line(r) for r in rows] + [""] + summary(rows)
    print("\n".join(summary(rows)))
    (a.work / "balance_reads.json").write_text(json.dumps(rows, indent=1))
    (a.work / "balance_reads.md").write_text("```\n" + "\n".join(text) + "\n```\n")
    plot(rows, a.work / "balance_reads.png")


if __name__ == "__main__":
    main()
