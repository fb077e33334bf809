"""The action mappings of the learned agents: a residual on a base controller, or a gain
schedule of the slip PI.

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

Used by the scenario-mix training env (:mod:`rover_env.benchmark.mixture`) and by the
``ppo:`` controller (:mod:`rover_env.policies.ppo`), which read the same ``env_kwargs``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from rover_env.config import RoverConfig
from rover_env.control.open_loop import skid_steer_targets
from rover_env.control.slip_pi import SlipPI, SlipPIConfig
from rover_env.control.slip_pi import replace as replace_gains
from rover_env.envs.proto_explorer import OBS_NAMES, ProtoExplorerEnv
from rover_env.estimation.estimator import static_rolling_radius
from rover_env.policies.controllers import LEARNED_KINDS, make_classical

__all__ = [
    "SCHEDULE_KNOBS",
    "Residual",
    "Schedule",
    "residual_action",
    "schedule_knobs",
]

Obs = npt.NDArray[np.float32]

_I_CMD = OBS_NAMES.index("command_speed")


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
    """Env action = base controller's env action + scale * policy action, clipped to [-1, 1].

    ``ramp`` (s, default 0: none) grows the residual's authority linearly from 0 at the
    drive's start to ``scale`` at ``t = ramp``: during a soft-start base
    (``open-loop@gain=K@ramp=T``) the policy then cannot undo the soft start. Why: on the
    sand climb the start decides the sinkage and energy, and a policy paid for progress from
    the first step speeds the wheels up there (``docs/benchmark-agents-mobility``).
    """

    def __init__(self, base: str, scale: float, ramp: float = 0.0) -> None:
        if base.split(":")[0] in LEARNED_KINDS:
            raise ValueError(f"residual_base must be a classical controller, got {base!r}")
        if not 0 < scale <= 2:
            raise ValueError(f"action_residual must be in (0, 2], got {scale}")
        if isinstance(ramp, bool) or not (np.isfinite(ramp) and 0 <= ramp <= 60):
            raise ValueError(f"residual_ramp must be a time in [0, 60] s, got {ramp!r}")
        self.base = make_classical(base)
        self.scale = float(scale)
        self.ramp = float(ramp)

    def authority(self, t: float) -> float:
        """The residual's scale at drive time ``t`` (s)."""
        if self.ramp <= 0.0:
            return self.scale
        return self.scale * min(max(t, 0.0) / self.ramp, 1.0)

    def reset(self, env: ProtoExplorerEnv) -> None:
        self.base.reset(env)

    def __call__(self, action: npt.ArrayLike, env: ProtoExplorerEnv, obs: Obs) -> Obs:
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (4,) or not np.all(np.isfinite(a)):
            raise ValueError(f"residual action must be 4 finite entries (1L 1R 2L 2R), got {a}")
        base = np.asarray(self.base.action(env, obs), dtype=np.float64)
        scale = self.authority(env.controller_input(obs).t) if self.ramp > 0 else self.scale
        return np.clip(base + scale * np.clip(a, -1.0, 1.0), -1.0, 1.0).astype(np.float32)


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
        if not base.startswith("slip-pi"):
            raise ValueError(f"action_schedule needs a slip-pi base controller, got {base!r}")
        self.knobs = schedule_knobs(spec)
        self.base = make_classical(base)
        self._pi: SlipPI | None = None
        self._cfg0: SlipPIConfig | None = None

    @property
    def n_actions(self) -> int:
        return len(self.knobs)

    def reset(self, env: ProtoExplorerEnv) -> None:
        self.base.reset(env)
        pi = self.base.controller
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
