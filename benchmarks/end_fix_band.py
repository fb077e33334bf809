"""Dead reckoning against each drive's last pose fix only (the paper's case, SPEC §6): what
clean drives of the independent generator leave, and what a rolling radius moves.

Why (stop 100): diagnose's odometry stage names a rolling radius from the free wheels'
travel against the pose over straight intervals between fixes (1 Hz); a log with the pose at
each drive's end only has no such interval, and nothing read the pose at all (stop 99's log
variants). :func:`rover_env.estimation.dead_reckoning.end_fix_parts` reads each drive
commanded straight from its start (a fix by definition) to its last fix, against the free
wheels' net travel. Judged against the model's twins of the same drives: this script
measures the difference (the logs' minus the nominal model's twins') per case, on clean
builds (the band a rolling radius must leave) and on singles of every catalogue effect
(what else moves it), beside the 1 Hz statistic on the same drives.

    python benchmarks/end_fix_band.py --seeds 70892-70951 --out out/end_fix_band

Cases: every ``--clean-every``-th seed is clean, the others singles of ``--effects`` in
turn, each magnitude drawn from its seed as ``bench_independent.py`` draws it. Writes
``OUT/end_fix_band.json``, ``.md`` and ``.png``; the shipped band's runs are in
``docs/calibration/end_fix_band/`` (seeds 70892-70951 with ``--clean-every 2``, 70952-70999
with ``--clean-every 1``).
"""

from __future__ import annotations

import argparse
import json
import time
from multiprocessing import Pool
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from _independent_plan import DRIVES, DURATION, catalogue_truth, generator_params
from _report import write_report

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnosis.odometry import WHEELS
from rover_env.calibration.replay import ReplaySettings, prepare
from rover_env.config import load_rover
from rover_env.estimation.dead_reckoning import (
    end_fix_parts,
    fixes,
    path_and_travel_of,
    scale_of,
)
from rover_env.estimation.estimator import static_rolling_radius
from rover_env.independent.generate import make_independent_logs
from rover_env.logs import read_log

ALL = (
    "rolling_radius",
    "slope",
    "rolling_resistance",
    "loose_soil",
    "command_delay",
    "command_lag",
    "torque_limit",
    "friction",
)


def statistics(pose: np.ndarray, phi: np.ndarray, cmd: np.ndarray, r_e: float) -> dict[str, Any]:
    """Per wheel group: the end-fix parts and the 1 Hz interval parts of one drive."""
    end = {k: end_fix_parts(pose, phi, cmd, r_e, w) for k, w in WHEELS.items()}
    hz = {k: path_and_travel_of(pose, phi, r_e, w) for k, w in WHEELS.items()}
    return {"end": end, "hz": hz}


def run_case(case: dict[str, Any]) -> dict[str, Any]:
    """Generate ``case``'s drives, read both statistics on the logs and on the nominal
    model's twins."""
    t0 = time.perf_counter()
    cfg = load_rover()
    r_e = static_rolling_radius(cfg)
    work = Path(case["work"])
    paths = sorted(work.glob("drive_*.csv")) or make_independent_logs(
        work, case["effects"], drives=DRIVES, seed=case["seed"], duration=DURATION
    )
    logs, twins = [], []
    for p in paths:
        g = read_log(p)
        pose = fixes(g.t, g.pose)
        logs.append(statistics(pose, g.phi, g.cmd, r_e) | {"chord_end": _chord(g.pose)})
        phi, _, tpose = rs.twin_states(prepare(g, cfg, p.stem, ReplaySettings()), cfg)
        tpose = np.where(np.isfinite(pose), tpose, np.nan)
        twins.append(statistics(tpose, phi, g.cmd, r_e))
    row: dict[str, Any] = {k: case[k] for k in ("seed", "kind", "effect", "effects", "truth")}
    for form in ("end", "hz"):
        for k in WHEELS:
            a = scale_of([d[form][k] for d in logs])
            b = scale_of([d[form][k] for d in twins])
            row[f"{form}_{k}"] = [a, b, a - b]
    row["drives_read"] = sum(d["end"]["both"][1] > 0 for d in logs)
    row["chords"] = [d["chord_end"] for d in logs]
    row["seconds"] = time.perf_counter() - t0
    return row


def _chord(pose: np.ndarray) -> float:
    k = np.flatnonzero(np.all(np.isfinite(pose), axis=1))
    return float(np.hypot(*pose[k[-1], :2])) if k.size else 0.0


def plan(seeds: list[int], every: int, effects: tuple[str, ...], work: Path) -> list[dict]:
    """Every ``every``-th seed clean, the rest singles of ``effects`` in turn."""
    out, i = [], 0
    for n, seed in enumerate(seeds):
        if n % every == 0:
            eff: dict[str, dict[str, float]] = {}
            name = "clean"
        else:
            name = effects[i % len(effects)]
            i += 1
            eff = {name: generator_params(name, seed)}
        truth = {k: catalogue_truth(k, v) for k, v in eff.items()}
        kind = "clean" if not eff else "single"
        out.append(
            {
                "seed": seed,
                "kind": kind,
                "effect": name,
                "effects": eff,
                "truth": truth,
                "work": str(work / f"{seed}_{name}"),
            }
        )
    return out


def table(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| seed | effect | truth | drives read | end: logs - twins (both) | 3L - 3R | driven"
        " | 1 Hz: logs - twins |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in sorted(rows, key=lambda r: (r["effect"], r["seed"])):
        truth = "; ".join(f"{k} {v:.4g}" for t in r["truth"].values() for k, v in t.items())
        split = r["end_3L"][2] - r["end_3R"][2]
        lines.append(
            f"| {r['seed']} | {r['effect']} | {truth or '-'} | {r['drives_read']}"
            f" | {r['end_both'][2]:+.2%} | {split:+.2%} | {r['end_driven'][2]:+.2%}"
            f" | {r['hz_both'][2]:+.2%} |"
        )
    return "\n".join(lines) + "\n"


def summary(rows: list[dict[str, Any]]) -> str:
    clean = [r for r in rows if r["effect"] != "rolling_radius"]
    out = []
    for form in ("end", "hz"):
        x = np.array([r[f"{form}_both"][2] for r in clean], dtype=float)
        x = x[np.isfinite(x)]
        if x.size:
            q = np.percentile(x, [0, 2.5, 50, 97.5, 100])
            out.append(
                f"- {form}: {x.size} cases without a radius: min {q[0]:+.2%}, 2.5 % {q[1]:+.2%},"
                f" median {q[2]:+.2%}, 97.5 % {q[3]:+.2%}, max {q[4]:+.2%}"
            )
    return "\n".join(out) + "\n"


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for i, form in enumerate(("end", "hz")):
        for r in rows:
            y = r[f"{form}_both"][2]
            x = r["truth"].get("rolling_radius", {}).get("fraction", 0.0)
            c = "C3" if r["effect"] == "rolling_radius" else "C0" if r["kind"] == "clean" else "C7"
            ax[i].plot(x, y, "o", color=c, ms=4)
        ax[i].axline((0, 0), slope=1, color="k", lw=0.5)
        ax[i].set_title(f"{form}: logs - nominal twins")
        ax[i].set_xlabel("rolling radius change (catalogue)")
    ax[0].set_ylabel("path over free-wheel travel, logs - twins")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", required=True, help="FIRST-LAST")
    ap.add_argument("--clean-every", type=int, default=2)
    ap.add_argument("--effects", nargs="+", default=list(ALL), choices=list(ALL))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--work", type=Path, default=Path("out/end_fix_band/work"))
    ap.add_argument("--out", type=Path, default=Path("out/end_fix_band"))
    a = ap.parse_args(argv)
    lo, _, hi = a.seeds.partition("-")
    seeds = list(range(int(lo), int(hi or lo) + 1))
    todo = plan(seeds, a.clean_every, tuple(a.effects), a.work)
    rows = []
    with Pool(a.workers) as pool:
        for r in pool.imap_unordered(run_case, todo):
            rows.append(r)
            print(
                f"[{len(rows)}/{len(todo)}] {r['seed']} {r['effect']}:"
                f" end {r['end_both'][2]:+.2%}, 1 Hz {r['hz_both'][2]:+.2%}"
                f" ({r['seconds']:.0f} s)",
                flush=True,
            )
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "end_fix_band.json").write_text(json.dumps(rows, indent=1))
    head = (
        "# Dead reckoning against the last pose fix: logs against the nominal model's twins\n\n"
        f"Independent generator, seeds {a.seeds}, {DRIVES} drives of {DURATION:g} s each"
        " (`benchmarks/end_fix_band.py`).\n\n"
    )
    write_report(
        a.out / "end_fix_band.md",
        head + summary(rows) + "\n" + table(rows) + "\n![cases](end_fix_band.png)\n",
    )
    plot(rows, a.out / "end_fix_band.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
