"""An algorithm's hyperparameters are its stable-baselines3 constructor's arguments: names,
types and defaults are read from ``inspect.signature`` instead of being declared a second
time, so a typo or a wrong type fails at start-up naming the file and the key."""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable, Mapping
from typing import Any

from rover_env.config import ConfigError

RUNNER_SET = frozenset(
    "policy env policy_kwargs action_noise seed device verbose tensorboard_log _init_setup_model"
    " rollout_buffer_class rollout_buffer_kwargs replay_buffer_class replay_buffer_kwargs".split()
)
"""Arguments the runner sets (or a config states in its own typed form), not a config key."""


@functools.cache
def parameters(algo: str) -> dict[str, inspect.Parameter]:
    """The config-settable arguments of ``algo``'s SB3 class, in signature order."""
    from stable_baselines3 import PPO, SAC, TD3

    sig = inspect.signature({"ppo": PPO, "sac": SAC, "td3": TD3}[algo])  # its __init__'s
    return {n: p for n, p in sig.parameters.items() if n not in RUNNER_SET}


@functools.cache
def _annotations(algo: str) -> dict[str, str]:
    return {n: str(p.annotation) for n, p in parameters(algo).items()}


def is_schedule(algo: str, name: str) -> bool:
    """SB3 takes a callable of the remaining progress for this argument."""
    return "Callable" in _annotations(algo)[name]


def number(v: Any, where: str) -> float:
    # PyYAML reads 3e-4 (no dot) as a string, so numeric strings are accepted.
    if isinstance(v, str):
        try:
            v = float(v)
        except ValueError:
            raise ConfigError(f"{where}: expected a number, got {v!r}") from None
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ConfigError(f"{where}: expected a finite number, got {v!r}")
    return float(v)


def check_value(algo: str, name: str, v: Any, where: str, schedule: Callable[..., Any]) -> Any:
    """``v`` as the type SB3's annotation and default give ``name`` (``schedule`` converts a
    schedule argument)."""
    ann, default = _annotations(algo)[name], parameters(algo)[name].default
    if v is None:
        if default is None or "None" in ann:
            return None
        raise ConfigError(f"{where}: may not be null")
    if "Callable" in ann:
        return schedule(v, where)
    if ann == "<class 'bool'>":
        if not isinstance(v, bool):
            raise ConfigError(f"{where}: expected true or false, got {v!r}")
        return v
    if "float" in ann:
        if "str" in ann and isinstance(v, str):
            try:
                return number(v, where)
            except ConfigError:
                return v
        return number(v, where)
    if "int" in ann:  # int, or int | tuple (train_freq: a step count here)
        x = number(v, where)
        if x != int(x):
            raise ConfigError(f"{where}: expected an integer, got {v!r}")
        return int(x)
    if "str" in ann:
        if not isinstance(v, str):
            raise ConfigError(f"{where}: expected a string, got {v!r}")
        return v
    raise ConfigError(f"{where}: {name} ({ann}) cannot be set from a config file")


def check_hyperparams(
    algo: str, data: Mapping[str, Any], where: str, schedule: Callable[..., Any]
) -> dict[str, Any]:
    """Every key of ``data`` an argument of ``algo``'s SB3 class, converted to its type."""
    params = parameters(algo)
    unknown = sorted(set(map(str, data)) - set(params))
    if unknown:
        raise ConfigError(
            f"{where}: unknown key(s) {', '.join(unknown)}; allowed: {', '.join(sorted(params))}"
        )
    return {
        k: check_value(algo, k, v, f"{where}.{k}" if where else k, schedule)
        for k, v in data.items()
    }


def defaults(algo: str) -> dict[str, Any]:
    """SB3's default of every config-settable argument of ``algo``."""
    return {n: p.default for n, p in parameters(algo).items()}
