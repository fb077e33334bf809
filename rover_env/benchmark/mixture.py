"""A training ground made of the benchmark's scenarios, and the residual action of its agents.

``ScenarioMixEnv`` (registered as ``rover_env/ProtoExplorerScenarioMix-v0``) runs, each
episode, one scenario of ``configs/scenarios`` drawn by the env's seeded generator, with a
jitter seed drawn from the seed plan's *training* block (so training never meets a test or
validation episode) and the commanded speed and yaw rate scaled at random, so a policy
learns the situations (ice, split friction, a blocked wheel, slopes, bumps, turns) rather
than one command. The observation and action are ``ProtoExplorerEnv``'s.

``action_residual`` (fraction of the maximum wheel speed, e.g. 0.5) makes the action a
correction added to a base controller's targets (:class:`Residual`; residual policy
learning) instead of an absolute target: a zero action then drives like the base, and
learning starts from a rover that already tracks the command. ``residual_base`` names the
base with a benchmark controller spec: ``"open-loop"`` (the skid-steer feed-forward,
kinematics only, :func:`residual_action`) or ``"slip-pi"`` (the tuned slip PI, whose
integrators then also remove any steady bias the policy adds). The ``ppo:`` benchmark
controller applies the same mapping, read from the run's config.

``action_schedule`` instead makes the action a *gain schedule* of the slip PI
(:class:`Schedule`): one number per knob of :data:`SCHEDULE_KNOBS`, given as ``{knob:
octaves}``, each scaling one of the PI's settings by ``2 ** (octaves * a)`` every step (the
list ``[deadband_octaves, gain_octaves]`` is the first schedule agents' form). The wheels are
always driven by the PI, so exploration noise perturbs how the PI corrects slip, not the
wheel speeds themselves: with a residual on the wheel targets every exploratory action is
itself slip, ten times the PI's own on ice (``docs/benchmark-ppo/attempts.md``). A zero
action is the PI as configured.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from rover_env.benchmark.run import ScenarioWrapper
from rover_env.benchmark.scenarios import Episode, load_scenario
from rover_env.benchmark.seeds import SPLITS
from rover_env.config import RoverConfig
from rover_env.control.base import CommandSchedule
from rover_env.control.open_loop import skid_steer_targets
from rover_env.control.slip_pi import SlipPI, SlipPIConfig
from rover_env.control.slip_pi import replace as replace_gains
from rover_env.envs.proto_explorer import OBS_NAMES, ProtoExplorerEnv
from rover_env.estimation.estimator import static_rolling_radius

__all__ = [
    "DEFAULT_MIX",
    "SCHEDULE_KNOBS",
    "SOIL_MIX",
    "Residual",
    "ScenarioMixEnv",
    "Schedule",
    "residual_action",
    "schedule_knobs",
]

Obs = npt.NDArray[np.float32]

_I_CMD = OBS_NAMES.index("command_speed")

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


def residual_action(action: npt.ArrayLike, obs: Obs, rover_cfg: RoverConfig, scale: float) -> Obs:
    """Env action (normalised wheel targets 1L 1R 2L 2R) = feed-forward + scale * action.

    The feed-forward is the open-loop targets of the command in ``obs`` (its
    ``command_speed``, ``command_yaw_rate`` entries) over the maximum wheel speed.
    """
    a = np.asarray(action, dtype=np.float64).reshape(-1)
    if a.shape != (4,):
        raise ValueError(f"residual action must have 4 entries (1L 1R 2L 2R), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"residual action has non-finite entries: {a}")
    v, w = float(obs[_I_CMD]), float(obs[_I_CMD + 1])
    ff = skid_steer_targets(
        v, w, rover_cfg.geometry.half_track, static_rolling_radius(rover_cfg)
    ) / float(rover_cfg.motor.max_wheel_speed)
    return np.clip(ff + scale * np.clip(a, -1.0, 1.0), -1.0, 1.0).astype(np.float32)


class Residual:
    """Env action = base controller's env action + scale * policy action, clipped to [-1, 1]."""

    def __init__(self, base: str, scale: float) -> None:
        from rover_env.benchmark.controllers import make_controller

        if base.startswith("ppo"):
            raise ValueError(f"residual_base must be a classical controller, got {base!r}")
        if not 0 < scale <= 2:
            raise ValueError(f"action_residual must be in (0, 2], got {scale}")
        self.base = make_controller(base)
        self.scale = float(scale)

    def reset(self, env: ProtoExplorerEnv) -> None:
        self.base.reset(env)

    def __call__(self, action: npt.ArrayLike, env: ProtoExplorerEnv, obs: Obs) -> Obs:
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (4,) or not np.all(np.isfinite(a)):
            raise ValueError(f"residual action must be 4 finite entries (1L 1R 2L 2R), got {a}")
        base = np.asarray(self.base.action(env, obs), dtype=np.float64)
        return np.clip(base + self.scale * np.clip(a, -1.0, 1.0), -1.0, 1.0).astype(np.float32)


SCHEDULE_KNOBS: dict[str, tuple[str, ...]] = {
    "deadband": ("deadband",),  # capped at max_deadband
    "gain": ("kp", "ki"),
    "axle_fight": ("axle_fight_scale",),  # the axle-fight mode's deadband alone
    "retry_interval": ("retry_interval",),  # how long a wheel held stopped waits
    "stuck_retry": ("stuck_retry_scale",),  # how long a stopped stuck wheel waits
}
"""Each knob of a :class:`Schedule`: the slip PI settings its action scales by ``2^(o a)``
(``o``: the knob's octaves)."""


def schedule_knobs(spec: Sequence[float] | Mapping[str, float]) -> dict[str, float]:
    """``{knob: octaves}`` from an ``action_schedule``: a mapping over :data:`SCHEDULE_KNOBS`,
    or the list ``[deadband_octaves, gain_octaves]`` (the first schedule agents' form)."""
    if isinstance(spec, Mapping):
        knobs = {str(k): v for k, v in spec.items()}
    else:
        seq = list(spec)
        if len(seq) != 2:
            raise ValueError(
                f"action_schedule as a list must be [deadband_octaves, gain_octaves], got {spec!r}"
            )
        knobs = {"deadband": seq[0], "gain": seq[1]}
    unknown = sorted(set(knobs) - set(SCHEDULE_KNOBS))
    if unknown or not knobs:
        raise ValueError(
            f"action_schedule knobs {unknown or '(none)'} unknown; use {', '.join(SCHEDULE_KNOBS)}"
        )
    out: dict[str, float] = {}
    for k, v in knobs.items():
        if isinstance(v, bool) or not isinstance(v, int | float) or not 0 <= v <= 3:
            raise ValueError(f"action_schedule.{k} must be octaves in [0, 3], got {v!r}")
        out[k] = float(v)
    return out


class Schedule:
    """Env action = the slip PI's, some of its settings scaled each step by the action (one
    action per knob of :data:`SCHEDULE_KNOBS`, in the order given)."""

    def __init__(self, base: str, spec: Sequence[float] | Mapping[str, float]) -> None:
        from rover_env.benchmark.controllers import make_controller

        if not base.startswith("slip-pi"):
            raise ValueError(f"action_schedule needs a slip-pi base controller, got {base!r}")
        self.knobs = schedule_knobs(spec)
        self.base = make_controller(base)
        self._pi: SlipPI | None = None
        self._cfg0: SlipPIConfig | None = None

    @property
    def n_actions(self) -> int:
        return len(self.knobs)

    def reset(self, env: ProtoExplorerEnv) -> None:
        self.base.reset(env)
        pi = getattr(self.base, "_ctrl", None)
        assert isinstance(pi, SlipPI)
        if pi is not self._pi or self._cfg0 is None:
            self._pi, self._cfg0 = pi, pi.cfg
        pi.cfg = self._cfg0

    def gains(self, action: npt.ArrayLike) -> SlipPIConfig:
        """The PI's settings for one action (validated: a bad action raises ValueError)."""
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (self.n_actions,) or not np.all(np.isfinite(a)):
            raise ValueError(
                f"schedule action must be {self.n_actions} finite entries "
                f"({', '.join(self.knobs)}), got {a}"
            )
        assert self._cfg0 is not None, "reset() first"
        c0 = self._cfg0
        changes: dict[str, float] = {}
        for (knob, octaves), x in zip(self.knobs.items(), np.clip(a, -1.0, 1.0), strict=True):
            f = 2.0 ** (octaves * x)
            for name in SCHEDULE_KNOBS[knob]:
                changes[name] = getattr(c0, name) * f
        if "deadband" in changes:
            changes["deadband"] = min(changes["deadband"], c0.max_deadband)
        return replace_gains(c0, **changes)

    def __call__(self, action: npt.ArrayLike, env: ProtoExplorerEnv, obs: Obs) -> Obs:
        assert self._pi is not None, "reset() first"
        self._pi.cfg = self.gains(action)
        return self.base.action(env, obs)


def _scaled(schedule: CommandSchedule, speed: float, yaw: float) -> CommandSchedule:
    return CommandSchedule(
        schedule.times,
        tuple(v * speed for v in schedule.speeds),
        tuple(w * yaw for w in schedule.yaw_rates),
    )


class ScenarioMixEnv(gym.Env[Obs, Obs]):
    """Benchmark scenarios drawn per episode, for training (see the module docstring).

    Args:
        scenarios: scenario name -> weight (default :data:`DEFAULT_MIX`), or a list of names
            (equal weights).
        action_residual: None for absolute targets (the plain env's action), or the scale of
            a residual on the base controller (fraction of the maximum wheel speed).
        residual_base: the base controller's spec, "open-loop" or "slip-pi" (module docstring).
        action_schedule: None, or ``{knob: octaves}`` over :data:`SCHEDULE_KNOBS` (or
            ``[deadband_octaves, gain_octaves]``): the action is then a gain schedule of the
            ``residual_base`` slip PI (:class:`Schedule`), one value per knob.
        speed_scale: range of the factor on every commanded speed of an episode.
        yaw_scale: range of the factor on every commanded yaw rate (its sign is drawn too).
        **env_kwargs: passed to every scenario's ``ProtoExplorerEnv`` (e.g. reward_weights);
            ``terrain`` comes from the scenario.
    """

    metadata = {"render_modes": [], "render_fps": 10}  # noqa: RUF012

    def __init__(
        self,
        scenarios: dict[str, float] | Sequence[str] | None = None,
        action_residual: float | None = None,
        residual_base: str = "open-loop",
        action_schedule: Sequence[float] | Mapping[str, float] | None = None,
        speed_scale: tuple[float, float] = (0.6, 1.3),
        yaw_scale: tuple[float, float] = (0.5, 1.5),
        **env_kwargs: Any,
    ) -> None:
        mix = DEFAULT_MIX if scenarios is None else scenarios
        if not isinstance(mix, dict):
            mix = dict.fromkeys(mix, 1.0)
        if not mix or any(not (w > 0) for w in mix.values()):
            raise ValueError(f"scenarios need positive weights, got {mix}")
        if "terrain" in env_kwargs:
            raise ValueError("ScenarioMixEnv: the terrain comes from each scenario, not env_kwargs")
        if action_residual is not None and action_schedule is not None:
            raise ValueError("give action_residual or action_schedule, not both")
        self.residual: Residual | Schedule | None = None
        if action_residual is not None:
            self.residual = Residual(residual_base, action_residual)
        elif action_schedule is not None:
            self.residual = Schedule(residual_base, action_schedule)
        if self.residual is not None and env_kwargs.get("action_layout", "wheels") != "wheels":
            raise ValueError("action_residual and action_schedule need action_layout='wheels'")
        self.names = list(mix)
        self.cfgs = [load_scenario(n) for n in self.names]
        p = np.array([mix[n] for n in self.names], dtype=np.float64)
        self.p = p / p.sum()
        self.speed_scale = (float(speed_scale[0]), float(speed_scale[1]))
        self.yaw_scale = (float(yaw_scale[0]), float(yaw_scale[1]))
        self.env_kwargs = dict(env_kwargs)
        self._wrappers: dict[str, ScenarioWrapper] = {}
        first = self._wrapper(self.cfgs[0].episode(SPLITS["training"].start))
        self.rover_cfg = first.base.rover_cfg
        self.observation_space = first.observation_space
        self.action_space = first.action_space
        if isinstance(self.residual, Schedule):
            self.action_space = gym.spaces.Box(
                -1.0, 1.0, (self.residual.n_actions,), dtype=np.float32
            )
        self._active: ScenarioWrapper = first
        self._obs: Obs = np.zeros(len(OBS_NAMES), dtype=np.float32)

    def _wrapper(self, episode: Episode) -> ScenarioWrapper:
        if episode.scenario not in self._wrappers:
            env = ProtoExplorerEnv(terrain=episode.terrain, **self.env_kwargs)
            self._wrappers[episode.scenario] = ScenarioWrapper(env)
        return self._wrappers[episode.scenario]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        super().reset(seed=seed)
        rng = self.np_random
        i = int(rng.choice(len(self.cfgs), p=self.p))
        block = SPLITS["training"]
        episode = self.cfgs[i].episode(int(rng.integers(block.start, block.stop)))
        yaw = float(rng.uniform(*self.yaw_scale)) * (1.0 if rng.random() < 0.5 else -1.0)
        schedule = _scaled(episode.schedule, float(rng.uniform(*self.speed_scale)), yaw)
        episode = dataclasses.replace(episode, schedule=schedule)
        self._active = self._wrapper(episode)
        self._active.set_episode(episode)
        obs, info = self._active.reset()
        if self.residual is not None:
            self.residual.reset(self._active.base)
        info["scenario"] = episode.scenario
        self._obs = obs
        return obs, info

    def step(self, action: Obs) -> tuple[Obs, float, bool, bool, dict[str, Any]]:
        a = action
        if self.residual is not None:
            a = self.residual(action, self._active.base, self._obs)
        obs, reward, terminated, truncated, info = self._active.step(a)
        self._obs = obs
        return obs, reward, terminated, truncated, info

    def close(self) -> None:
        for w in self._wrappers.values():
            w.close()
