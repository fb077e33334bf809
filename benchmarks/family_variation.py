"""Does every scenario family vary? The slip PI on tuning seeds of each family's training
distribution and of each shift: mean and coefficient of variation of its energy per metre,
and its success share (issue 46's acceptance: CV >= 10 % on every family).

    python benchmarks/family_variation.py [--seeds 20] [--workers 2] [--out docs/benchmark/families.md]

The slip PI is ``slip-pi`` on hard ground and the set-point PI ``slip-pi:slip_pi_soil`` on a
family with loose soil. Seeds are the tuning split's first N (``rover_env.seeds``): designing
a family's ranges on them touches neither validation nor test. The fixed worlds are played
too, for the CV a seed gave before families (start jitter and sensor noise only).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HARD, SOIL = "slip-pi", "slip-pi:slip_pi_soil"
CV_MIN = 0.10


def controller_for(scenario: str) -> str:
    from rover_env.tasks.scenarios import load_scenario

    t = load_scenario(scenario).terrain_config()
    return SOIL if (t.soil or any(p.soil for p in t.patches)) else HARD


def main(argv: list[str] | None = None) -> int:
    from rover_env.benchmark.run import Job, run_jobs
    from rover_env.seeds import seeds
    from rover_env.tasks.scenarios import load_scenario, scenario_names

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--seeds", type=int, default=20, help="tuning seeds per family (20)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--scenarios", default="all", help="comma list of scenario names, or all")
    p.add_argument("--out", default=None, help="markdown table to write (default: print only)")
    args = p.parse_args(argv)
    names = scenario_names() if args.scenarios == "all" else args.scenarios.split(",")
    keys = []
    for n in names:
        keys += [n, *(f"{n}@{v}" for v in load_scenario(n).variants)]
    seed_list = seeds("tuning", args.seeds)
    jobs = [Job(controller_for(k), k, s) for k in keys for s in seed_list]
    t0 = time.perf_counter()
    done = [0]

    def tick(row: dict[str, object]) -> None:
        done[0] += 1
        if done[0] % 20 == 0 or done[0] == len(jobs):
            print(f"{done[0]}/{len(jobs)} episodes, {time.perf_counter() - t0:.0f} s", flush=True)

    rows = run_jobs(jobs, workers=args.workers, progress=tick)
    lines = [
        "# Scenario families: does every family vary?",
        "",
        f"Produced by `python benchmarks/family_variation.py --seeds {args.seeds}`: the slip PI "
        f"(`{HARD}` on hard ground, `{SOIL}` on loose soil) on tuning seeds "
        f"{seed_list[0]}..{seed_list[-1]} of each scenario's fixed world (`NAME`), training "
        "distribution (`NAME@train`) and shifts (`NAME@SHIFT`), each scenario's own length. "
        "CV: standard deviation over mean of the energy per metre across seeds (ddof 1). "
        f"Acceptance (issue 46): CV >= {100 * CV_MIN:.0f} % on every family and shift.",
        "",
        "| scenario | controller | n | energy per metre mean [J/m] | CV | success | check |",
        "|---|---|---|---|---|---|---|",
    ]
    bad = []
    for k in keys:
        sel = [r for r in rows if r["scenario"] == k]
        e = np.array([float(r["energy_per_metre"]) for r in sel])
        ok = np.isfinite(e)
        mean = float(np.mean(e[ok])) if ok.any() else float("nan")
        cv = float(np.std(e[ok], ddof=1) / mean) if ok.sum() > 1 else float("nan")
        succ = float(np.mean([float(r["success"]) for r in sel]))
        family = "@" in k
        check = ("pass" if cv >= CV_MIN else "FAIL") if family else "(fixed world)"
        if family and not cv >= CV_MIN:
            bad.append(k)
        lines.append(
            f"| {k} | {sel[0]['controller']} | {len(sel)} | {mean:.3g} | {100 * cv:.1f} % | "
            f"{succ:.2f} | {check} |"
        )
    lines += [
        "",
        f"{len(keys)} distributions, {len(jobs)} episodes in {time.perf_counter() - t0:.0f} s "
        f"with {args.workers} workers.",
        "",
    ]
    text = "\n".join(lines)
    print(text)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text)
    if bad:
        print(f"CV below {100 * CV_MIN:.0f} %: {', '.join(bad)}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
