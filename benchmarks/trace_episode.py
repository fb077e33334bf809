"""Print one benchmark episode second by second: position, wheel speed targets, slip, sinkage.

python benchmarks/trace_episode.py ppo:agents/mobility-ppo-rr-ft-patch 1052 --scenario soft-patch

Used to see what a controller does where it stalls (docs/benchmark-agents-mobility, stop 27).
The seed is kept in its split like every entry point (a test seed is refused: tracing is
looking).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from rover_env.benchmark.run import wrapper_for
from rover_env.policies.specs import make_controller
from rover_env.seeds import split_of
from rover_env.tasks.scenarios import load_scenario


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("controller", help="controller spec, as in rover-env benchmark")
    ap.add_argument("seed", type=int, help="episode seed (tuning or validation split)")
    ap.add_argument("--scenario", default="soft-patch")
    ap.add_argument("--every", type=float, default=1.0, help="seconds between lines (1)")
    args = ap.parse_args()
    if split_of(args.seed) == "test":
        print(
            f"error: seed {args.seed} is a test seed; trace tuning or validation seeds",
            file=sys.stderr,
        )
        return 2
    ctrl = make_controller(args.controller)
    episode = load_scenario(args.scenario).episode(args.seed)
    w = wrapper_for(args.scenario, ctrl.action_layout, episode)
    w.set_episode(episode)
    obs, info = w.reset()
    ctrl.reset(w.base)
    x0 = np.asarray(info["position"])[:2]
    dt = w.base.control_dt
    every = max(1, round(args.every / dt))
    vmax = w.base.sim.cfg.motor.max_wheel_speed
    k, energy = 0, 0.0
    print(
        "t [s]  path [m]  targets 1L 1R 2L 2R [rad/s]   slip 1L 1R 2L 2R   sinkage [mm]  energy [J]"
    )
    while True:
        a = ctrl.action(w.base, obs)
        obs, _, term, trunc, info = w.step(a)
        k += 1
        energy += float(info["energy"])
        if k % every == 0 or term or trunc:
            path = float(np.linalg.norm(np.asarray(info["position"])[:2] - x0))
            tg = " ".join(f"{v:5.2f}" for v in np.asarray(a, dtype=float)[:4] * vmax)
            sl = " ".join(f"{v:5.2f}" for v in np.asarray(info["slip_true"], dtype=float))
            sink = 1000 * float(np.mean(info["wheel_sinkage"]))
            print(f"{k * dt:5.1f}  {path:8.2f}  {tg}   {sl}   {sink:6.1f}  {energy:8.1f}")
        if term or trunc:
            return 0


if __name__ == "__main__":
    sys.exit(main())
