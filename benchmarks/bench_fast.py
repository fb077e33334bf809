"""Throughput of the tire-plugin backend against MuJoCo alone, measured in one run.

Run: python benchmarks/bench_fast.py [--seconds 5] [--terrain flat] [--threads 2]
Prints substeps per second of the rover model stepped by MuJoCo alone (no tire layer, as in
bench_physics.py), with the numpy tire layer, and with the plugin; then the batched
throughput of ``BatchRoverSim`` for several rover counts in rover-seconds per wall-second.
Every figure is also given as a ratio to the raw single-rover reference of this run.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import mujoco
import numpy as np

from rover_env.sim.batch import BatchRoverSim
from rover_env.sim.simulator import RoverSim

TARGETS = [2.0, 3.0, 2.0, 3.0]


def _rate(fn: Callable[[int], None], n: int, repeats: int = 5) -> float:
    """Best calls-per-second of ``fn(n)`` over ``repeats`` runs (the machine is shared)."""
    best = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(n)
        best = max(best, n / (time.perf_counter() - t0))
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per repeat")
    ap.add_argument("--terrain", default="flat")
    ap.add_argument("--threads", type=int, default=2, help="threads of the batched runs")
    ap.add_argument("--sizes", type=int, nargs="+", default=[1, 8, 32, 128])
    args = ap.parse_args()

    ref = RoverSim(terrain=args.terrain)
    ref.set_speed_targets(TARGETS)
    dt = ref.dt
    n = round(args.seconds / dt)

    # Reference: the compiled model without the plugin stepped by MuJoCo alone. Gravity is
    # off so the rover, which touches the ground only through the tire layer, neither
    # falls nor lands on its chassis: pure engine cost (as in bench_physics.py).
    model = ref.model
    data = mujoco.MjData(model)
    data.qpos[:] = ref.data.qpos
    data.ctrl[:] = ref.data.ctrl
    model.opt.gravity[:] = 0.0
    raw = _rate(lambda k: mujoco.mj_step(model, data, k), n)
    model.opt.gravity[:] = [0.0, 0.0, -9.81]

    numpy_rate = _rate(ref.step, max(n // 10, 100))
    fast = RoverSim(terrain=args.terrain, backend="plugin")
    fast.set_speed_targets(TARGETS)
    plugin_rate = _rate(fast.step, n)

    print(f"timestep {dt * 1e3:g} ms, terrain {args.terrain}, best of 5")
    print(f"{'':28s}{'substeps/s':>12s}{'x real-time':>13s}{'/ raw':>8s}")
    for name, rate in (
        ("MuJoCo alone (raw)", raw),
        ("numpy tire layer", numpy_rate),
        ("plugin tire layer", plugin_rate),
    ):
        print(f"{name:28s}{rate:12.0f}{rate * dt:13.1f}{rate / raw:8.3f}")

    print(f"\nBatchRoverSim, {args.threads} threads: rover-seconds per wall-second")
    print(f"{'rovers':>8s}{'rover-s/s':>12s}{'/ raw':>8s}{'/ plugin 1':>12s}")
    for size in args.sizes:
        b = BatchRoverSim(size, terrain=args.terrain, nthread=args.threads)
        b.set_speed_targets(np.tile(TARGETS, (size, 1)))
        # About the same number of rover-substeps per repeat for every size.
        nstep = max(n // size, 50)
        rate = _rate(b.step, nstep) * size  # rover-substeps per second
        print(f"{size:8d}{rate * dt:12.1f}{rate / raw:8.3f}{rate / plugin_rate:12.3f}")


if __name__ == "__main__":
    main()
