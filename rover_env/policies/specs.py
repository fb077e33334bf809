"""Every controller spec of the command line, built: classical ones and learned agents.

Specs: ``open-loop[@gain=K]``, ``open-loop:axle_load``, ``slip-pi[:GAINS.yaml][@field=value...]``
(:mod:`rover_env.policies.controllers`) and ``ppo:PATH``, ``sac:PATH``, ``td3:PATH`` (a run
folder or a ``.zip``, :mod:`rover_env.policies.ppo`, imported only when asked so that torch
loads only then).
"""

from __future__ import annotations

from typing import Any

from rover_env.policies.controllers import (
    LEARNED_KINDS,
    EnvController,
    classical_settings,
    make_classical,
    split_overrides,
)

__all__ = ["controller_settings", "is_learned", "make_controller", "parse_specs"]

_USE = "open-loop[:axle_load][@gain=K], slip-pi[:GAINS], ppo:PATH, sac:PATH or td3:PATH"


def is_learned(spec: str) -> bool:
    """A learned agent's spec (``ppo:``, ``sac:``, ``td3:``)?"""
    kind, sep, arg = spec.partition(":")
    return kind in LEARNED_KINDS and bool(sep and arg)


def make_controller(spec: str) -> EnvController:
    """Build a controller from its command-line spec (module docstring)."""
    kind, _, arg = spec.partition(":")
    if is_learned(spec):
        from rover_env.policies.ppo import SB3Controller  # lazy: torch only when asked

        return SB3Controller(arg, name=spec, algo=kind)
    if kind in ("open-loop", "slip-pi") or kind.startswith(("slip-pi@", "open-loop@")):
        return make_classical(spec)
    raise ValueError(f"unknown controller {spec!r}; use {_USE}")


def controller_settings(spec: str) -> dict[str, Any]:
    """What decides a classical controller's actions (for the test ledger's hash)."""
    if is_learned(spec):
        raise ValueError(f"a learned agent ({spec}) is identified by its files, not settings")
    return classical_settings(spec)


def parse_specs(text: str) -> list[str]:
    """Comma-separated specs, validated (an agent's path is checked when it is loaded)."""
    specs = [s.strip() for s in text.split(",") if s.strip()]
    if not specs:
        raise ValueError("no controllers given")
    if len(set(specs)) != len(specs):
        raise ValueError(f"controllers repeated in {text!r}")
    for s in specs:
        if is_learned(s):
            continue
        head, _ = split_overrides(s)
        kind, _, arg = head.partition(":")
        bad_ol = kind == "open-loop" and arg not in ("", "axle_load")
        if kind not in ("open-loop", "slip-pi") or bad_ol:
            raise ValueError(f"unknown controller {s!r}; use {_USE}")
        make_classical(s)  # a bad override fails here, named
    return specs
