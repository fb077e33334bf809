"""What an executor costs (docs/cluster.md): start-up, per-task overhead, worker memory.

    python benchmarks/bench_executor.py --executor local
    python benchmarks/bench_executor.py --executor ray                       # local Ray instance
    python benchmarks/bench_executor.py --executor ray --ray-address HOST:PORT

Overhead: start the executor, run 2 no-op tasks, then 400. Memory: VmRSS of the worker before
and after benchmark episodes of 2 s (every scenario, the classical controllers, then the
shipped PPO agent, which loads torch), on 2 workers.
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

from rover_env.executor import add_executor_args, make_executor

SCENARIOS = ["flat-turns", "ice-patch", "split-mu", "slope", "bumps", "stuck-wheel"]


def _noop(x: int) -> int:
    return x


def _rss_mb() -> dict[str, int]:
    out = {}
    with open("/proc/self/status") as fh:
        for line in fh:
            key, val = line.split(":", 1)
            if key in ("VmRSS", "VmHWM"):
                out[key] = int(val.split()[0]) // 1024
    return out


def _episode_memory(spec: tuple[str, str, int, float]) -> dict[str, Any]:
    from rover_env.benchmark.run import Job, run_job

    before = _rss_mb()
    run_job(Job(*spec))
    return {"pid": os.getpid(), "controller": spec[0], "before": before, "after": _rss_mb()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-memory", action="store_true", help="overhead only")
    add_executor_args(ap)
    args = ap.parse_args()
    n = 400
    t0 = time.perf_counter()
    with make_executor(args.executor, args.workers, args.ray_address) as ex:
        t1 = time.perf_counter()
        ex.map(_noop, [0, 1])
        t2 = time.perf_counter()
        ex.map(_noop, list(range(n)))
        t3 = time.perf_counter()
        print(
            f"{ex.describe()}: start {t1 - t0:.2f} s, first 2 tasks {t2 - t1:.2f} s, {n} no-op"
            f" tasks {t3 - t2:.2f} s ({1000 * (t3 - t2) / n:.2f} ms/task);"
            f" load {os.getloadavg()[0]:.1f}"
        )
        if args.no_memory:
            return 0
        ctrls = ["open-loop", "slip-pi", "ppo:agents/axle-schedule"]
        tasks = [(c, s, 3000, 2.0) for c in ctrls for s in SCENARIOS]
        rows = ex.map(_episode_memory, tasks)
    first: dict[int, dict[str, Any]] = {}
    for r in rows:
        first.setdefault(r["pid"], r)
    classical = [r["after"]["VmRSS"] for r in rows if not r["controller"].startswith("ppo")]
    ppo = [r["after"]["VmRSS"] for r in rows if r["controller"].startswith("ppo")]
    starts = sorted(r["before"]["VmRSS"] for r in first.values())
    after1 = sorted(r["after"]["VmRSS"] for r in first.values())
    print(
        f"worker VmRSS: at start {starts} MB, after its first episode {after1} MB, at most"
        f" {max(classical)} MB with classical controllers, {min(ppo)}-{max(ppo)} MB after"
        " PPO-agent episodes"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
