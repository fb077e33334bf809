"""The scenario mix: one benchmark scenario drawn per episode, its seed kept in its split.

Not a :class:`~rover_env.tasks.base.Task` itself: scenarios differ in the structure of their
ground (a rock, a slope), which needs another compiled simulator, so the env that plays the
mix (``rover_env.benchmark.mixture.ScenarioMixEnv``) keeps one env per scenario and gives it
the :class:`~rover_env.tasks.scenario.ScenarioTask` drawn here.

Seeds (:mod:`rover_env.seeds`): the jitter seed of the drawn scenario is the reset seed
itself when that seed is held out (a validation seed plays the benchmark's own validation
episode of the drawn scenario) and otherwise a seed drawn from the split of the last reset
seed (the training block after a training seed or none, the tuning or validation block after
one of theirs). Test seeds are played only as given: an unseeded reset after a test seed
raises rather than draw further test episodes (the test block is played only by a final
run, seed by seed), and a spent seed (:data:`rover_env.seeds.SPENT`) is refused. Training
seeds draw the scenario, jitter seed and command scales in the order the shipped agents were
trained with.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from rover_env.control.base import CommandSchedule
from rover_env.seeds import SPENT, draw_seed, refuse_final_only, split_of
from rover_env.tasks.scenario import ScenarioTask
from rover_env.tasks.scenarios import Episode, ScenarioConfig, load_scenario

__all__ = ["DEFAULT_MIX", "SOIL_MIX", "ScenarioMix"]

DEFAULT_MIX: dict[str, float] = {
    "stuck-wheel": 2.0,
    "split-mu": 2.0,
    "ice-patch": 2.0,
    "flat-turns": 1.0,
    "slope": 1.0,
    "bumps": 1.0,
}
"""Scenario weights: where slip is wasted counts double. The loose-soil scenarios are not in
it: the shipped agents were trained on this mix (``gym.make`` of the mix env must keep
meaning what they learnt on), and a soil episode costs more simulation time; ask for them
with ``scenarios=SOIL_MIX`` or ``{**DEFAULT_MIX, **SOIL_MIX}``."""

SOIL_MIX: dict[str, float] = {
    "sand-slope": 2.0,
    "soft-patch": 1.0,
    "sand-turns": 1.0,
}
"""The loose-soil scenarios (issue 15); the climb, where the open loop digs in, counts double."""


def _scaled(schedule: CommandSchedule, speed: float, yaw: float) -> CommandSchedule:
    return CommandSchedule(
        schedule.times,
        tuple(v * speed for v in schedule.speeds),
        tuple(w * yaw for w in schedule.yaw_rates),
    )


class ScenarioMix:
    """Draws one :class:`ScenarioTask` per episode (module docstring).

    Args:
        scenarios: name -> weight (default :data:`DEFAULT_MIX`), or names (equal weights).
        speed_scale: range of the factor on every commanded speed of an episode.
        yaw_scale: range of the factor on every commanded yaw rate (its sign is drawn too).
        scale_commands: False plays each episode's own schedule (a family draws its
            commands itself); the scales are drawn all the same, so the stream is unchanged.
    """

    def __init__(
        self,
        scenarios: dict[str, float] | Sequence[str] | None = None,
        speed_scale: tuple[float, float] = (0.6, 1.3),
        yaw_scale: tuple[float, float] = (0.5, 1.5),
        scale_commands: bool = True,
    ) -> None:
        mix = DEFAULT_MIX if scenarios is None else scenarios
        if not isinstance(mix, dict):
            mix = dict.fromkeys(mix, 1.0)
        if not mix or any(not (w > 0) for w in mix.values()):
            raise ValueError(f"scenarios need positive weights, got {mix}")
        self.names = list(mix)
        self.cfgs: list[ScenarioConfig] = [load_scenario(n) for n in self.names]
        p = np.array([mix[n] for n in self.names], dtype=np.float64)
        self.p = p / p.sum()
        self.speed_scale = (float(speed_scale[0]), float(speed_scale[1]))
        self.yaw_scale = (float(yaw_scale[0]), float(yaw_scale[1]))
        self.scale_commands = bool(scale_commands)
        self.split = "training"
        """The split of the last reset seed; unseeded episodes stay in it."""

    def draw(self, rng: np.random.Generator, seed: int | None) -> ScenarioTask:
        """The next episode's task; ``seed`` is the reset seed (None: continue the stream)."""
        if seed is not None:
            split = split_of(seed)
            if split == SPENT:
                refuse_final_only([seed], "ScenarioMix reset")
            self.split = split
        elif self.split == "test":
            raise ValueError(
                "ScenarioMix: an unseeded reset after a test seed would draw further test "
                "episodes; the test block is played only seed by seed by a final run "
                "(reset with a seed, or reset(seed=...) with a training/validation seed)"
            )
        i = int(rng.choice(len(self.cfgs), p=self.p))
        episode_seed = draw_seed(self.split, rng)  # drawn always: the same stream either way
        if seed is not None and self.split != "training":
            episode_seed = int(seed)  # a held-out seed plays its own episode
        episode: Episode = self.cfgs[i].episode(episode_seed)
        yaw = float(rng.uniform(*self.yaw_scale)) * (1.0 if rng.random() < 0.5 else -1.0)
        schedule = _scaled(episode.schedule, float(rng.uniform(*self.speed_scale)), yaw)
        if not self.scale_commands:
            return ScenarioTask(episode)
        return ScenarioTask(dataclasses.replace(episode, schedule=schedule))
