"""Print one benchmark episode second by second: position, wheel speed targets, slip, sinkage.

python benchmarks/trace_episode.py slip-pi:slip_pi_soil 1052 --scenario soft-patch   # or ppo:RUN_DIR --spread

Used to see what a controller does where it stalls (docs/benchmark-agents-mobility, stop 27).
``--spread`` adds a PPO or SAC policy's action mean and standard deviation (is it held at the
clip bound?); ``--scale-after T:S`` multiplies the controller's targets by S from T seconds
on and prints the energy spent from then (what easing off in a stall would save; stop 36).
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
    ap.add_argument("--spread", action="store_true", help="print the policy's mean and std")
    ap.add_argument("--scale-after", default=None, metavar="T:S",
                    help="targets x S from T seconds on (e.g. 7:0.5)")  # fmt: skip
    args = ap.parse_args()
    t_scale, scale = 0.0, 1.0
    if args.scale_after is not None:
        try:
            t_text, s_text = args.scale_after.split(":")
            t_scale, scale = float(t_text), float(s_text)
        except ValueError:
            print(f"error: --scale-after {args.scale_after!r}: expected T:S, e.g. 7:0.5",
                  file=sys.stderr)  # fmt: skip
            return 2
    if split_of(args.seed) in ("test", "spent"):
        print(
            f"error: seed {args.seed} is a test or spent seed; trace tuning or validation seeds",
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
    spread = getattr(ctrl, "spread", None) if args.spread else None
    if args.spread and spread is None:
        print(f"error: --spread needs a ppo: or sac: controller, not {args.controller}",
              file=sys.stderr)  # fmt: skip
        return 2
    k, energy, energy_after = 0, 0.0, 0.0
    print(
        "t [s]  path [m]  targets 1L 1R 2L 2R [rad/s]   slip 1L 1R 2L 2R   sinkage [mm]  energy [J]"
        + ("   policy mean (std)" if spread else "")
    )
    while True:
        stats = spread(obs) if spread else None
        a = np.asarray(ctrl.action(w.base, obs), dtype=np.float32)
        late = args.scale_after is not None and k * dt >= t_scale
        if late:
            a = a * np.float32(scale)
        obs, _, term, trunc, info = w.step(a)
        k += 1
        energy += float(info["energy"])
        energy_after += float(info["energy"]) if late else 0.0
        if k % every == 0 or term or trunc:
            path = float(np.linalg.norm(np.asarray(info["position"])[:2] - x0))
            tg = " ".join(f"{v:5.2f}" for v in np.asarray(a, dtype=float)[:4] * vmax)
            sl = " ".join(f"{v:5.2f}" for v in np.asarray(info["slip_true"], dtype=float))
            sink = 1000 * float(np.mean(info["wheel_sinkage"]))
            line = f"{k * dt:5.1f}  {path:8.2f}  {tg}   {sl}   {sink:6.1f}  {energy:8.1f}"
            if stats is not None:
                mean, std = stats
                line += (
                    "   " + " ".join(f"{v:+5.2f}" for v in mean) + f" ({float(np.mean(std)):.2f})"
                )
            print(line)
        if term or trunc:
            if args.scale_after is not None:
                span = max(k * dt - t_scale, dt)
                print(
                    f"from {t_scale:g} s on, targets x {scale:g}: {energy_after:.1f} J over"
                    f" {span:.1f} s ({energy_after / span:.2f} W)"
                )
            return 0


if __name__ == "__main__":
    sys.exit(main())
