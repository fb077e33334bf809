"""The clean-fit allowance: the model's form seen through each effect's fit (issue 47).

On clean drives of another implementation of the rover (nothing injected, its build within
tolerances) every effect's fit still finds something: a delay of about 16 ms, a slope of
a degree, a torque cut. That is the model's form mismatch seen through the effect, a bias
b; on drives that hold the effect the fit finds about truth + b, and an interval that holds
only noise and the replay's own bias misses the truth whenever b is wider than it. The
allowance is b's spread, its 5 % and 95 % quantiles (``low``, ``high``) over clean cases,
and a named effect's interval for the truth becomes [lo - high, hi - low] (a tilt, which a
spurious tilt adds to in any direction: [lo - high, hi + high], at least level). It widens
intervals only: what is named is decided before it.

A soil's stiffness is the exception (:data:`FACTOR`): no clean drive holds soil, and k_phi
spans decades, so its entry is the spread of fitted over true k_phi on named soils of
another implementation, a factor: the interval for the truth is [lo / high, hi / low].
It never withdraws a name (:func:`rover_env.calibration.diagnosis.judge.allowance_reaches_off`):
whether soil is there at all is the windows' question.

An effect that is there can be fitted off the other way (``below``, ``above``): a command lag
of 0.4455 s fitted 0.432 [0.380, 0.443] (spent case 52505), where clean drives only ever
add lag. So each entry may also carry how far the truth sat beyond a right name's own
interval on named singles of another implementation (95 % quantiles, ``benchmarks/
form_allowance.py --named``), and the pad on each side is the larger of the two.

The shipped table (``configs/calibration/form_allowance.yaml``) is measured by
``benchmarks/form_allowance.py --write`` on the independent generator's clean cases; it is
that implementation's mismatch with this model, the only one measured, not a real rover's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rover_env.config import ConfigError, load_config, resolve_path
from rover_env.effects import CATALOGUE

SHIPPED = "form_allowance"
"""The shipped table's name in ``configs/calibration/``."""

FACTOR = frozenset({"loose_soil"})
"""Effects whose allowance is a factor on the fitted value (low and high: quantiles of fitted
over true), measured on named cases against their truth (``benchmarks/form_allowance.py
--soil``). Why (stop 81): on 87 named soils of spent blocks 47600-52200 the fitted k_phi sat
0.57-3.4 x the truth (5-95 %) while the stored intervals covered it in 42; widened, they
held it in 26 of 26 named soils of fresh study 60800."""


@dataclass(frozen=True)
class Bias:
    """An effect's clean-fit spread on its first parameter (a slope's tilt in degrees)."""

    low: float
    """5 % quantile of the clean fits."""
    high: float
    """95 % quantile of the clean fits."""
    cases: int
    """Clean diagnoses it was measured on."""
    below: float = 0.0
    """95 % quantile of how far below a right name's own 95 % interval (before widening) the
    truth sat, over the named singles it was measured on (0: never, or not measured)."""
    above: float = 0.0
    """The same above the interval."""
    named: int = 0
    """Named singles ``below`` and ``above`` were measured on (0: not measured)."""
    reach: float = 0.0
    """95 % quantile of how far beyond the fit's value, away from "off", the truth sat on
    the same named singles (0: never, or not measured): the far end's floor
    (:func:`reach_floor`)."""

    def __post_init__(self) -> None:
        if not self.low <= self.high:
            raise ConfigError(f"low {self.low!r} is above high {self.high!r}")
        if self.cases < 1:
            raise ConfigError(f"cases must be at least 1, got {self.cases!r}")
        for k in ("below", "above", "named", "reach"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"{k} must be a finite number >= 0, got {v!r}")


@dataclass(frozen=True)
class FormAllowance:
    """Per effect, the :class:`Bias` its fit carries on clean drives."""

    effects: dict[str, Bias]
    options: dict[str, Any] = field(default_factory=dict)
    """The diagnosis options the clean fits were made with, where they differed from the
    defaults (:data:`rover_env.calibration.diagnosis.procedure.PROCEDURE`): a diagnosis run
    otherwise is judged by another procedure's spread, and its report says so."""
    rover: str | None = None
    """The rover configuration the measured logs named (None: not recorded)."""

    def pad(self, effect: str) -> tuple[float, float] | None:
        """How far below and above a fitted interval the truth may sit, or None."""
        b = self.effects.get(effect)
        if b is None:
            return None
        if effect in FACTOR:
            return b.high, b.low
        if effect == "slope":
            clean = max(0.0, b.high), max(0.0, b.high)
        else:
            clean = max(0.0, b.high), max(0.0, -b.low)
        return max(clean[0], b.below), max(clean[1], b.above)

    def reach(self, effect: str) -> float:
        """How far beyond the fit, away from "off", the truth may sit (:attr:`Bias.reach`;
        0 for a :data:`FACTOR` effect or one without an entry)."""
        b = self.effects.get(effect)
        return 0.0 if b is None or effect in FACTOR else b.reach

    def edge(self, effect: str, side: str) -> float:
        """The magnitude on ``side`` of "off" ("+", "-"; a slope: "deg") below which a
        fit's interval, however narrow, widened by the allowance still reaches "off": what
        a clean build of another implementation fits there. 0 for a :data:`FACTOR` effect
        (its allowance never withdraws a name) or one without an entry."""
        pad = self.pad(effect)
        if pad is None or effect in FACTOR:
            return 0.0
        return pad[1] if side == "-" else pad[0]


def naming_bar(
    effect: str, detectable: dict[str, float], allowance: FormAllowance | None
) -> dict[str, float]:
    """Per side of "off", the smallest magnitude a diagnosis can name on these logs: the
    larger of the detection limit (what pays the training BIC's price against what the
    model leaves) and the allowance's edge (:meth:`FormAllowance.edge`). The noise
    threshold counts the sensors only; this counts the model's form too, so an effect
    under it is not named whatever the sensors (issue 47: "3.7 x the report's own
    threshold" was not named because that threshold left the form out). Sides without a
    detection limit are left out: what pays the price there was not measured."""
    return {
        side: max(d, allowance.edge(effect, side) if allowance else 0.0)
        for side, d in detectable.items()
        if side in ("+", "-", "deg") and math.isfinite(d)
    }


def widen(
    effect: str, lo: float, hi: float, pad: tuple[float, float], bounds: tuple[float, float]
) -> tuple[float, float]:
    """``[lo, hi]`` widened by ``pad`` (below, above) within ``bounds``; a tilt's magnitude
    is bounded by level alone, a :data:`FACTOR` effect's value divided by the factors."""
    if effect in FACTOR:
        return lo / pad[0], hi / pad[1]
    floor, ceil = (0.0, math.inf) if effect == "slope" else bounds
    return max(floor, lo - pad[0]), min(ceil, hi + pad[1])


def reach_floor(
    value: float, lo: float, hi: float, reach: float, off: float, bounds: tuple[float, float]
) -> tuple[float, float]:
    """``[lo, hi]`` with its end away from ``off`` at least ``reach`` beyond ``value``,
    within ``bounds``; the end towards "off" is untouched, so nothing that decides a name
    moves.

    Why (stop 101): a named lag's fit sits short of its truth by an amount set by the
    build, not by the lag (-0.2 to 14 ms on four builds at 0.05-0.6 s), so a pad measured
    beyond each name's own interval stays too narrow where the interval is narrow (case
    71923: 0.2084 s fitted 0.1974 [0.1495, 0.2057]); a floor measured from the fit is not."""
    if reach <= 0.0 or not math.isfinite(value):
        return lo, hi
    if value >= off:
        return lo, max(hi, min(bounds[1], value + reach))
    return min(lo, max(bounds[0], value - reach)), hi


def load_allowance(name_or_path: str | Path = SHIPPED) -> FormAllowance:
    """The table by shipped name (``configs/calibration/NAME.yaml``) or path; an effect
    outside the catalogue is an error naming the file and the key."""
    a = load_config(FormAllowance, name_or_path, "calibration", drop=("description", "source"))
    unknown = sorted(set(a.effects) - set(CATALOGUE))
    if unknown:
        path = resolve_path(name_or_path, "calibration")
        raise ConfigError(
            f"{path}: effects.{unknown[0]}: not a catalogue effect; have {', '.join(sorted(CATALOGUE))}"
        )
    for name in sorted(FACTOR & set(a.effects)):
        if a.effects[name].low <= 0.0:
            path = resolve_path(name_or_path, "calibration")
            raise ConfigError(
                f"{path}: effects.{name}.low: a factor (fitted over true), must be above 0,"
                f" got {a.effects[name].low!r}"
            )
    return a
