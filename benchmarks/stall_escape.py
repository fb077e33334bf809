"""Can a stalled rover get out? Back off, then drive again, on the seeds where a controller stalls.

    python benchmarks/stall_escape.py slip-pi:slip_pi_soil 1002,1024 --scenario soft-patch

A feasibility study for issue 18, not a controller: the stall is detected from the
simulator's truth (the rover's position moved less than 1 cm in the last 1.5 s, after the
first 3 s), and the manoeuvre is scripted. Each variant backs the rover off at
``back_speed`` (rad/s, all four wheels) for ``back_time`` s, then drives straight at
``gain`` times the command's feed-forward, reached over ``ramp`` s; a new stall starts it
again. "retry in place" (back_time 0) stops the wheels at once and pushes again over 3 s;
the slip PI's own retry eases off over ~4 s, waits 5 s and pushes at 2 rad/s.
Tuning and validation seeds only (a test seed is refused: this is looking).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass

import numpy as np

from rover_env.benchmark.run import wrapper_for
from rover_env.estimation.estimator import static_rolling_radius
from rover_env.policies.controllers import EnvController
from rover_env.policies.specs import make_controller
from rover_env.seeds import split_of
from rover_env.tasks.scenarios import load_scenario

STILL_M = 0.01
"""A stall: the rover moved less than this (m) ..."""
STILL_S = 1.5
"""... over this long (s), after ``SETTLE_S``."""
SETTLE_S = 3.0


@dataclass(frozen=True)
class Variant:
    """One escape manoeuvre (module docstring)."""

    name: str
    back_speed: float
    back_time: float
    gain: float
    ramp: float


VARIANTS = (
    Variant("retry in place", 0.0, 0.0, 1.0, 3.0),
    Variant("back 0.25 m, retry at 1x", 2.0, 4.0, 1.0, 3.0),
    Variant("back 0.15 m, retry at 2.2x", 1.0, 3.0, 2.2, 1.0),
    Variant("back 0.5 m, retry at 0.6x", 1.0, 6.0, 0.6, 2.0),
)


def run(
    ctrl: EnvController, seed: int, scenario: str, v: Variant | None
) -> tuple[bool, float, int, float]:
    """(goal reached, distance made good m, escape attempts, energy J) of one episode. The
    goal is read as distance made good >= goal_fraction of the commanded path (the
    benchmark counts path progress; the same on a straight scenario)."""
    sc = load_scenario(scenario)
    sched = sc.schedule
    ep = sc.episode(seed)
    goal = sc.goal_fraction * sched.path_length(sc.duration)
    w = wrapper_for(scenario, ctrl.action_layout, ep)
    w.set_episode(ep)
    obs, info = w.reset()
    ctrl.reset(w.base)
    dt = w.base.control_dt
    vmax = w.base.sim.cfg.motor.max_wheel_speed
    r_e = static_rolling_radius(w.base.sim.cfg)
    lag = max(1, round(STILL_S / dt))
    hist: list[np.ndarray] = []
    mode, t_mode, tries, energy, k = "drive", 0.0, 0, 0.0, 0
    x0 = np.asarray(info["position"])[:2]
    while True:
        a = np.asarray(ctrl.action(w.base, obs), dtype=np.float32)
        t = k * dt
        hist.append(np.asarray(info["position"])[:2].copy())
        still = len(hist) > lag and np.linalg.norm(hist[-1] - hist[-1 - lag]) < STILL_M
        if v is not None:
            if mode == "drive" and still and t > SETTLE_S:
                mode, t_mode, tries = "back", t, tries + 1
            if mode == "back":
                if t - t_mode < v.back_time:
                    a = np.full(4, -v.back_speed / vmax, dtype=np.float32)
                else:
                    mode, t_mode = "again", t
            if mode == "again":
                g = min((t - t_mode) / v.ramp, 1.0) if v.ramp > 0 else 1.0
                base = v.gain * sched.at(t)[0] / r_e / vmax
                a = np.full(4, g * base, dtype=np.float32)
                if t - t_mode > v.ramp + STILL_S and still:
                    mode, t_mode, tries = "back", t, tries + 1
        obs, _, term, trunc, info = w.step(a)
        energy += float(info["energy"])
        k += 1
        if term or trunc:
            dist = float(np.linalg.norm(np.asarray(info["position"])[:2] - x0))
            return dist >= goal, dist, tries, energy


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("controller", help="controller spec, as in rover-env benchmark")
    ap.add_argument("seeds", help="comma-separated episode seeds (tuning or validation)")
    ap.add_argument("--scenario", default="soft-patch")
    args = ap.parse_args()
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    bad = [s for s in seeds if split_of(s) in ("test", "spent")]
    if bad:
        print(
            f"error: seeds {bad} are test or spent seeds; use tuning or validation seeds",
            file=sys.stderr,
        )
        return 2
    ctrl = make_controller(args.controller)  # one agent load for every episode
    print(f"{args.controller} on {args.scenario}: goal reached / distance (m) / tries / energy (J)")
    for v in (None, *VARIANTS):
        cells = []
        for s in seeds:
            ok, dist, tries, energy = run(ctrl, s, args.scenario, v)
            cells.append(f"{s}: {'goal' if ok else '-'} {dist:.2f} m {tries} {energy:.0f} J")
        name = "as is" if v is None else v.name
        print(f"{name:28s} " + "; ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
