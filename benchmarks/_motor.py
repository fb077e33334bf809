"""Another motor for the model: the ``--motor FIELD=FACTOR`` option of the benchmarks that ask
what the independent generator's effects look like under another speed loop
(``effect_twin.py``, ``truth_ceiling.py``)."""

from __future__ import annotations

import argparse
import dataclasses
from dataclasses import replace
from typing import Any

from rover_env.config import MotorSpec, RoverConfig


def with_motor(cfg: RoverConfig, motor: dict[str, Any]) -> RoverConfig:
    """``cfg`` with its motor's fields scaled by the numbers in ``motor`` (set by strings)."""
    m = cfg.motor
    kw: dict[str, Any] = {
        k: v if isinstance(v, str) else getattr(m, k) * v for k, v in motor.items()
    }
    return replace(cfg, motor=replace(m, **kw))


def parse_motor(text: str) -> tuple[str, Any]:
    """``FIELD=FACTOR`` (a number: a factor) or ``FIELD=VALUE`` (a word: the value)."""
    key, sep, value = text.partition("=")
    fields = {f.name for f in dataclasses.fields(MotorSpec)}
    if not sep or key not in fields:
        raise SystemExit(f"--motor {text!r}: FIELD=FACTOR with FIELD one of {sorted(fields)}")
    try:
        return key, float(value)
    except ValueError:
        return key, value


def add_motor_argument(ap: argparse.ArgumentParser) -> None:
    """The ``--motor FIELD=FACTOR`` option (repeatable; read with :func:`motors`)."""
    ap.add_argument(
        "--motor",
        action="append",
        default=[],
        metavar="FIELD=FACTOR",
        help="scale a motor field of the model first (armature=2, speed_gain=2.8;"
        " anti_windup=conditional sets it)",
    )


def motors(args: argparse.Namespace) -> dict[str, Any]:
    """The fields ``--motor`` scales or sets."""
    return dict(parse_motor(m) for m in args.motor)
