"""Physics throughput: the rover with the tire layer against MuJoCo stepping the same model alone.

Run: python benchmarks/bench_physics.py [--seconds 5]
Prints substeps per second and real-time factors, and their ratio, all measured in this run.
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from rover_env.sim.simulator import RoverSim


def _rate(fn, n: int, repeats: int = 3) -> float:
    best = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(n)
        best = max(best, n / (time.perf_counter() - t0))
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seconds", type=float, default=2.0, help="simulated seconds per repeat")
    ap.add_argument("--terrain", default="flat")
    args = ap.parse_args()

    sim = RoverSim(terrain=args.terrain)
    sim.set_speed_targets([2.0, 3.0, 2.0, 3.0])
    n = round(args.seconds / sim.dt)

    # Reference: the same compiled model and state stepped by MuJoCo alone (no tire layer).
    # Gravity is off so the rover, which only touches the ground through the tire layer,
    # neither falls nor lands on its chassis (no contacts either way): pure engine cost.
    model = sim.model
    data = mujoco.MjData(model)
    data.qpos[:] = sim.data.qpos
    data.ctrl[:] = sim.data.ctrl
    model.opt.gravity[:] = 0.0

    def raw(k: int) -> None:
        mujoco.mj_step(model, data, k)

    raw_rate = _rate(raw, n)
    model.opt.gravity[:] = [0.0, 0.0, -9.81]
    tire_rate = _rate(sim.step, n)
    dt = sim.dt
    print(f"timestep {dt * 1e3:g} ms, terrain {args.terrain}, {n} substeps per repeat, best of 3")
    print(f"MuJoCo alone      : {raw_rate:10.0f} substeps/s  real-time x{raw_rate * dt:7.1f}")
    print(f"with tire layer   : {tire_rate:10.0f} substeps/s  real-time x{tire_rate * dt:7.1f}")
    print(f"ratio tire/alone  : {tire_rate / raw_rate:10.3f}")
    assert np.isfinite(tire_rate)


if __name__ == "__main__":
    main()
