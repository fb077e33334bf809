"""Catalogue of named model extensions ("effects") that calibration can add to the rover.

Each effect is one small class: a name, named parameters with units, bounds and an "off"
value, and the hooks it needs. A rover configuration switches effects on through its
``extensions`` mapping (effect name -> {parameter: value}); :class:`rover_env.sim.simulator.
RoverSim` builds them with :func:`build_effects` and applies them:

* through the configuration (``apply_config``: tire friction, motor torque limit, rolling
  radius factor) and the compiled model (``apply_model``: gravity direction, wheel-hinge
  friction), which both tire backends honour unchanged;
* through the speed targets (``CommandEffect``: lag, delay), applied per physics substep;
* inside the tire layer (``TireEffect``: friction ellipse, load-dependent friction): the
  numpy layer calls their hooks; the compiled plugin repeats them from numbers in its
  configuration (:meth:`TireEffect.plugin_values`). An effect the plugin cannot run sets
  ``plugin_ok = False``, and ``RoverSim(backend="plugin")`` refuses it with a message
  naming it (``backend="auto"`` falls back to numpy).

Adding an effect: subclass :class:`Effect`, declare ``name``, ``params`` (tuple of
:class:`Param`), ``plugin_ok``, implement the hook(s), decorate with :func:`register`.

This module is numpy-only (rank 0 of the layer rule): it touches compiled models only
through their numpy arrays, so the configuration can validate extensions without importing
the simulator.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from rover_env.effects import native
from rover_env.tire import TireParams

Array = NDArray[np.float64]
GRAVITY = 9.81

__all__ = [
    "CATALOGUE",
    "CommandEffect",
    "Effect",
    "EffectError",
    "HingeEffect",
    "Param",
    "TireEffect",
    "build_effects",
    "command_rows",
    "command_sequence",
    "effect_class",
    "validate_extensions",
]


class _Dataclass(Protocol):
    __dataclass_fields__: ClassVar[dict[str, Any]]


class _Masses(Protocol):
    @property
    def total(self) -> float: ...


class _Geometry(Protocol):
    @property
    def wheel_radius(self) -> float: ...


class _Motor(_Dataclass, Protocol):
    @property
    def torque_limit(self) -> float: ...


class RoverLike(_Dataclass, Protocol):
    """What effects read of a rover configuration (:class:`rover_env.config.RoverConfig`),
    stated here so the catalogue that the configuration validates against needs no import
    of it."""

    @property
    def masses(self) -> _Masses: ...
    @property
    def geometry(self) -> _Geometry: ...
    @property
    def motor(self) -> _Motor: ...
    @property
    def tire(self) -> TireParams: ...


Cfg = TypeVar("Cfg", bound=RoverLike)


class EffectError(ValueError):
    """An extension name or parameter is unknown or out of bounds (the message names it)."""


@dataclass(frozen=True)
class Param:
    """One physical parameter of an effect."""

    name: str
    unit: str
    lo: float
    hi: float
    off: float
    doc: str
    discrete: bool = False
    """Only whole numbers in [lo, hi] are meaningful (a switch or a choice, as ``on`` or a
    soil's ``preset``): fitted by trying them, not by gradient."""
    moderate: float = 0.0
    """A typical clearly-present value, for examples and ``make-logs`` defaults only: the
    diagnosis never reads it (its fits start from a search over [lo, hi]; issue 16)."""


class Effect:
    """Base class of a model extension; instances hold validated parameter values."""

    name: ClassVar[str] = ""
    doc: ClassVar[str] = ""
    params: ClassVar[tuple[Param, ...]] = ()
    plugin_ok: ClassVar[bool] = True
    """The compiled tire plugin honours it (through configuration or model arrays)."""

    def __init__(self, values: Mapping[str, float] | None = None) -> None:
        values = dict(values or {})
        known = {p.name for p in self.params}
        unknown = sorted(set(values) - known)
        if unknown:
            raise EffectError(
                f"extensions.{self.name}: unknown parameter(s) {', '.join(unknown)}; "
                f"allowed: {', '.join(sorted(known))}"
            )
        self.values: dict[str, float] = {}
        for p in self.params:
            v = values.get(p.name, p.off)
            if isinstance(v, bool):
                v = float(v)
            if not isinstance(v, int | float) or not math.isfinite(float(v)):
                raise EffectError(f"extensions.{self.name}.{p.name}: expected a number, got {v!r}")
            v = float(v)
            if not (p.lo <= v <= p.hi):
                raise EffectError(
                    f"extensions.{self.name}.{p.name}: {v!r} outside [{p.lo}, {p.hi}] {p.unit}"
                )
            if p.discrete and v != round(v):
                raise EffectError(
                    f"extensions.{self.name}.{p.name}: a choice, must be a whole number in "
                    f"[{p.lo:g}, {p.hi:g}], got {v!r}"
                )
            self.values[p.name] = v

    def __getitem__(self, key: str) -> float:
        return self.values[key]

    @property
    def is_off(self) -> bool:
        return all(self.values[p.name] == p.off for p in self.params)

    def apply_config(self, cfg: Cfg) -> Cfg:
        """The configuration the physics is built from (default: unchanged)."""
        return cfg

    def apply_model(self, model: Any, cfg: RoverLike) -> None:
        """Change compiled-model arrays after compilation (default: nothing)."""

    def soil_changes(self) -> dict[str, float]:
        """Soil constants (``rover_env.soil.SoilParams`` fields) this effect sets on the loose
        soil over the whole ground; the simulator applies them (to the terrain's own ground
        soil, or to LOOSE_SOIL_BASE's on hard ground). Default: none."""
        return {}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.values})"


class CommandEffect(Effect):
    """Transforms the speed targets on their way to the motor controllers, per substep."""

    def reset(self, targets: Array) -> None:
        """Start in steady state at ``targets`` (a rover at rest: zeros)."""
        raise NotImplementedError

    def step(self, targets: Array, dt: float) -> Array:
        """Advance one substep with ``targets`` commanded; return what the motors get."""
        raise NotImplementedError

    def sequence(self, rows: Array, dt: float) -> Array:
        """(n, 4) what :meth:`step` returns on each of ``rows`` (one row of targets per
        substep), in order: the same numbers; an effect may compute them at once (a replay
        holds each logged command for 10-20 substeps and drives a window's rows between two
        read-outs in one call)."""
        r = np.asarray(rows, dtype=np.float64)
        return np.array([self.step(u, dt) for u in r]).reshape(len(r), -1)

    def prime(self, t: Array, cmd: Array, t_now: float, dt: float) -> None:
        """Set the internal state as if commands ``cmd[k]`` (held from ``t[k]``) had run.

        Used to start a replay window mid-drive with the effect's memory filled.
        """
        raise NotImplementedError


def command_rows(effects: Sequence[CommandEffect], targets: Array, dt: float, n: int) -> Array:
    """(n, 4) what the motors get over ``n`` substeps with ``targets`` held, through command
    effects in the simulator's order (each takes the last one's output, substep by substep):
    :func:`command_sequence` over the held rows."""
    return command_sequence(effects, np.tile(np.asarray(targets, dtype=np.float64), (n, 1)), dt)


def command_sequence(effects: Sequence[CommandEffect], rows: Array, dt: float) -> Array:
    """(n, 4) what the motors get when the targets are ``rows[j]`` on substep j, through
    command effects in the simulator's order: :func:`command_rows` over runs of held rows
    gives the same numbers (issue 47: a replay's per-row calls were a third of a lag's
    replay)."""
    out = np.asarray(rows, dtype=np.float64)
    for e in effects:
        out = e.sequence(out, dt)
    return out


class TireEffect(Effect):
    """Hooks inside the tire layer: the numpy layer calls them; the compiled plugin runs the
    same arithmetic from :meth:`plugin_values` (a new tire effect needs C there too)."""

    plugin_ok: ClassVar[bool] = False

    def plugin_values(self, cfg: RoverLike) -> dict[str, float]:
        """The plugin's ``effects`` numbers this effect sets (``rover_env.sim.fast``)."""
        raise NotImplementedError(f"{self.name}: no compiled implementation")

    def friction(self, mu_x: Array, mu_y: Array, F_z: Array) -> tuple[Array, Array]:
        """Friction coefficients for this substep (default: unchanged)."""
        return mu_x, mu_y

    def forces(
        self, F_x: Array, F_y: Array, F_z: Array, mu_x: Array, mu_y: Array
    ) -> tuple[Array, Array]:
        """Post-process the contact forces (default: unchanged)."""
        return F_x, F_y


class HingeEffect(Effect):
    """Dry friction of the wheel hinges set every substep from each wheel's tire state.

    ``RoverSim`` steps substep by substep when one is on (both tire backends: the numpy
    layer's state, or the compiled plugin's committed truth) and sets each wheel hinge's
    ``frictionloss`` to its static value plus :meth:`hinge_friction`. The value computed from
    substep k's load acts from substep k + 1 (the constraint rows of a step are built
    before its tire forces), identically on both backends.
    """

    def hinge_friction(self, F_z: Array, delta: Array, radius: float) -> Array:
        """Friction moment (N m) of each wheel hinge for loads F_z and deflections delta."""
        raise NotImplementedError


CATALOGUE: dict[str, type[Effect]] = {}


def register(cls: type[Effect]) -> type[Effect]:
    if not cls.name or cls.name in CATALOGUE:
        raise ValueError(f"effect name {cls.name!r} empty or registered twice")
    CATALOGUE[cls.name] = cls
    return cls


def effect_class(name: str) -> type[Effect]:
    try:
        return CATALOGUE[name]
    except KeyError:
        raise EffectError(
            f"extensions: unknown model extension {name!r}; known: {', '.join(sorted(CATALOGUE))}"
        ) from None


def _static_wheel_load(cfg: RoverLike) -> float:
    return cfg.masses.total * GRAVITY / 6


# --------------------------------------------------------------------------- the catalogue


@register
class RollingResistance(HingeEffect):
    """Rolling resistance: a resisting force c_rr * F_z at steady rolling, F_z the wheel's own load.

    The textbook definition (Wong, *Theory of Ground Vehicles*): the ground pushes back on a
    rolling wheel with c_rr times its normal load. It acts as dry friction of each wheel
    hinge (MuJoCo ``frictionloss``, so a wheel at rest sticks instead of chattering) whose
    moment c_rr * F_z * (d - delta) is set every substep from that wheel's actual load F_z
    and deflection delta: the tire force acts at the contact point, d - delta below the
    hub, so at steady rolling the ground's resisting force is c_rr * F_z exactly (rig test).
    Free wheels slow down; driven wheels need more torque and slip more. The moment is the
    ground's (the normal force's forward offset), not the bearing's: ``RoverSim`` gives the
    wheel's carrier back its share of the hinge's friction torque, so segment 3's pitch reads
    it as another implementation of this definition does (rig test). Until issue 16 the
    moment was c_rr * F_z0 * r_e with the static load F_z0 and the rolling radius r_e as
    lever, which made the resisting force about 1.3 c_rr F_z0 whatever the wheel carried.
    """

    name = "rolling_resistance"
    params = (Param("c_rr", "-", 0.0, 0.3, 0.0, "rolling resistance coefficient", moderate=0.05),)

    def hinge_friction(self, F_z: Array, delta: Array, radius: float) -> Array:
        # F_z >= 0 (eq. 17) and is 0 whenever the wheel is off the ground (delta < 0).
        return np.asarray(self.values["c_rr"] * F_z * (radius - delta), dtype=np.float64)


@register
class Slope(Effect):
    """Constant ground tilt: gravity rotated so the ground rises ``deg`` toward ``heading_deg``.

    ``heading_deg`` is measured in the world (log) frame, counter-clockwise from +x. The
    terrain stays as configured; only the direction of gravity changes.
    """

    name = "slope"
    params = (
        Param("deg", "deg", -20.0, 20.0, 0.0, "tilt of the ground", moderate=5.0),
        Param("heading_deg", "deg", -180.0, 180.0, 0.0, "direction in which the ground rises"),
    )

    def gravity(self) -> Array:
        th, ps = math.radians(self["deg"]), math.radians(self["heading_deg"])
        return np.array(
            [
                -GRAVITY * math.sin(th) * math.cos(ps),
                -GRAVITY * math.sin(th) * math.sin(ps),
                -GRAVITY * math.cos(th),
            ]
        )

    def apply_model(self, model: Any, cfg: RoverLike) -> None:
        if self["deg"] != 0.0:
            model.opt.gravity[:] = self.gravity()


@register
class RollingRadius(Effect):
    """Effective rolling radius changed by ``fraction`` at static load (deflection, sinkage).

    The loss grows with load like the deflection: k_re (r_e = d - k_re delta) becomes
    k_re - fraction * d / delta_0, delta_0 the static deflection, so at static load r_e
    changes by fraction * d (-0.08: 8 % of the wheel radius less travel per turn).
    """

    name = "rolling_radius"
    params = (
        Param("fraction", "-", -0.2, 0.1, 0.0, "change of r_e at static load", moderate=-0.08),
    )

    def apply_config(self, cfg: Cfg) -> Cfg:
        f = self["fraction"]
        if f == 0.0:
            return cfg
        delta0 = _static_wheel_load(cfg) / cfg.tire.C_z
        k = cfg.tire.k_re - f * cfg.geometry.wheel_radius / delta0
        if not 0.0 <= k <= 1.0:
            raise EffectError(
                f"extensions.rolling_radius.fraction: {f!r} needs k_re = {k:.3f}, outside [0, 1]"
            )
        return dataclasses.replace(cfg, tire=dataclasses.replace(cfg.tire, k_re=k))


@register
class TorqueLimit(Effect):
    """Motor torque limit (driver current limit) changed by ``fraction``; ``conditional`` 1:
    the speed loop integrates conditionally (``motor.anti_windup``), the form under which
    ``diagnose --torque-forms`` may fit the limit (a clamped integral catches up after the
    limit lets go, which hides it: exploratory seeds 74038 and 74040, stop 110)."""

    name = "torque_limit"
    params = (
        Param("fraction", "-", -0.8, 1.0, 0.0, "change of motor.torque_limit", moderate=-0.5),
        Param("conditional", "-", 0.0, 1.0, 0.0, "1: conditional anti-windup", discrete=True),
    )

    def apply_config(self, cfg: Cfg) -> Cfg:
        f = self["fraction"]
        motor = cfg.motor
        if self["conditional"] >= 0.5:
            motor = dataclasses.replace(motor, anti_windup="conditional")
        if f != 0.0:
            motor = dataclasses.replace(motor, torque_limit=motor.torque_limit * (1 + f))
        return cfg if motor is cfg.motor else dataclasses.replace(cfg, motor=motor)


@register
class Friction(Effect):
    """Tire-ground friction level (mu_x and mu_y of the tire) changed by ``fraction``.

    Scales the tire's Table 3 values, which the default ground uses; terrain friction
    patches with their own mu keep them.
    """

    name = "friction"
    params = (Param("fraction", "-", -0.7, 1.0, 0.0, "change of mu_x and mu_y", moderate=-0.3),)

    def apply_config(self, cfg: Cfg) -> Cfg:
        f = self["fraction"]
        if f == 0.0:
            return cfg
        t = cfg.tire
        return dataclasses.replace(
            cfg, tire=dataclasses.replace(t, mu_x=t.mu_x * (1 + f), mu_y=t.mu_y * (1 + f))
        )


NATIVE_ROWS = 32
"""Rows from which a lag's recursion runs compiled (:mod:`.native`): a ctypes call costs
about 30 us, a row on Python floats about 0.5 us (a hinge effect's 10-substep stretches)."""


@register
class CommandLag(CommandEffect):
    """First-order lag of the speed targets (motor driver input filter): tau dx/dt = u - x."""

    name = "command_lag"
    params = (Param("tau", "s", 0.0, 2.0, 0.0, "time constant", moderate=0.3),)

    def __init__(self, values: Mapping[str, float] | None = None) -> None:
        super().__init__(values)
        self.x = np.zeros(4)

    def reset(self, targets: Array) -> None:
        self.x = np.array(targets, dtype=np.float64)

    def step(self, targets: Array, dt: float) -> Array:
        tau = self["tau"]
        if tau == 0.0:
            self.x = np.array(targets, dtype=np.float64)
        else:
            self.x = targets + (self.x - targets) * math.exp(-dt / tau)
        return self.x

    def sequence(self, rows: Array, dt: float) -> Array:
        r = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
        n = len(r)
        tau = self["tau"]
        if tau <= 0.0:
            if n:
                self.x = r[-1].copy()
            return r.copy()
        a = math.exp(-dt / tau)
        # compiled: the same numbers, to the bit (a call's set-up outweighs a few rows)
        done = native.lag_sequence(r, a, self.x) if n >= NATIVE_ROWS else None
        if done is not None:
            out, self.x = done
            return out
        # step()'s recursion on Python floats: the same IEEE operations as numpy's
        # elementwise ones (bit-identical), without numpy's per-call cost on 4 numbers
        cols = []
        for ucol, xi in zip(r.T.tolist(), self.x.tolist(), strict=True):
            col = []
            for ui in ucol:
                xi = ui + (xi - ui) * a
                col.append(xi)
            cols.append(col)
        # C order, as step()'s rows stacked: a caller's mean over rows must sum them in the
        # same order (a transposed view summed pairwise and moved the last bit)
        out = np.ascontiguousarray(np.array(cols, dtype=np.float64).T.reshape(n, 4))
        if n:
            self.x = out[-1].copy()
        return out

    def prime(self, t: Array, cmd: Array, t_now: float, dt: float) -> None:
        tau = self["tau"]
        ta = np.asarray(t, dtype=np.float64)
        # the samples sent before now (t is increasing), each held to the next or to now
        sent = ta < t_now - 1e-12
        k_now = len(ta) if sent.all() else int(np.argmin(sent))
        ends = np.minimum(np.append(ta[1 : k_now + 1], t_now)[:k_now], t_now)
        steps = np.round((ends - ta[:k_now]) / dt).astype(np.int64).tolist()
        decay = {  # one exp per distinct hold, as math.exp gave it per sample
            n: math.exp(-n * dt / tau) if tau > 0 else 0.0 for n in set(steps)
        }
        f = [decay[n] for n in steps]
        rows = np.asarray(cmd, dtype=np.float64).reshape(-1, 4)[:k_now]
        primed = native.lag_prime(rows, np.array(f, dtype=np.float64).reshape(-1))
        if primed is not None:
            self.x = primed
            return
        cc = rows.T.tolist()
        x = []
        for col in cc:  # Python floats: numpy's elementwise results, to the bit
            xi = 0.0
            for c, fk in zip(col, f, strict=True):
                xi = c + (xi - c) * fk
            x.append(xi)
        self.x = np.array(x, dtype=np.float64)


@register
class CommandDelay(CommandEffect):
    """Pure delay of the speed targets (communication, driver latency)."""

    name = "command_delay"
    params = (Param("delay", "s", 0.0, 1.0, 0.0, "dead time", moderate=0.15),)

    def __init__(self, values: Mapping[str, float] | None = None) -> None:
        super().__init__(values)
        self._hist: deque[Array] = deque()
        self._fill = np.zeros(4)

    def reset(self, targets: Array) -> None:
        self._hist = deque()
        self._fill = np.array(targets, dtype=np.float64)

    def step(self, targets: Array, dt: float) -> Array:
        n = round(self["delay"] / dt)
        if n == 0:
            return np.array(targets, dtype=np.float64)
        self._hist.append(np.array(targets, dtype=np.float64))
        if len(self._hist) > n:
            return self._hist.popleft()
        return self._fill

    def sequence(self, rows: Array, dt: float) -> Array:
        r = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
        lag = round(self["delay"] / dt)
        if lag == 0:
            return r.copy()
        # step()'s delay line at once: each substep appends its row and, once more than
        # ``lag`` are held, hands out the oldest; until then the fill
        n, h = len(r), len(self._hist)
        line = np.concatenate([np.array(list(self._hist)).reshape(h, 4), r])
        filled = min(n, max(0, lag - h))
        out = np.empty((n, 4))
        out[:filled] = self._fill
        out[filled:] = line[: n - filled]
        self._hist = deque(line[n - filled :])
        return out

    def prime(self, t: Array, cmd: Array, t_now: float, dt: float) -> None:
        n = round(self["delay"] / dt)
        self._fill = np.zeros(4)
        self._hist = deque()
        for j in range(n, 0, -1):
            tj = t_now - j * dt
            k = int(np.searchsorted(t, tj + 1e-9, side="right")) - 1
            self._hist.append(np.zeros(4) if k < 0 else np.array(cmd[k], dtype=np.float64))


@register
class CombinedSlip(TireEffect):
    """Friction ellipse (Gim and Nikravesh part 2): longitudinal and lateral forces share grip.

    With ``on`` = 1 the force pair is scaled down so (F_x / mu_x F_z)^2 + (F_y / mu_y F_z)^2
    <= 1; off, each direction saturates independently (the paper's eqs. 13, 14).
    """

    name = "combined_slip"
    params = (
        Param("on", "-", 0.0, 1.0, 0.0, "friction ellipse switch", discrete=True, moderate=1),
    )
    plugin_ok = True

    def plugin_values(self, cfg: RoverLike) -> dict[str, float]:
        return {"combined_on": self["on"]}

    def forces(
        self, F_x: Array, F_y: Array, F_z: Array, mu_x: Array, mu_y: Array
    ) -> tuple[Array, Array]:
        if self["on"] == 0.0:
            return F_x, F_y
        fz = np.maximum(F_z, 1e-12)
        n = np.hypot(F_x / (mu_x * fz), F_y / (mu_y * fz))
        s = 1.0 / np.maximum(n, 1.0)
        return F_x * s, F_y * s


@register
class LoadDependentFriction(TireEffect):
    """Friction falling with load: mu * (1 - fall * clip((F_z - F_z0) / (2 range F_z0), -1/2, 1/2)).

    F_z0 = m g / 6 the static wheel load. mu falls by ``fall`` (a fraction of the nominal mu)
    across the operating range of wheel loads F_z0 (1 - range) .. F_z0 (1 + range), is
    nominal at static load and constant beyond the range. ``range`` 0.1 is this rover's
    operating range on flat ground: the driven wheels' loads stay within about ±10 % of
    F_z0 (1st-99th percentile 23.7-29.8 N around 26.8 N over a 50 s ``make-logs`` test
    drive), so "falling 30 % across the operating range" is fall 0.3 with range 0.1. (Until
    this version the range was fixed at ±50 %, which made fall 0.3 a ~5 % change over the
    loads the rover actually sees.)
    """

    name = "load_dependent_friction"
    params = (
        Param("fall", "-", 0.0, 0.8, 0.0, "relative fall of mu across the range", moderate=0.3),
        Param("range", "-", 0.01, 1.0, 0.1, "half-width of the load range, fraction of F_z0"),
    )
    plugin_ok = True

    def __init__(self, values: Mapping[str, float] | None = None) -> None:
        super().__init__(values)
        self.fz0 = 1.0
        self.span = 1.0

    @property
    def is_off(self) -> bool:
        return self["fall"] == 0.0

    def _loads(self, cfg: RoverLike) -> tuple[float, float]:
        fz0 = _static_wheel_load(cfg)
        return fz0, 2.0 * self["range"] * fz0

    def apply_model(self, model: Any, cfg: RoverLike) -> None:
        self.fz0, self.span = self._loads(cfg)

    def plugin_values(self, cfg: RoverLike) -> dict[str, float]:
        fz0, span = self._loads(cfg)
        return {"load_fall": self["fall"], "load_fz0": fz0, "load_span": span}

    def friction(self, mu_x: Array, mu_y: Array, F_z: Array) -> tuple[Array, Array]:
        a = self["fall"]
        if a == 0.0:
            return mu_x, mu_y
        k = 1.0 - a * np.clip((F_z - self.fz0) / self.span, -0.5, 0.5)
        return mu_x * k, mu_y * k


LOOSE_SOIL_PRESETS = ("mars-sand", "regolith", "dry-sand")
"""The soil presets whose other constants (c, k_c, n, K, lambda, ...) a ``loose_soil`` effect
on hard ground takes, by its ``preset`` index: the sand of the soil scenarios
(configs/soil/mars-sand.yaml), SOIL.md's reference set (configs/soil/regolith.yaml) and
Wong's dry sand in SOIL.md's form (configs/soil/dry-sand.yaml)."""

LOOSE_SOIL_BASE = LOOSE_SOIL_PRESETS[0]
"""The default preset (``preset`` 0)."""


@register
class LooseSoil(Effect):
    """The ground is loose soil, or softer than modelled: Bekker's k_phi (and phi, n0).

    ``k_phi`` is the frictional modulus of Bekker's pressure-sinkage law p = (k_c / b +
    k_phi) z^n (N/m^(n+2); Wong, *Theory of Ground Vehicles*), ``phi_deg`` the soil's
    internal friction angle of Mohr-Coulomb's shear strength c + p tan(phi) and ``n0`` the
    sinkage exponent at zero slip (n = n0 + n1 |s|). ``k_phi`` 0 is off: hard ground, the Gim
    tire. On hard ground the other soil constants are those of the preset ``preset`` names
    (:data:`LOOSE_SOIL_PRESETS`: 0 ``mars-sand``, 1 ``regolith``, SOIL.md's reference set,
    2 ``dry-sand``, Wong's dry sand);
    on a terrain that already has loose soil over the ground, its constants. ``phi_deg``,
    ``n0`` and ``lam`` (SOIL.md's exit-angle ratio, which it calls the least certain
    constant) replace the soil's own where they are not 0 ("softer than modelled"). Soil
    patches keep their own soil.

    Only ``k_phi`` is fitted by ``diagnose``, as u = 1e6 / k_phi (a log-spaced ladder over
    u's range, as every magnitude; ``calibration.candidates``); ``phi_deg`` and ``n0`` are
    make-logs' and a rover file's to set. ``memory`` is the soil's dynamic design, which
    SOIL.md leaves open (:attr:`rover_env.soil.SoilParams.memory`): 1 this project's ruts and
    dug holes, 0 a surface that forgets; ``sigma`` the relaxation length of the slip on the
    soil (0: the tire's). ``diagnose`` fits k_phi under each of their combinations
    (``calibration.candidates.SOIL_FORMS``) and keeps the best (a model form of the soil,
    counted as one parameter). Why k_phi:
    at the rover's wheel it decides the static sinkage, which the rolling resistance of
    compaction and the slip the drive needs follow (the rig test checks Bekker's law).
    """

    name = "loose_soil"
    params = (
        Param(
            "k_phi",
            "N/m^(n+2)",
            0.0,
            1.0e9,
            0.0,
            "Bekker's frictional modulus; 0: hard ground",
            moderate=2.2591e6,
        ),
        Param("phi_deg", "deg", 0.0, 45.0, 0.0, "internal friction angle; 0: the soil's own"),
        Param("n0", "-", 0.0, 1.5, 0.0, "sinkage exponent at zero slip; 0: the soil's own"),
        Param(
            "preset",
            "-",
            0.0,
            2.0,
            0.0,
            "the other soil constants on hard ground: 0 mars-sand, 1 regolith (SOIL.md's set), "
            "2 dry-sand (Wong's dry sand)",
            discrete=True,
        ),
        Param(
            "lam",
            "-",
            0.0,
            1.0,
            0.0,
            "SOIL.md's exit-angle ratio lambda (theta_r = -lambda theta_f); 0: the soil's own",
        ),
        Param(
            "memory",
            "-",
            0.0,
            1.0,
            1.0,
            "the surface's memory of passes: 1 ruts and dug holes, 0 virgin soil under every wheel",
        ),
        Param(
            "sigma",
            "m",
            0.0,
            0.1,
            0.0,
            "relaxation length of the slip on the soil; 0: the tire's",
        ),
    )

    @property
    def is_off(self) -> bool:
        return self["k_phi"] == 0.0

    def soil_changes(self) -> dict[str, float]:
        if self.is_off:
            return {}
        out = {k: self[k] for k in ("k_phi", "memory", "sigma", "preset")}
        # 0 is "the soil's own" for these (none of them is 0 in a real soil).
        out.update({k: self[k] for k in ("phi_deg", "n0", "lam") if self[k] != 0.0})
        return out


# --------------------------------------------------------------------------- helpers


def build_effects(extensions: Mapping[str, Mapping[str, float]]) -> list[Effect]:
    """Effect instances in catalogue order (so application order never depends on YAML order)."""
    if not isinstance(extensions, Mapping):
        raise EffectError(f"extensions: expected a mapping, got {extensions!r}")
    for name, values in extensions.items():
        effect_class(name)
        if values is not None and not isinstance(values, Mapping):
            raise EffectError(
                f"extensions.{name}: expected a mapping of parameters, got {values!r}"
            )
    return [cls(extensions[n] or {}) for n, cls in CATALOGUE.items() if n in extensions]


def validate_extensions(extensions: Mapping[str, Mapping[str, float]]) -> None:
    """Raise :class:`EffectError` naming the key if any entry is unknown or out of bounds."""
    build_effects(extensions)


def plugin_refusals(extensions: Mapping[str, Mapping[str, float]]) -> list[str]:
    """Names of switched-on extensions that the compiled plugin cannot run.

    Unknown names count as refused (a configuration that bypassed validation must not be
    run silently without them).
    """
    unknown = sorted(str(n) for n in extensions if n not in CATALOGUE)
    if unknown:
        return unknown
    return [e.name for e in build_effects(extensions) if not e.plugin_ok and not e.is_off]
