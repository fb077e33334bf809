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

``--source slip`` reads the slip balance instead (the driven wheels' slip against the free
wheels', for logs without the torque; its allowance ``CLEAN_SLIP_TILT``); ``--existing``
reads every case already in WORK (``KIND_SEED`` folders) instead of a new layout.

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

from rover_env.calibration.balance import (
    CLEAN_SLIP_TILT,
    CLEAN_TILT,
    SCALE,
    SLIP_SCALE,
    read_balance,
)
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


ALLOW = {"effort": CLEAN_TILT, "slip": CLEAN_SLIP_TILT}
TOLERANCE = {"effort": SCALE, "slip": SLIP_SCALE}


def case(work: Path, kind: str, seed: int, source: str = "effort") -> dict[str, Any]:
    """One case's logs (generated once) and the balance read on them."""
    effects = draw(kind, seed)
    d = work / f"{kind}_{seed}"
    if not (d / "drive_02.csv").exists():
        make_independent_logs(d, effects, drives=3, seed=seed, effort=True)
    logs = [read_log(p) for p in sorted(d.glob("drive_*.csv"))]
    r, runs = read_balance(logs, load_rover(), TOLERANCE[source], source)
    row: dict[str, Any] = {
        "kind": kind,
        "seed": seed,
        "effects": effects,
        "runs": len(runs),
        "source": source,
    }
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
    lo, hi = (math.inf if v is None else v for v in row["tilt_interval"])
    clo, chi = (math.nan if v is None else v for v in row["c_rr_interval"])
    infl = math.inf if row["inflation"] is None else row["inflation"]
    rest = (
        f"  same-both-ways slip {100 * row['offset_slip']:.2f} %"
        if row["source"] == "slip"
        else f"  c_rr {row['c_rr']:.4f} [{clo:.4f}, {chi:.4f}]"
    )
    return (
        head + f"  tilt {row['tilt']:5.2f} [{lo:5.2f}, {hi:5.2f}] toward {row['heading']:6.0f}"
        f"{rest}  inflation {infl:.0f}"
        + ("" if row["separated"] else " (unseparated)")
        + ("  NAMED" if named(row) else "")
    )


def named(row: dict[str, Any]) -> bool:
    """Whether the balance stage would name a slope from this reading (alone, nothing else
    named): its runs separate, and its interval, less the source's allowance, stays above
    level."""
    return bool(row.get("separated")) and row["tilt_interval"][0] - ALLOW[row["source"]] > 0.0


def summary(rows: list[dict[str, Any]]) -> list[str]:
    """The clean builds' reads (the measurement behind ``CLEAN_TILT``), the other loads', and
    the slopes' against the truth, counting what the balance stage would name."""
    out = []
    for kinds, what in ((("clean",), "clean builds"), (tuple(RANGES)[1:], "drags and soils")):
        part = [r for r in rows if r["kind"] in kinds and "tilt" in r]
        sep = [r for r in part if r["separated"]]
        if not part:
            continue
        lows = [r["tilt_interval"][0] for r in sep]
        out.append(
            f"{what}: {len(part)} read, {len(sep)} separated; of those the tilt up to"
            f" {max((r['tilt'] for r in sep), default=0.0):.2f}°, the interval's low end up to"
            f" {max(lows, default=0.0):.2f}°; a slope would be named on {sum(map(named, part))}"
        )
    slopes = [r for r in rows if r["kind"] == "slope" and "tilt" in r]
    allow = ALLOW[rows[0]["source"]] if rows else CLEAN_TILT
    if slopes:
        truth = [r["effects"]["slope"]["deg"] for r in slopes]
        hit = [named(r) for r in slopes]
        cover = sum(
            r["tilt_interval"][0] - allow <= t <= r["tilt_interval"][1]
            for r, t, h in zip(slopes, truth, hit, strict=True)
            if h
        )
        big = [h for h, t in zip(hit, truth, strict=True) if t >= 2 * allow]
        ratio = [r["tilt"] / t for r, t, h in zip(slopes, truth, hit, strict=True) if h]
        out.append(
            f"slopes: {len(slopes)} read; named {sum(hit)} (of {2 * allow:g}° or more"
            f" {sum(big)}/{len(big)}, under it {sum(hit) - sum(big)}/{len(hit) - len(big)});"
            f" of the named, the truth in [low - {allow:g}, high] {cover}/{sum(hit)},"
            f" read over truth {min(ratio, default=0):.2f}-{max(ratio, default=0):.2f}"
        )
    return out


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    for r in rows:
        if "tilt" not in r or r["kind"] not in ("clean", "slope") or not r["separated"]:
            continue  # unseparated reads have no bounded interval to draw
        t = r["effects"]["slope"]["deg"] if r["kind"] == "slope" else 0.0
        lo, hi = r["tilt_interval"]
        c = "tab:blue" if r["kind"] == "slope" else "tab:gray"
        ax.errorbar(t, r["tilt"], yerr=[[r["tilt"] - lo], [hi - r["tilt"]]], fmt="o", color=c, ms=4)
    ax.plot([0, 3.2], [0, 3.2], "k:", lw=1)
    src = rows[0]["source"] if rows else "effort"
    name = "CLEAN_SLIP_TILT" if src == "slip" else "CLEAN_TILT"
    ax.axhline(ALLOW[src], color="tab:red", lw=1, label=f"{name} {ALLOW[src]:g}°")
    what = "slip balance" if src == "slip" else "force balance"
    ax.set_title(f"{what}: separated reads (unseparated ones ask for a drive)", fontsize=9)
    ax.set_xlabel("true tilt (°; clean builds at 0)")
    ax.set_ylabel("balance's tilt and 95 % interval (°)")
    ax.set_ylim(0, 4)
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed0", type=int, help="the first case's seed (not with --existing)")
    for kind in ("clean", "slopes", "rr", "soils"):
        ap.add_argument(f"--{kind}", type=int, default=0, help=f"cases of {kind}")
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--source", choices=("effort", "slip"), default="effort")
    ap.add_argument(
        "--existing", action="store_true", help="read the cases already in WORK, generate none"
    )
    a = ap.parse_args()
    if (a.seed0 is None) != a.existing:
        ap.error("give --seed0 for new cases, or --existing to read those in WORK (not both)")
    kinds = (
        ["clean"] * a.clean
        + ["slope"] * a.slopes
        + ["rolling_resistance"] * a.rr
        + ["loose_soil"] * a.soils
    )
    if a.existing:
        found = [p.name.rsplit("_", 1) for p in sorted(a.work.glob("*_*")) if p.is_dir()]
        jobs = [(a.work, k, int(s), a.source) for k, s in found if k == "clean" or k in RANGES]
    else:
        jobs = [(a.work, k, a.seed0 + i, a.source) for i, k in enumerate(kinds)]
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
