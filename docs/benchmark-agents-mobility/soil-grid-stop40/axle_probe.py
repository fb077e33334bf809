"""Probe (stop 40, not a shipped controller): does splitting the over-speed between the front
and the middle axle change the soft-patch stalls? Open loop, the front wheels at F x and the
middle ones at M x the feed-forward, reached over a 2 s soft start. Tuning seeds only.

    PYTHONPATH=. python docs/benchmark-agents-mobility/soil-grid-stop40/axle_probe.py F M 1000 1040
"""

from __future__ import annotations

import sys

import numpy as np

from rover_env.benchmark.run import run_episode, wrapper_for
from rover_env.config import RoverConfig
from rover_env.control.base import ControllerInput
from rover_env.control.open_loop import OpenLoop
from rover_env.policies.controllers import ClassicalController
from rover_env.seeds import split_of
from rover_env.tasks.scenarios import load_scenario


class AxleOpenLoop(OpenLoop):
    """The open loop with one over-speed per axle (1L 1R at ``front``, 2L 2R at ``middle``)."""

    def __init__(self, cfg: RoverConfig, front: float, middle: float, ramp: float = 2.0):
        super().__init__(cfg)
        self.per_wheel = np.array([front, front, middle, middle])
        self.ramp = ramp

    def act(self, obs: ControllerInput) -> np.ndarray:
        ff = self.feedforward(obs.speed_command, obs.yaw_rate_command)
        k = min(max(obs.t, 0.0) / self.ramp, 1.0)
        g = 1.0 + (self.per_wheel - 1.0) * k
        return np.clip(ff * g, -self.max_wheel_speed, self.max_wheel_speed)


def main() -> None:
    front, middle = float(sys.argv[1]), float(sys.argv[2])
    seeds = range(int(sys.argv[3]), int(sys.argv[4]))
    ctrl = ClassicalController(
        f"axle {front}/{middle}", lambda cfg, dt: AxleOpenLoop(cfg, front, middle)
    )
    rows = []
    for s in seeds:
        if split_of(s) == "test":
            raise SystemExit(f"seed {s} is a test seed")
        ep = load_scenario("soft-patch").episode(s)
        rows.append(run_episode(wrapper_for("soft-patch", "wheels", ep), ctrl, ep))
    ok = np.array([r["success"] for r in rows], dtype=bool)
    e = np.array([r["energy_per_metre"] for r in rows])
    print(
        f"front x{front} middle x{middle}: goals {ok.sum()}/{len(rows)}, "
        f"{e.mean():.1f} J/m (reached {e[ok].mean():.1f}), "
        f"failed {[s for s, o in zip(seeds, ok, strict=True) if not o]}"
    )


if __name__ == "__main__":
    main()
