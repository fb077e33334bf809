"""Whether the clean-fit allowance table was measured the way this diagnosis runs.

The allowance (:mod:`rover_env.calibration.form_allowance`) is what each effect's fit finds
on clean drives: a property of the procedure that fitted them (the model forms searched,
the fit's budget, the split) and of the configured rover, not of the effect alone. An
entry measured under one procedure judges another's fits by the wrong spread: on clean
builds of the independent generator, the torque limit's fit went from a median cut of 18 %
to 45 % under ``--torque-forms`` (stop 111), and with the drives the report proposes for an
untested limit from 18 % to 53-55 % (stop 112, two builds). So a table records the options it
was measured with (``options``: those that differed from the defaults) and the rover its
logs named (``rover``), and a diagnosis that differs in either says so in its report.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from rover_env.calibration.diagnosis.state import Options
from rover_env.calibration.form_allowance import FormAllowance
from rover_env.config import ConfigError, RoverConfig, load_rover

PROCEDURE = (
    "settings",
    "numpy_every",
    "screen",
    "screen_coarse",
    "screen_middle",
    "screen_shared",
    "max_nfev",
    "second",
    "reweigh",
    "polish",
    "interleave",
    "torque_forms",
    "model_form",
    "fit_joint_zero",
    "fit_free_gain",
    "free_common",
    "fit_yaw_spring",
    "fit_joint_height",
    "height_beside_soil",
    "fit_com_height",
    "fit_speed_loop",
    "joint_motor_loop",
    "fit_slip_floor",
    "fit_anti_windup",
    "rejudge_form",
    "forms_beside_winner",
    "weak_adoption_stands",
    "forms_beside_leader",
    "forms_beside_rival",
    "fit_windup",
)
"""The :class:`Options` that shape what a candidate's fit finds on clean drives (the forms
searched, the fit's budget and windows). Left out: what decides names from fits (alpha,
the allowance's own use), what runs them (workers), and ``candidates`` (each entry is one
candidate's own fit)."""

_DEFAULTS = Options()


def check_options(table: FormAllowance, path: Path) -> None:
    """Refuse a table whose ``options`` name something other than a :data:`PROCEDURE`
    option, or give one a value of another type than its default's: one error naming the
    file and the key."""
    for key, value in table.options.items():
        if key not in PROCEDURE:
            raise ConfigError(
                f"{path}: options.{key}: not an option that shapes a fit; have"
                f" {', '.join(PROCEDURE)}"
            )
        want = type(getattr(_DEFAULTS, key))
        if want is float and isinstance(value, int) and not isinstance(value, bool):
            continue
        if not isinstance(value, want) or (want is int and isinstance(value, bool)):
            raise ConfigError(
                f"{path}: options.{key}: expected {want.__name__} like the default"
                f" {getattr(_DEFAULTS, key)!r}, got {value!r}"
            )


def differences(opts: Options, table: FormAllowance, rover: RoverConfig) -> list[str]:
    """How this diagnosis (``opts``, the logs' ``rover``) differs from the procedure the
    table was measured with, one line each; empty when it does not."""
    out = []
    for key in PROCEDURE:
        measured = table.options.get(key, getattr(_DEFAULTS, key))
        here = getattr(opts, key)
        if here != measured:
            out.append(f"{key}: measured with {_text(measured)}, here {_text(here)}")
    if table.rover is not None:
        parts = changed_parts(load_rover(table.rover), rover)
        if parts:
            out.append(
                f"rover: measured on logs naming {table.rover!r}; these logs' rover differs"
                f" in {', '.join(parts)}"
            )
    return out


def changed_parts(a: RoverConfig, b: RoverConfig) -> list[str]:
    """The top-level sections of two rover configurations that differ, with the changed
    fields of each (``motor.armature``), in declaration order."""
    out = []
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if x == y:
            continue
        if dataclasses.is_dataclass(x) and dataclasses.is_dataclass(y):
            inner = [
                g.name for g in dataclasses.fields(x) if getattr(x, g.name) != getattr(y, g.name)
            ]
            out += [f"{f.name}.{g}" for g in inner] or [f.name]
        else:
            out.append(f.name)
    return out


def _text(v: Any) -> str:
    if isinstance(v, bool):
        return "on" if v else "off"
    return repr(v)
