"""One episode of a benchmark scenario as a task: its ground, start pose, fixed command
schedule and length."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rover_env.tasks.base import Command, EpisodeSetup, Task
from rover_env.tasks.reward import RewardWeights
from rover_env.tasks.scenarios import Episode

__all__ = ["ScenarioTask"]

_EPS = 1e-9  # CommandSchedule.at's tolerance on a breakpoint


class ScenarioTask(Task):
    """The :class:`Episode` of one scenario seed. The command at time t is
    ``episode.schedule.at(t)``; the env asks again at the schedule's next breakpoint."""

    def __init__(self, episode: Episode, reward_weights: RewardWeights | None = None) -> None:
        self.episode = episode
        self.name = episode.scenario
        self.time_limit = episode.duration
        self.reward_weights = reward_weights

    def setup(self, rng: np.random.Generator) -> EpisodeSetup:
        return EpisodeSetup(
            terrain=self.episode.terrain, start=self.episode.start, timestep=self.episode.timestep
        )

    def reset_info(self) -> dict[str, Any]:
        """``world``: the episode's drawn parameters (empty for a fixed scenario)."""
        return {"world": dict(self.episode.world)}

    def command(self, rng: np.random.Generator, t: float) -> Command:
        v, w = self.episode.schedule.at(t)
        later = [b for b in self.episode.schedule.times if b > t + _EPS]
        return v, w, (later[0] - _EPS) if later else math.inf
