"""A training ground made of the benchmark's scenarios, one drawn per episode.

``ScenarioMixEnv`` (registered as ``rover_env/ProtoExplorerScenarioMix-v0``) runs, each
episode, one scenario of ``configs/scenarios`` drawn by the env's seeded generator, with the
commanded speed and yaw rate scaled at random, so a policy learns the situations (ice, split
friction, a blocked wheel, slopes, bumps, turns) rather than one command. The observation
and action are ``ProtoExplorerEnv``'s.

Seeds stay in their split (:mod:`rover_env.seeds`): the scenario's jitter seed of an episode
is the reset seed itself when that seed is held out (``reset(seed=2000)`` plays the
validation episode 2000 of the drawn scenario, the one the benchmark plays for seed 2000),
and otherwise a seed drawn from the split of the last reset seed: the training block after a
training seed (or none), so training never meets a tuning, validation or test episode, and
the validation block for unseeded resets after a validation seed. An unseeded reset after a
test seed raises (test episodes are played seed by seed, by a final run only), and a spent
seed (the old test block 3000-3999) is refused. Episodes of training seeds
are those the shipped agents were trained on, draw for draw. ``info["seed_split"]`` and
``info["episode_seed"]`` say which episode was played.

``rover_env/ProtoExplorerFamilies-v0`` (:func:`families_env`, issue 46) is the same env over
the scenario families' training distributions (``NAME@train``, :data:`FAMILY_MIX`): each
episode's world (soil, slope, ripples, patches, rock, commands, start) is drawn from its seed
and reported in ``info["world"]``; the commands are the family's own (``scale_commands``
False). ``ProtoExplorerScenarioMix-v0`` keeps meaning the fixed worlds the shipped agents
learnt on.

Version history: v0. Issue 17 made held-out seeds play their own split's episodes (before,
every reset seed drew a training-block episode, so "validation" was training episodes);
episodes of training seeds are unchanged draw for draw, so the id was kept. Stop 41 changed
the loose soil's rut map (docs/soil.md 3.4b) and raised ``soft-patch``'s ripples to 9 cm: with
``scenarios=SOIL_MIX`` (or any soil scenario) episodes differ from before; the default mix is
hard ground only and unchanged, so the id was kept and the change is the scenarios' (agents
trained on soil before stop 41 met the old map: docs/benchmark-agents-soil/README.md).

The action may be a residual or a gain schedule (``action_residual``, ``action_schedule``;
:mod:`rover_env.policies.residual`). ``stall_clock`` appends one observation, the seconds the
rover has been slow (:mod:`rover_env.policies.memory`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from rover_env.benchmark.run import ScenarioWrapper
from rover_env.envs.proto_explorer import OBS_NAMES, ProtoExplorerEnv
from rover_env.policies.memory import StallClock, stall_clock_from
from rover_env.policies.residual import Residual, Schedule
from rover_env.seeds import SPLITS
from rover_env.tasks.mix import DEFAULT_MIX, SOIL_MIX, ScenarioMix
from rover_env.tasks.scenarios import Episode

__all__ = ["DEFAULT_MIX", "FAMILY_MIX", "SOIL_MIX", "ScenarioMixEnv", "families_env"]

FAMILY_MIX: dict[str, float] = {f"{k}@train": w for k, w in {**DEFAULT_MIX, **SOIL_MIX}.items()}
"""Every scenario family's training distribution, weighted as the fixed mixes
(``rover_env/ProtoExplorerFamilies-v0``)."""

Obs = npt.NDArray[np.float32]


class ScenarioMixEnv(gym.Env[Obs, Obs]):
    """Benchmark scenarios drawn per episode, for training (see the module docstring).

    Args:
        scenarios: scenario name -> weight (default :data:`DEFAULT_MIX`), or a list of names
            (equal weights).
        action_residual: None for absolute targets (the plain env's action), or the scale of
            a residual on the base controller (fraction of the maximum wheel speed).
        residual_base: the base controller's spec, "open-loop" or "slip-pi"
            (:mod:`rover_env.policies.residual`).
        residual_ramp: seconds over which the residual's authority grows from 0 to
            ``action_residual`` at each episode's start (0: from the first step).
        action_schedule: None, or ``{knob: octaves}`` over ``SCHEDULE_KNOBS`` (or
            ``[deadband_octaves, gain_octaves]``): the action is then a gain schedule of the
            ``residual_base`` slip PI (:class:`Schedule`), one value per knob.
        stall_clock: None/false, true or ``{speed, cap}``: append the seconds since the
            estimated speed was last >= ``speed`` (:class:`StallClock`) to the observation,
            which then has 47 values.
        speed_scale: range of the factor on every commanded speed of an episode.
        yaw_scale: range of the factor on every commanded yaw rate (its sign is drawn too).
        scale_commands: False plays each episode's own commands (the families' env).
        **env_kwargs: passed to every scenario's ``ProtoExplorerEnv`` (e.g. reward_weights);
            ``terrain`` comes from the scenario.
    """

    metadata = {"render_modes": [], "render_fps": 10}  # noqa: RUF012

    def __init__(
        self,
        scenarios: dict[str, float] | Sequence[str] | None = None,
        action_residual: float | None = None,
        residual_base: str = "open-loop",
        residual_ramp: float = 0.0,
        action_schedule: Sequence[float] | Mapping[str, float] | None = None,
        stall_clock: bool | Mapping[str, float] | None = None,
        speed_scale: tuple[float, float] = (0.6, 1.3),
        yaw_scale: tuple[float, float] = (0.5, 1.5),
        scale_commands: bool = True,
        **env_kwargs: Any,
    ) -> None:
        if "terrain" in env_kwargs:
            raise ValueError("ScenarioMixEnv: the terrain comes from each scenario, not env_kwargs")
        if action_residual is not None and action_schedule is not None:
            raise ValueError("give action_residual or action_schedule, not both")
        self.mix = ScenarioMix(scenarios, speed_scale, yaw_scale, scale_commands)
        self.residual: Residual | Schedule | None = None
        if action_residual is not None:
            self.residual = Residual(residual_base, action_residual, residual_ramp)
        elif action_schedule is not None:
            self.residual = Schedule(residual_base, action_schedule)
        if self.residual is not None and env_kwargs.get("action_layout", "wheels") != "wheels":
            raise ValueError("action_residual and action_schedule need action_layout='wheels'")
        self.clock: StallClock | None = stall_clock_from(stall_clock)
        self.names = self.mix.names
        self.p = self.mix.p
        self.env_kwargs = dict(env_kwargs)
        self._wrappers: dict[str, ScenarioWrapper] = {}
        first = self._wrapper(self.mix.cfgs[0].episode(SPLITS["training"].start))
        self.rover_cfg = first.base.rover_cfg
        self.observation_space = first.observation_space
        if self.clock is not None:
            n = len(OBS_NAMES) + 1
            self.observation_space = gym.spaces.Box(-np.inf, np.inf, (n,), dtype=np.float32)
        self.action_space = first.action_space
        if isinstance(self.residual, Schedule):
            self.action_space = gym.spaces.Box(
                -1.0, 1.0, (self.residual.n_actions,), dtype=np.float32
            )
        self._active: ScenarioWrapper = first
        self._obs: Obs = np.zeros(len(OBS_NAMES), dtype=np.float32)

    def _wrapper(self, episode: Episode) -> ScenarioWrapper:
        if episode.scenario not in self._wrappers:
            env = ProtoExplorerEnv(**{**episode.env_kwargs(), **self.env_kwargs})
            self._wrappers[episode.scenario] = ScenarioWrapper(env)
        return self._wrappers[episode.scenario]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        super().reset(seed=seed)
        task = self.mix.draw(self.np_random, seed)
        episode = task.episode
        self._active = self._wrapper(episode)
        self._active.set_episode(task)
        obs, info = self._active.reset()
        if self.residual is not None:
            self.residual.reset(self._active.base)
        info["scenario"] = episode.scenario
        info["seed_split"] = self.mix.split
        info["episode_seed"] = episode.seed
        self._obs = obs
        if self.clock is not None:
            self.clock.reset()
            return self.clock.extend(obs, 0.0), info
        return obs, info

    def step(self, action: Obs) -> tuple[Obs, float, bool, bool, dict[str, Any]]:
        a = action
        if self.residual is not None:
            a = self.residual(action, self._active.base, self._obs)
        obs, reward, terminated, truncated, info = self._active.step(a)
        self._obs = obs
        if self.clock is not None:
            obs = self.clock.extend(obs, self._active.base.control_dt)
        return obs, float(reward), terminated, truncated, info

    def close(self) -> None:
        for w in self._wrappers.values():
            w.close()


def families_env(**kwargs: Any) -> ScenarioMixEnv:
    """``rover_env/ProtoExplorerFamilies-v0``: the scenario mix over the families' training
    distributions (:data:`FAMILY_MIX`), each episode a world its seed draws, with its own
    commands (no further scaling). Held-out seeds play their own split's worlds, as in the
    mix; the shifts are never drawn. ``kwargs``: :class:`ScenarioMixEnv`'s."""
    kwargs.setdefault("scenarios", FAMILY_MIX)
    kwargs.setdefault("scale_commands", False)
    return ScenarioMixEnv(**kwargs)
