"""Grid over the slip PI's set-point and band on the soil scenarios, tuning seeds only.

Each candidate is the shipped slip PI (configs/control/slip_pi.yaml) with ``slip_setpoint``
and ``traction_allowance`` replaced; it runs through the benchmark's own episode code
(rover_env.benchmark.run) beside open-loop and the shipped slip PI. Objective: the mean
success rate over the scenarios, ties broken by the mean energy per metre relative to
open loop (lower is better). Writes one CSV row per candidate.

    python benchmarks/tune_slip_setpoint.py --seeds 8 --workers 2 \
        --out docs/benchmark-soil/tuning.csv
"""

from __future__ import annotations

import argparse
import csv
import itertools
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from rover_env.benchmark.run import Job, run_jobs
from rover_env.benchmark.seeds import seeds as split_seeds
from rover_env.config import configs_dir, load_yaml

SCENARIOS = ("sand-slope", "soft-patch", "sand-turns")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8, help="first N tuning seeds")
    ap.add_argument("--setpoints", default="-0.2,-0.4,-0.5,-0.6,-0.7,-0.8")
    ap.add_argument("--allowances", default="0.05,0.1")
    ap.add_argument(
        "--max-corrections",
        default="",
        help="also grid the PI's max_correction (comma list; empty: the shipped 0.5 only)",
    )
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("docs/benchmark-soil/tuning.csv"))
    args = ap.parse_args()
    seeds = split_seeds("tuning", args.seeds)
    scenarios = args.scenarios.split(",")
    base = load_yaml(configs_dir() / "control" / "slip_pi.yaml")
    tmp = Path(tempfile.mkdtemp(prefix="setpoint-"))
    specs = {"open-loop": "open-loop", "slip-pi": "slip-pi"}
    caps = [float(x) for x in args.max_corrections.split(",") if x.strip()] or [None]
    for s0, a, cap in itertools.product(
        [float(x) for x in args.setpoints.split(",")],
        [float(x) for x in args.allowances.split(",")],
        caps,
    ):
        cfg = {**base, "slip_setpoint": s0, "traction_allowance": a}
        label = f"setpoint {s0:+.2f} band {a:.2f}"
        if cap is not None:
            cfg["max_correction"] = cap
            label += f" max {cap:.2f}"
        p = tmp / f"sp{s0:+.2f}_a{a:.2f}_m{cap}.yaml"
        p.write_text(yaml.safe_dump(cfg))
        specs[label] = f"slip-pi:{p}"
    jobs = [Job(spec, sc, s) for spec in specs.values() for sc in scenarios for s in seeds]
    t0 = time.perf_counter()
    rows = run_jobs(jobs, workers=args.workers)
    by: dict[tuple[str, str], list[dict[str, float]]] = {}
    for r in rows:
        by.setdefault((r["controller"], r["scenario"]), []).append(r)

    def mean(spec: str, sc: str, key: str) -> float:
        return float(np.mean([r[key] for r in by[(spec, sc)]]))

    out = []
    for label, spec in specs.items():
        row: dict[str, object] = {"candidate": label}
        for sc in scenarios:
            for key in (
                "success",
                "mean_sinkage",
                "energy_per_metre",
                "time_stuck",
                "rms_speed_error",
            ):
                row[f"{sc}:{key}"] = round(mean(spec, sc, key), 4)
        row["success"] = round(float(np.mean([mean(spec, sc, "success") for sc in scenarios])), 4)
        row["energy_vs_open_loop"] = round(
            float(
                np.mean(
                    [
                        mean(spec, sc, "energy_per_metre")
                        / mean("open-loop", sc, "energy_per_metre")
                        for sc in scenarios
                    ]
                )
            ),
            4,
        )
        out.append(row)
    out.sort(key=lambda r: (-float(r["success"]), float(r["energy_vs_open_loop"])))  # type: ignore[arg-type]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(out[0]))
        w.writeheader()
        w.writerows(out)
    print(f"{len(jobs)} episodes in {time.perf_counter() - t0:.0f} s; seeds {seeds[0]}-{seeds[-1]}")
    for r in out:
        print(
            f"{r['candidate']:36s} success {r['success']:.3f}  "
            f"E/m vs open loop {r['energy_vs_open_loop']:.3f}  "
            + "  ".join(f"{sc} {r[f'{sc}:success']:.2f}" for sc in scenarios)
        )


if __name__ == "__main__":
    main()
