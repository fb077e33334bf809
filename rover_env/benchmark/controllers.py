"""Controllers as the benchmark runs them: every one through the environment.

The benchmark gives all controllers the same task and the same metrics by stepping the
Gymnasium environment for each of them. A controller here turns the env's state into an
*env action* (speed targets scaled to [-1, 1]):

* classical controllers (:mod:`rover_env.control`) get ``env.controller_input(obs)`` - the
  noisy estimate, joint angles and command the env just sampled - and their rad/s targets are
  divided by the motor's ``max_wheel_speed`` (the env multiplies them back; both clip at the
  same limit, so nothing is lost);
* a learnt policy (``ppo:PATH``, :mod:`rover_env.benchmark.policy`) gets the observation the
  env returned, exactly as in training.

Specs: ``open-loop``, ``open-loop:axle_load`` (feed-forward with per-axle loaded radii, for
comparison: what calibrating the radii alone buys), ``slip-pi`` (gains from
``configs/control/slip_pi.yaml``),
``slip-pi:NAME`` or ``slip-pi:PATH.yaml`` (other gains: ``slip-pi:slip_pi_soil`` is the
loose-soil loop with a slip set-point), ``ppo:PATH`` (a run folder or a ``.zip``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np
import numpy.typing as npt

from rover_env.config import RoverConfig
from rover_env.control.base import Controller, ControllerInput
from rover_env.control.open_loop import OpenLoop
from rover_env.control.slip_pi import SlipPI, load_slip_pi_config
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.estimation.estimator import axle_load_radii

__all__ = ["ClassicalController", "EnvController", "make_controller", "parse_specs"]

Obs = npt.NDArray[np.float32]


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


def make_controller(spec: str) -> EnvController:
    """Build a controller from its command-line spec (module docstring)."""
    kind, _, arg = spec.partition(":")
    if kind == "open-loop" and not arg:
        return ClassicalController(spec, lambda cfg, dt: OpenLoop(cfg))
    if kind == "open-loop" and arg == "axle_load":
        return ClassicalController(spec, lambda cfg, dt: OpenLoop(cfg, axle_load_radii(cfg)[:4]))
    if kind == "slip-pi":
        gains = load_slip_pi_config(arg or "slip_pi")
        return ClassicalController(spec, lambda cfg, dt: SlipPI(cfg, gains, dt=dt))
    if kind == "ppo" and arg:
        from rover_env.benchmark.policy import PPOController  # lazy: torch only when asked

        return PPOController(arg, name=spec)
    raise ValueError(
        f"unknown controller {spec!r}; use open-loop[:axle_load], slip-pi[:GAINS] or ppo:PATH"
    )


def parse_specs(text: str) -> list[str]:
    """Comma-separated specs, validated (the PPO path is checked when it is loaded)."""
    specs = [s.strip() for s in text.split(",") if s.strip()]
    if not specs:
        raise ValueError("no controllers given")
    if len(set(specs)) != len(specs):
        raise ValueError(f"controllers repeated in {text!r}")
    for s in specs:
        kind, _, arg = s.partition(":")
        bad_ol = kind == "open-loop" and arg not in ("", "axle_load")
        if kind not in ("open-loop", "slip-pi", "ppo") or (kind == "ppo" and not arg) or bad_ol:
            raise ValueError(f"unknown controller {s!r}; use open-loop, slip-pi or ppo:PATH")
    return specs
