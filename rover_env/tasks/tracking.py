"""Random tracking commands: the task of the plain env."""

from __future__ import annotations

import numpy as np

from rover_env.tasks.base import Command, Task
from rover_env.tasks.reward import RewardWeights

__all__ = ["RandomTracking"]


class RandomTracking(Task):
    """A new random command every ``interval`` seconds (uniform in the given range): speed
    uniform in [0.3, 1] x ``max_speed``, and a yaw rate uniform in +-``max_yaw_rate``, except
    that a third of the commands go straight (the rover must also hold a heading)."""

    name = "random-tracking"

    def __init__(
        self,
        max_speed: float,
        max_yaw_rate: float,
        interval: tuple[float, float],
        reward_weights: RewardWeights | None = None,
    ) -> None:
        self.reward_weights = reward_weights
        if not 0 < interval[0] <= interval[1]:
            raise ValueError(f"command_interval must be 0 < min <= max, got {interval}")
        self.max_speed = float(max_speed)
        self.max_yaw_rate = float(max_yaw_rate)
        self.interval = (float(interval[0]), float(interval[1]))

    def command(self, rng: np.random.Generator, t: float) -> Command:
        v = float(rng.uniform(0.3, 1.0)) * self.max_speed
        w = 0.0 if rng.random() < 1 / 3 else float(rng.uniform(-1, 1)) * self.max_yaw_rate
        return v, w, t + float(rng.uniform(*self.interval))
