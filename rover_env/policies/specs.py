"""Every controller spec of the command line, built: classical ones and ``ppo:PATH``.

Specs: ``open-loop``, ``open-loop:axle_load``, ``slip-pi[:GAINS.yaml][@field=value...]``
(:mod:`rover_env.policies.controllers`) and ``ppo:PATH`` (a run folder or a ``.zip``,
:mod:`rover_env.policies.ppo`, imported only when asked so that torch loads only then).
"""

from __future__ import annotations

from typing import Any

from rover_env.policies.controllers import (
    EnvController,
    classical_settings,
    make_classical,
    split_overrides,
)

__all__ = ["controller_settings", "make_controller", "parse_specs"]


def make_controller(spec: str) -> EnvController:
    """Build a controller from its command-line spec (module docstring)."""
    kind, _, arg = spec.partition(":")
    if kind == "ppo" and arg:
        from rover_env.policies.ppo import PPOController  # lazy: torch only when asked

        return PPOController(arg, name=spec)
    if kind in ("open-loop", "slip-pi") or kind.startswith("slip-pi@"):
        return make_classical(spec)
    raise ValueError(
        f"unknown controller {spec!r}; use open-loop[:axle_load], slip-pi[:GAINS] or ppo:PATH"
    )


def controller_settings(spec: str) -> dict[str, Any]:
    """What decides a classical controller's actions (for the test ledger's hash)."""
    if spec.startswith("ppo:"):
        raise ValueError("a ppo: agent is identified by its files, not settings")
    return classical_settings(spec)


def parse_specs(text: str) -> list[str]:
    """Comma-separated specs, validated (the PPO path is checked when it is loaded)."""
    specs = [s.strip() for s in text.split(",") if s.strip()]
    if not specs:
        raise ValueError("no controllers given")
    if len(set(specs)) != len(specs):
        raise ValueError(f"controllers repeated in {text!r}")
    for s in specs:
        head, _ = split_overrides(s) if not s.startswith("ppo:") else (s, {})
        kind, _, arg = head.partition(":")
        bad_ol = kind == "open-loop" and arg not in ("", "axle_load")
        if kind not in ("open-loop", "slip-pi", "ppo") or (kind == "ppo" and not arg) or bad_ol:
            raise ValueError(f"unknown controller {s!r}; use open-loop, slip-pi or ppo:PATH")
        if kind != "ppo":
            make_classical(s)  # a bad override fails here, named
    return specs
