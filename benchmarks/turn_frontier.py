"""The turns' trade-off: energy per metre and |S| against yaw-rate error, fixed controllers.

On a skid-steer turn, slip and energy come from turning: the faster the rover drives at a
commanded yaw rate, the wider its curve, and once the outer wheels reach the motor's limit
the rover also turns less than commanded. So every fixed setting buys energy and slip with
yaw-rate error. This script measures that frontier on tuning seeds for the open loop at a
range of over-speed gains and for the set-point slip PI at a range of ``max_correction``
(how far it may speed a wheel up), so that a learned policy's point can be read against it:
below the curve is a better allocation, on it is another gain.

    python benchmarks/turn_frontier.py --seeds 10 --workers 2 --out docs/benchmark-agents-mobility/frontier
    python benchmarks/turn_frontier.py --extra ppo:agents/NAME ...  # an agent's point
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

from rover_env.benchmark.run import Job, run_jobs
from rover_env.benchmark.seeds import seeds as split_seeds

SCENARIOS = ("flat-turns", "sand-turns")
GAINS = (1.0, 1.4, 1.8, 2.2, 2.6, 3.0, 3.5, 4.0)
CORRECTIONS = (0.5, 1.0, 1.6, 2.5)
METRICS = ("rms_yaw_rate_error", "energy_per_metre", "mean_abs_slip", "mean_sinkage", "success")


def _specs(gains: tuple[float, ...], corrections: tuple[float, ...]) -> dict[str, str]:
    specs = {f"open loop x {g:g}": f"open-loop@gain={g:g}" for g in gains}
    for c in corrections:
        specs[f"slip PI max_correction {c:g}"] = f"slip-pi:slip_pi_soil@max_correction={c:g}"
    return specs


def _plot(rows: list[dict[str, object]], scenarios: list[str], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(scenarios), figsize=(5 * len(scenarios), 7), squeeze=False)
    for j, sc in enumerate(scenarios):
        for i, (key, label) in enumerate(
            (("energy_per_metre", "energy per metre (J/m)"), ("mean_abs_slip", "mean |S|"))
        ):
            ax = axes[i, j]
            for family, marker in (("open loop", "o-"), ("slip PI", "s--")):
                pts = [r for r in rows if r["scenario"] == sc and str(r["name"]).startswith(family)]
                x = [float(r["rms_yaw_rate_error"]) for r in pts]  # type: ignore[arg-type]
                y = [float(r[key]) for r in pts]  # type: ignore[arg-type]
                ax.plot(x, y, marker, label=family)
                for r, xi, yi in zip(pts, x, y, strict=True):
                    ax.annotate(str(r["name"]).split()[-1], (xi, yi), fontsize=7)
            for r in rows:
                if r["scenario"] == sc and r["name"] == r["controller"]:  # an --extra spec
                    x0, y0 = float(r["rms_yaw_rate_error"]), float(r[key])  # type: ignore[arg-type]
                    ax.plot([x0], [y0], "k*", markersize=12)
                    ax.annotate(str(r["name"]).split("/")[-1], (x0, y0), fontsize=8)
            ax.set_xlabel("RMS yaw-rate error (rad/s)")
            ax.set_ylabel(label)
            ax.set_title(sc)
            ax.legend(fontsize=8)
    fig.suptitle("Fixed controllers: labels are the open loop's gain or the PI's max_correction")
    fig.tight_layout()
    fig.savefig(out / "frontier.png", dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10, help="first N tuning seeds")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--gains", default=",".join(f"{g:g}" for g in GAINS))
    ap.add_argument("--corrections", default=",".join(f"{c:g}" for c in CORRECTIONS))
    ap.add_argument(
        "--extra",
        default="",
        help="more controller specs to place on the plot, comma-separated (e.g. a learned agent)",
    )
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("docs/benchmark-agents-mobility/frontier"))
    args = ap.parse_args()
    seeds = split_seeds("tuning", args.seeds)
    scenarios = args.scenarios.split(",")
    specs = _specs(
        tuple(float(g) for g in args.gains.split(",")),
        tuple(float(c) for c in args.corrections.split(",")),
    )
    for spec in filter(None, args.extra.split(",")):
        specs[spec] = spec
    jobs = [Job(spec, sc, s) for spec in specs.values() for sc in scenarios for s in seeds]
    t0 = time.perf_counter()
    done = [0]

    def tick(_row: dict[str, object]) -> None:
        done[0] += 1
        if done[0] % 20 == 0 or done[0] == len(jobs):
            print(f"  {done[0]}/{len(jobs)} episodes, {time.perf_counter() - t0:.0f} s", flush=True)

    results = run_jobs(jobs, workers=args.workers, progress=tick)
    rows: list[dict[str, object]] = []
    for name, spec in specs.items():
        for sc in scenarios:
            mine = [r for r in results if r["controller"] == spec and r["scenario"] == sc]
            row: dict[str, object] = {"name": name, "controller": spec, "scenario": sc}
            for m in METRICS:
                row[m] = round(float(np.mean([r[m] for r in mine])), 5)
            rows.append(row)
    args.out.mkdir(parents=True, exist_ok=True)
    with (args.out / "frontier.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    _plot(rows, scenarios, args.out)
    print(
        f"{len(jobs)} episodes in {time.perf_counter() - t0:.0f} s; tuning seeds {seeds[0]}-{seeds[-1]}"
    )
    for r in rows:
        print(
            f"{r['scenario']:11s} {r['name']:30s} yaw err {r['rms_yaw_rate_error']:.4f}  "
            f"E/m {r['energy_per_metre']:7.2f}  |S| {r['mean_abs_slip']:.4f}  "
            f"sink {1000 * float(r['mean_sinkage']):.1f} mm  success {r['success']:.2f}"  # type: ignore[arg-type]
        )


if __name__ == "__main__":
    main()
