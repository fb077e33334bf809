"""The Task interface: what one episode asks of the rover (see :mod:`rover_env.tasks`)."""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rover_env.config import TerrainConfig
from rover_env.tasks.reward import RewardWeights, StepResult, reward_terms

__all__ = ["Command", "EpisodeSetup", "Task"]

Command = tuple[float, float, float]
"""(forward speed m/s, yaw rate rad/s, time from which the task wants a new command, s)."""


@dataclass(frozen=True)
class EpisodeSetup:
    """Where an episode starts: ``None`` leaves the choice to the env (its ground; the arena
    centre with a random heading, or the ``reset`` options)."""

    terrain: TerrainConfig | None = None
    start: tuple[float, float, float] | None = None
    """x, y (m) and heading (rad) of the front axle at rest."""
    timestep: float | None = None
    """Physics substep (s) the episode was drawn for (None: any); an env at another refuses
    it, so a family's world is never played at a step its figures were not made at."""


class Task(abc.ABC):
    """Command schedule, episode setup and time limit of an episode.

    The env calls :meth:`setup` at every reset, :meth:`command` at the start of the episode
    and again whenever the simulated time reaches the time the last command named, and ends
    the episode (truncation) once the time reaches :attr:`time_limit` (None: never; the
    registered ``max_episode_steps`` then ends it). Randomness comes only from the env's
    seeded generator ``rng``.
    """

    name: str = "task"
    time_limit: float | None = None
    reward_weights: RewardWeights | None = None
    """The weights of the env's reward terms for this task (None: the env's own
    ``reward_weights`` argument)."""

    def setup(self, rng: np.random.Generator) -> EpisodeSetup:
        """The episode's ground and start pose (default: the env decides)."""
        return EpisodeSetup()

    def reset_info(self) -> dict[str, Any]:
        """Entries the env adds to ``reset``'s info (a scenario's drawn ``world``)."""
        return {}

    @abc.abstractmethod
    def command(self, rng: np.random.Generator, t: float) -> Command:
        """The command from time ``t`` on and when to ask again (``math.inf``: never)."""

    def reward(self, weights: RewardWeights, result: StepResult) -> tuple[float, dict[str, float]]:
        """The step's reward and its terms by info key (:func:`~rover_env.tasks.reward.reward_terms`)."""
        return reward_terms(weights, result)

    def terminated(self, result: StepResult) -> bool:
        """Whether the step ends the episode: a flip or leaving the arena."""
        return result.terminated

    def truncated(self, t: float) -> bool:
        """Whether time ``t`` is past the task's length."""
        return self.time_limit is not None and t >= self.time_limit - 1e-9


NEVER = math.inf
