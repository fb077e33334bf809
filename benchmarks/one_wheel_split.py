"""The free wheels' dead-reckoning split on fresh logs of the independent generator (issue 47):
what diagnose's one-wheel rule (:mod:`rover_env.calibration.diagnosis.one_wheel`) would read.

A named rolling resistance is withdrawn where the two free wheels' travel against the pose,
each against the model's twins, differs by more than the odometry band's ``split`` (5 %): the
ground drags both wheels alike, a dragging brake one. The rule acts only where a rolling
resistance is named, which is rare on fresh cases; its harm is the share of cases whose
wheels part that far without a dragging brake. This script reads that share on cases of
``bench_independent.py``'s plans (the same seeds, effects and builds), without the naming:
for each case the logs, the diagnosis's split, form and floor stages (the model forms the
twins are made with), then the split against the twins of the model with nothing named (a
rolling resistance acts on both wheels alike: tests/test_one_wheel.py). Rows go to ``--out``
as JSON lines, one per case, resumable; ``--report`` writes the summary and a figure.

    python benchmarks/one_wheel_split.py --seed0 67200 --plans 8 --out /tmp/split.jsonl
    python benchmarks/one_wheel_split.py --report /tmp/split.jsonl --blocks /tmp/b67200 \\
        --md docs/calibration/study67200/split.md

``--only`` keeps the cases whose tag contains one of its comma-separated texts (default:
the rolling-resistance singles and the clean cases), taken round-robin over the plans.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from _independent_plan import DRIVES, DURATION, cases, tag

from rover_env.calibration.diagnosis import floor, form, split
from rover_env.calibration.diagnosis.one_wheel import free_wheel_difference
from rover_env.calibration.diagnosis.state import ODOMETRY_BAND, Diagnosis, Options
from rover_env.independent import make_independent_logs


def planned(seed0: int, plans: int, only: list[str]) -> list[dict[str, Any]]:
    """The cases of plans ``seed0``, ``seed0 + 100``, ... whose tag holds one of ``only``,
    round-robin: each plan's first of each kind, then the second, ..."""
    per: list[list[dict[str, Any]]] = []
    for k in range(plans):
        for text in only:
            per.append([c for c in cases(False, seed0 + 100 * k) if text in tag(c)])
    out: list[dict[str, Any]] = []
    for i in range(max((len(g) for g in per), default=0)):
        out += [g[i] for g in per if i < len(g)]
    return out


def split_of(case: dict[str, Any], work: Path) -> dict[str, Any]:
    """One case's row: the free wheels' difference from the twins, each and apart."""
    t0 = time.perf_counter()
    paths = make_independent_logs(
        work / "logs", case["effects"], drives=DRIVES, seed=case["seed"], duration=DURATION
    )
    d = Diagnosis([str(p) for p in paths], work / "out", Options(progress=False))
    split.split(d)
    form.fit_model_form(d)
    floor.baseline(d)
    d.odometry, d.chosen = None, []
    diff = free_wheel_difference(d)
    return {
        "case": tag(case),
        "seed": case["seed"],
        "effects": case["effects"],
        **{k: float(v) for k, v in diff.items()},
        "split": float(diff["3L"] - diff["3R"]),
        "seconds": time.perf_counter() - t0,
    }


def run(args: argparse.Namespace) -> None:
    out = Path(args.out)
    done = set()
    if out.is_file():
        done = {json.loads(line)["case"] for line in out.read_text().splitlines() if line}
    todo = [c for c in planned(args.seed0, args.plans, args.only.split(",")) if tag(c) not in done]
    todo = todo[: args.limit]
    print(f"{len(todo)} cases to run ({len(done)} done before)", flush=True)
    for k, c in enumerate(todo, 1):
        with tempfile.TemporaryDirectory() as tmp:
            row = split_of(c, Path(tmp))
        with out.open("a") as f:
            f.write(json.dumps(row) + "\n")
        apart = abs(row["split"]) > ODOMETRY_BAND.split
        print(
            f"[{k}/{len(todo)}] {row['case']}: 3L {row['3L']:+.4f} 3R {row['3R']:+.4f} split"
            f" {row['split']:+.4f}{' BEYOND' if apart else ''} ({row['seconds']:.0f} s)",
            flush=True,
        )


def brake_rows(blocks: list[Path]) -> list[dict[str, Any]]:
    """Brake-drag cases of ``bench_independent.py`` block directories: their torque and what
    the one-wheel rule read (``one_wheel`` in result.json, or the odometry's difference)."""
    rows = []
    for b in blocks:
        for res in sorted(b.glob("work/outside_brake_drag_*/out/result.json")):
            r = json.loads(res.read_text())
            rec = r.get("one_wheel") or {}
            diff = (r.get("dead_reckoning") or {}).get("difference")
            sp = rec.get("split", (diff["3L"] - diff["3R"]) if diff else float("nan"))
            truth = yaml.safe_load((res.parent.parent / "logs" / "truth.yaml").read_text())
            torque = float(truth["effects"]["brake_drag"]["torque"])
            rows.append(
                {
                    "case": res.parent.parent.name,
                    "split": sp,
                    "torque": torque,
                    "asked": bool(rec),  # a rolling resistance named before the rule
                    "named": r["named"],
                }
            )
    return rows


def report(path: Path, blocks: list[Path], md: Path) -> None:
    """Counts beyond the limit per kind, quantiles, and a histogram beside the brake drags."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [json.loads(line) for line in path.read_text().splitlines() if line]
    lim = ODOMETRY_BAND.split
    kinds = sorted({r["case"].rsplit("_", 1)[0] for r in rows})
    lines = [
        "# The free wheels' dead-reckoning split (`benchmarks/one_wheel_split.py`)",
        "",
        f"Limit |3L - 3R| > {lim:.0%} (the odometry band's split).",
        "",
        "| cases | n | beyond the limit | min | 5 % | median | 95 % | max |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for k in kinds:
        s = np.array([r["split"] for r in rows if r["case"].startswith(k)])
        q = np.percentile(s, [5, 50, 95])
        lines.append(
            f"| {k} | {s.size} | {int(np.sum(np.abs(s) > lim))} | {s.min():+.4f} |"
            f" {q[0]:+.4f} | {q[1]:+.4f} | {q[2]:+.4f} | {s.max():+.4f} |"
        )
    brakes = brake_rows(blocks)
    if brakes:
        b = np.array([r["split"] for r in brakes], dtype=float)
        lines += [
            "",
            f"Brake drags ({len(brakes)} cases, first diagnoses): beyond the limit"
            f" {int(np.sum(np.abs(b) > lim))}; a rolling resistance named before the rule in"
            f" {sum(r['asked'] for r in brakes)}, withdrawn by it in"
            f" {sum(r['asked'] and abs(r['split']) > lim for r in brakes)}.",
        ]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 3.8))
    bins = np.linspace(-0.18, 0.18, 73)
    for k in kinds:
        ax.hist([r["split"] for r in rows if r["case"].startswith(k)], bins, alpha=0.6, label=k)
    if brakes:
        ax.hist([r["split"] for r in brakes], bins, alpha=0.6, label="outside_brake_drag")
    for x in (-lim, lim):
        ax.axvline(x, color="k", lw=0.8, ls="--")
    ax.set_xlabel("free wheels' split 3L - 3R (logs minus twins)")
    ax.set_ylabel("cases")
    ax.legend(fontsize=8)
    if brakes:
        t = np.array([r["torque"] for r in brakes])
        a = np.abs(np.array([r["split"] for r in brakes], dtype=float))
        rr = np.array([r["asked"] for r in brakes])
        bx.scatter(t[~rr], a[~rr], s=18, label="no rolling resistance named")
        bx.scatter(t[rr], a[rr], s=22, marker="x", label="rolling resistance named before the rule")
        bx.axhline(lim, color="k", lw=0.8, ls="--")
        bx.set_xlabel("brake drag torque (N m)")
        bx.set_ylabel("|3L - 3R|")
        bx.legend(fontsize=8)
    fig.tight_layout()
    md.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(md.with_suffix(".png"), dpi=110)
    lines += ["", f"![split]({md.with_suffix('.png').name})", ""]
    md.write_text("\n".join(lines))
    print("\n".join(lines))


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--seed0", type=int, default=67200, help="first plan's seed")
    ap.add_argument("--plans", type=int, default=8, help="plans seed0, seed0 + 100, ...")
    ap.add_argument("--only", default="single_rolling_resistance,clean", help="tag texts")
    ap.add_argument("--limit", type=int, default=None, help="run at most N cases")
    ap.add_argument("--out", default="out/one_wheel_split.jsonl", help="rows, one per case")
    ap.add_argument("--report", type=Path, default=None, help="summarise these rows")
    ap.add_argument("--blocks", type=Path, nargs="*", default=[], help="brake-drag blocks")
    ap.add_argument("--md", type=Path, default=Path("out/one_wheel_split.md"))
    args = ap.parse_args()
    if args.report is not None:
        report(args.report, args.blocks, args.md)
    else:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        run(args)


if __name__ == "__main__":
    main()
