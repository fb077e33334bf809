"""Controllers as the benchmark runs them: every one through the environment.

The benchmark gives all controllers the same task and the same metrics by stepping the
Gymnasium environment for each of them. A controller here turns the env's state into an
*env action* (speed targets scaled to [-1, 1]):

* classical controllers (:mod:`rover_env.control`) get ``env.controller_input(obs)`` - the
  noisy estimate, joint angles and command the env just sampled - and their rad/s targets are
  divided by the motor's ``max_wheel_speed`` (the env multiplies them back; both clip at the
  same limit, so nothing is lost);
* a learnt policy (``ppo:PATH``, ``sac:PATH``, ``td3:PATH``, :mod:`rover_env.policies.ppo`)
  gets the observation the
  env returned, exactly as in training.

Classical specs (:func:`make_classical`): ``open-loop``, ``open-loop:axle_load``
(feed-forward with per-axle loaded radii, for comparison: what calibrating the radii alone
buys), either with ``@gain=K`` (every target x K: a fixed over-speed for loose soil) and
``@ramp=T`` (that over-speed grown from 1 over the first T s: a soft start),
``slip-pi`` (gains from ``configs/control/slip_pi.yaml``), ``slip-pi:PATH.yaml``
(other gains); any slip-pi spec may end in ``@field=value`` settings overrides
(``slip-pi@stuck_retry_scale=2@axle_fight_scale=0.25``), the fixed settings of the ablations
(:mod:`rover_env.benchmark.ablation`). Every spec, ``ppo:PATH`` included, is built by
:func:`rover_env.policies.specs.make_controller`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from rover_env.config import ConfigError, RoverConfig, to_dict
from rover_env.control.base import Controller, ControllerInput
from rover_env.control.open_loop import OpenLoop
from rover_env.control.slip_pi import SlipPI, SlipPIConfig, load_slip_pi_config
from rover_env.control.slip_pi import replace as replace_gains
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.estimation.estimator import axle_load_radii

__all__ = [
    "LEARNED_KINDS",
    "ClassicalController",
    "EnvController",
    "classical_settings",
    "make_classical",
    "split_overrides",
]

Obs = npt.NDArray[np.float32]

LEARNED_KINDS = ("ppo", "sac", "td3")
"""Spec prefixes of learned agents (``ppo:PATH``, ``sac:PATH``, ``td3:PATH``)."""


class EnvController(Protocol):
    """What the benchmark steps: a name, a reset, and an env action per observation."""

    name: str
    action_layout: str
    """The env's action layout this controller needs ("wheels" or "sides")."""

    def reset(self, env: ProtoExplorerEnv) -> None: ...

    def action(self, env: ProtoExplorerEnv, obs: Obs) -> Obs: ...


class ClassicalController:
    """A :class:`rover_env.control.Controller` fed by ``env.controller_input``."""

    action_layout = "wheels"

    def __init__(self, name: str, factory: Callable[[RoverConfig, float], Controller]) -> None:
        self.name = name
        self._factory = factory
        self._ctrl: Controller | None = None
        self._for: tuple[int, float] | None = None

    @property
    def controller(self) -> Controller | None:
        """The rover-side controller (built at the first ``reset``)."""
        return self._ctrl

    def reset(self, env: ProtoExplorerEnv) -> None:
        key = (id(env.rover_cfg), env.control_dt)
        if self._ctrl is None or self._for != key:
            self._ctrl = self._factory(env.rover_cfg, env.control_dt)
            self._for = key
        self._ctrl.reset()

    def action(self, env: ProtoExplorerEnv, obs: Obs) -> Obs:
        assert self._ctrl is not None, "reset() first"
        ci: ControllerInput = env.controller_input(obs)
        targets = np.asarray(self._ctrl.act(ci), dtype=np.float64)
        return np.asarray(targets / env.max_wheel_speed, dtype=np.float32)


def split_overrides(spec: str) -> tuple[str, dict[str, float]]:
    """``slip-pi:GAINS@kp=0.2@ki=1`` -> (``slip-pi:GAINS``, {kp: 0.2, ki: 1.0})."""
    head, *parts = spec.split("@")
    out: dict[str, float] = {}
    for part in parts:
        key, eq, value = part.partition("=")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            eq = ""
        if not eq or not key.strip():
            raise ValueError(f"controller {spec!r}: override {part!r} is not field=number")
    return head, out


def _slip_pi_config(spec: str) -> SlipPIConfig:
    head, overrides = split_overrides(spec)
    _, _, arg = head.partition(":")
    gains = load_slip_pi_config(arg or "slip_pi")
    if not overrides:
        return gains
    fields = {
        f.name
        for f in dataclasses.fields(SlipPIConfig)
        if isinstance(getattr(gains, f.name), float)
        and not isinstance(getattr(gains, f.name), bool)
    }
    unknown = sorted(set(overrides) - fields)
    if unknown:
        raise ValueError(f"controller {spec!r}: {unknown} are not numeric SlipPIConfig fields")
    try:
        return replace_gains(gains, **overrides)
    except (ConfigError, TypeError, ValueError) as exc:
        raise ValueError(f"controller {spec!r}: {exc}") from None


def make_classical(spec: str) -> ClassicalController:
    """A classical controller from its spec (module docstring)."""
    head, overrides = split_overrides(spec)
    kind, _, arg = head.partition(":")
    if overrides and kind == "open-loop":
        if not set(overrides) <= {"gain", "ramp"}:
            raise ValueError(f"controller {spec!r}: open-loop takes only @gain=K and @ramp=T")
        if not overrides.get("gain", 1.0) > 0:
            raise ValueError(f"controller {spec!r}: gain must be > 0")
        if not overrides.get("ramp", 0.0) >= 0:
            raise ValueError(f"controller {spec!r}: ramp must be >= 0 (s)")
    elif overrides and kind != "slip-pi":
        raise ValueError(f"controller {spec!r}: only slip-pi and open-loop take @ overrides")
    gain = overrides.get("gain", 1.0) if kind == "open-loop" else 1.0
    ramp = overrides.get("ramp", 0.0) if kind == "open-loop" else 0.0
    if kind == "open-loop" and not arg:
        return ClassicalController(spec, lambda cfg, dt: OpenLoop(cfg, gain=gain, ramp=ramp))
    if kind == "open-loop" and arg == "axle_load":
        return ClassicalController(
            spec, lambda cfg, dt: OpenLoop(cfg, axle_load_radii(cfg)[:4], gain=gain, ramp=ramp)
        )
    if kind == "slip-pi":
        gains = _slip_pi_config(spec)
        return ClassicalController(spec, lambda cfg, dt: SlipPI(cfg, gains, dt=dt))
    raise ValueError(
        f"unknown classical controller {spec!r}; use open-loop[:axle_load] or "
        "slip-pi[:GAINS][@field=value...]"
    )


def classical_settings(spec: str) -> dict[str, Any]:
    """What decides a classical controller's actions: its kind and resolved settings."""
    head, overrides = split_overrides(spec)
    kind, _, arg = head.partition(":")
    make_classical(spec)  # validates
    if kind == "slip-pi":
        return {"kind": kind, "settings": to_dict(_slip_pi_config(spec))}
    gain, ramp = overrides.get("gain", 1.0), overrides.get("ramp", 0.0)
    out: dict[str, Any] = {"kind": kind, "variant": arg}
    if gain != 1.0:  # the plain open loop keeps its former settings (and ledger hash)
        out["gain"] = gain
    if ramp != 0.0:
        out["ramp"] = ramp
    return out
