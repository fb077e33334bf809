"""Candidate effects for the diagnosis: free variables, bounds and the map to extensions.

One candidate per catalogue effect (:mod:`rover_env.effects`), with its parameters as free
variables, except where a reparameterisation fits better: the slope's (tilt, heading) pair
is fitted as the two components of the tilt vector (smooth through zero tilt, where the
heading is undefined). A switch (combined slip) has no free variable: it is tried on.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from rover_env.effects import CATALOGUE

Array = NDArray[np.float64]
Extensions = dict[str, dict[str, float]]


@dataclass(frozen=True)
class Candidate:
    name: str
    labels: tuple[str, ...]
    lo: tuple[float, ...]
    hi: tuple[float, ...]
    off: tuple[float, ...]
    ladder: tuple[tuple[float, ...], ...] | None
    """Magnitude-blind start points: a log-spaced ladder over the parameter's physical range
    [lo, hi] on each side of "off" (built from the bounds alone, never from an example
    magnitude). The fit evaluates all of them and "off", then refines around the best."""
    to_ext: Callable[[Array], Extensions]
    discrete: bool = False
    plugin_ok: bool = True
    shown: Callable[[float, float, float, str], tuple[str, float, float, float, str]] | None = None
    """For a one-variable candidate fitted in another variable than its effect's parameter:
    (x, 95 % low, 95 % high, side) -> (parameter, value, low, high, side) in the effect's
    terms (``loose_soil``: fitted as 1/k_phi, shown as k_phi). None: x is the parameter."""
    forms: tuple[tuple[str, Extensions], ...] = ()
    """Alternative forms of the effect's model, (label, extensions merged into every value):
    the fit tries each and keeps the best (:func:`rover_env.calibration.fit.fit`), e.g. the
    soil's memory of passes, which SOIL.md leaves to the implementation."""
    form: str = ""
    """The form this candidate was fixed to (:meth:`with_form`); "" when it has none."""
    form_at_off: bool = False
    """The form changes the model at "off" too (a torque limit's anti-windup form): each
    form's search then has its own "off", the form alone."""

    @property
    def k(self) -> int:
        """Number of fitted parameters (a switch counts as one model choice, and so does a
        form chosen among several)."""
        return max(1, len(self.labels)) + (1 if self.form else 0)

    def with_form(self, label: str) -> Candidate:
        """This candidate with its model fixed to form ``label`` (one of :attr:`forms`)."""
        extra = dict(self.forms)[label]
        base = self.to_ext
        off = np.asarray(self.off, dtype=float)

        def to_ext(x: Array) -> Extensions:
            # "Off" is the same model in every form (hard ground has no memory): one replay.
            if not self.form_at_off and np.array_equal(np.asarray(x, dtype=float), off):
                return base(x)
            return merge(base(x), extra)

        return replace(self, to_ext=to_ext, forms=(), form=label)

    def adopt_form(self, ext: Extensions) -> Candidate:
        """The form whose extensions ``ext`` carries (a fit's, returned by a worker that
        could not send its candidate back); self when it has no forms or none matches."""
        for label, extra in self.forms:
            if all(ext.get(e, {}).get(k) == v for e, d in extra.items() for k, v in d.items()):
                return self.with_form(label)
        return self

    def reported(self, x: Array) -> dict[str, float]:
        """Physical parameter values (the effect's own names) for fitted variables x."""
        return dict(next(iter(self.to_ext(x).values())))


LADDER_RUNGS = 5
LADDER_RATIO = 3.0
"""Rungs per side and their ratio: span/81 ... span, i.e. 1.2 % to 100 % of the range."""


def magnitude_ladder(lo: float, hi: float, off: float) -> tuple[float, ...]:
    """Log-spaced values from ``off`` toward each bound: (bound - off) / 3^k, k = 4 .. 0."""
    out: list[float] = []
    for end in (lo, hi):
        span = end - off
        if span == 0.0:
            continue
        out += [off + span / LADDER_RATIO**k for k in range(LADDER_RUNGS - 1, -1, -1)]
    return tuple(sorted(out))


def _simple(name: str) -> Candidate:
    cls = CATALOGUE[name]
    p = cls.params[0]

    def to_ext(x: Array, name: str = name, pname: str = p.name) -> Extensions:
        return {name: {pname: float(x[0])}}

    if p.discrete:

        def switch_on(
            x: Array, name: str = name, pname: str = p.name, on: float = p.hi
        ) -> Extensions:
            return {name: {pname: on}}

        return Candidate(name, (), (), (), (), None, switch_on, True, cls.plugin_ok)
    ladder = tuple((v,) for v in magnitude_ladder(p.lo, p.hi, p.off))
    return Candidate(
        name, (p.name,), (p.lo,), (p.hi,), (p.off,), ladder, to_ext, False, cls.plugin_ok
    )


def _slope() -> Candidate:
    def to_ext(x: Array) -> Extensions:
        deg = math.hypot(float(x[0]), float(x[1]))
        head = math.degrees(math.atan2(float(x[1]), float(x[0]))) if deg > 0 else 0.0
        return {"slope": {"deg": deg, "heading_deg": head}}

    # Tilts of 14/9, 14/3 and 14 degrees in four directions: blind to magnitude and heading
    # (a tilt vector's response is smooth, the local fit finds the heading in between).
    mags = [14.0 / LADDER_RATIO**k for k in (2, 1, 0)]
    ladder = tuple((m * dx, m * dy) for m in mags for dx, dy in ((1, 0), (0, 1), (-1, 0), (0, -1)))
    return Candidate(
        "slope",
        ("tilt_x_deg", "tilt_y_deg"),
        (-14.0, -14.0),
        (14.0, 14.0),
        (0.0, 0.0),
        ladder,
        to_ext,
    )


INV_K_PHI_MAX = 10.0
"""Softest soil a ``loose_soil`` fit tries: 1/k_phi 10 m^(n+2)/MN, k_phi 1e5 N/m^(n+2)
(looser than any sand of configs/soil: dune sand 1.5e6, regolith 8.1e5)."""


SOIL_SIGMA_SHORT = 0.0025
"""The short relaxation length of the soil forms (m): an eighth of the tire's 2 cm, where the
transient form is near SOIL.md's steady state (the model-form stage's shortest sigma)."""

SOIL_LAMBDAS = (0.3, 0.6, 0.9)
"""SOIL.md's exit-angle ratio lambda over the span it quotes (0.3 to 0.9; "the least
certain" constant, which each implementation chooses per preset)."""

SOIL_SETS: tuple[tuple[float, str], ...] = ((1.0, "SOIL.md's regolith"),)
"""The literature's constant sets a soil is also fitted under, by the effect's ``preset``
index (:data:`rover_env.effects.LOOSE_SOIL_PRESETS`). Wong's dry sand (preset 2) was among
them for fresh study 64000 (registered, stop 85) and is not: its dry-sand soils came within
2 x on 4 of 5, but 3 of 8 regolith soils took the dry sand's constants and came out 2.3-4.1 x
their truth (regolith soils within 2 x: 3 of 8, against 11 of 15 in study 63200)."""

SOIL_FORMS: tuple[tuple[str, Extensions], ...] = tuple(
    (
        f"{mem_label}, {sig_label}",
        {"loose_soil": {"memory": mem, "sigma": sig, "preset": 0.0, "lam": 0.0}},
    )
    for mem_label, mem in (("ruts", 1.0), ("no memory", 0.0))
    for sig_label, sig in (("tire's relaxation", 0.0), ("short relaxation", SOIL_SIGMA_SHORT))
) + tuple(
    (
        f"{name}, lambda {lam:g}, no memory",
        {"loose_soil": {"memory": 0.0, "sigma": 0.0, "preset": preset, "lam": lam}},
    )
    for preset, name in SOIL_SETS
    for lam in SOIL_LAMBDAS
)
"""The soil's designs, which SOIL.md leaves open, and the soil's other constants.

The first four: mars-sand's constants (this project's soil scenarios), with or without the
surface's memory of passes (this project's ruts and dug holes, or virgin soil under every
wheel) and with the tire's 2 cm relaxation length or a short one near the steady state. On
a straight at 2 rad/s on k_phi 2.2e6 the two memories put the rear hubs 5.8 mm apart, and
after reversing the front ones 10 mm; the second generator's soil (no memory, steady state)
is matched by the memoryless one to 0.11 mm at rest. In a reversing turn on k_phi 2.35e5
its driven wheels replay at 0.27 rad RMS with the tire's relaxation length and 0.003 with
5 mm (docs/calibration, stop 32).

Then SOIL.md's reference constants (regolith; :data:`SOIL_SETS`) at each of
:data:`SOIL_LAMBDAS`, memoryless. Why (stop 55): k_phi alone cannot carry another soil's
shear modulus K, cohesion and lambda. On the independent generator's regolith (k_phi 5.1e5)
no mars-sand soil of any k_phi or lambda replayed the training windows better than hard
ground (the joints moved with the free wheels' resistance), while rolling resistance took
the slip. k_phi's unit is N/m^(n+2):
at the same sinkage a sand of n 1.1 carries 1.9 x the k_phi of the regolith's n 1.0, so a
sand is read in the regolith's unit (study 63200's dry-sand soils: a median 0.66 x their
truth; regolith soils 1.13 x).
"""


def _loose_soil() -> Candidate:
    """Fitted as u = 1e6 / k_phi (MN^-1 m^(n+2)): u = 0 is infinitely stiff soil, next to
    hard ground ("off"), so the ladder (10/81 .. 10: k_phi 8.1e6 .. 1e5) and the local search
    move continuously away from "off". k_phi itself would put "off" (0, hard ground) beside
    the softest soils. Under each of :data:`SOIL_FORMS`; the fit keeps the better."""
    k_hi = CATALOGUE["loose_soil"].params[0].hi

    def to_ext(x: Array) -> Extensions:
        u = float(x[0])
        return {"loose_soil": {"k_phi": 0.0 if u <= 0.0 else min(1e6 / u, k_hi)}}

    def shown(x: float, lo: float, hi: float, side: str) -> tuple[str, float, float, float, str]:
        def k(u: float) -> float:
            return math.inf if u <= 0.0 else 1e6 / u

        flip = {"upper": "lower", "lower": "upper"}.get(side, side)
        return "k_phi", k(x), k(hi), k(lo), flip

    return Candidate(
        "loose_soil",
        ("inv_k_phi",),
        (0.0,),
        (INV_K_PHI_MAX,),
        (0.0,),
        tuple((v,) for v in magnitude_ladder(0.0, INV_K_PHI_MAX, 0.0)),
        to_ext,
        shown=shown,
        forms=SOIL_FORMS,
    )


TORQUE_FORMS: tuple[tuple[str, Extensions], ...] = (
    ("the configured anti-windup", {"torque_limit": {"conditional": 0.0}}),
    ("conditional anti-windup", {"torque_limit": {"conditional": 1.0}}),
)
"""A torque limit's forms (``diagnose --torque-forms``): the speed loop's anti-windup as
configured, or integrating conditionally. Why (stop 110, exploratory seeds 74038-74043 of
the independent generator, whose loop bleeds its integral by back-calculation): under the
configured clamp the replays of a 51-70 % cut fitted the limit at -0.18 or at off, and the
loss over the cut was flat to -0.7 (74040: 1.00-0.98 of nominal); under the conditional
form it fell to 0.59 at -0.7 (truth about -0.70), the form alone 0.91."""


def with_torque_forms(c: Candidate) -> Candidate:
    """``c`` searched in each of :data:`TORQUE_FORMS` when it is the torque limit."""
    if c.name != "torque_limit":
        return c
    return replace(c, forms=TORQUE_FORMS, form_at_off=True)


REPLACED_BY_SOIL = frozenset(
    {"rolling_resistance", "rolling_radius", "friction", "load_dependent_friction"}
)
"""The tire's effects, which loose soil replaces: where the ground is loose soil, the soil,
not the tire, carries the wheel and resists its rolling (SPEC's rover, both generators). In
the model the rolling resistance still acts there (hinge friction, set from the wheel's
load), so beside a named soil it can only stand for the soil's own resistance beyond the
catalogue's fixed soil constants: a form of the soil, not another effect. Forward selection
does not try these beside a loose-soil winner (:attr:`.diagnosis.state.Options.soil_alone`)."""


def catalogue(names: list[str] | None = None) -> list[Candidate]:
    """Candidates for all catalogue effects (or the named ones), in catalogue order."""
    out = []
    for n in CATALOGUE:
        if names is not None and n not in names:
            continue
        if n == "slope":
            out.append(_slope())
        elif n == "loose_soil":
            out.append(_loose_soil())
        else:
            out.append(_simple(n))
    return out


def merge(*exts: Extensions) -> Extensions:
    out: Extensions = {}
    for e in exts:
        for k, v in e.items():
            out.setdefault(k, {}).update(v)
    return out


SEPARATING_PLANS: dict[frozenset[str], tuple[str, str]] = {
    frozenset({"rolling_resistance", "slope"}): (
        "reversals",
        "drive a line forwards and backwards, pivot long, and drive the crossing line both"
        " ways: a slope helps one way and hinders the other, rolling resistance opposes both",
    ),
    frozenset({"friction", "combined_slip"}): (
        "turn-accel",
        "accelerate and brake while turning: only the friction ellipse couples the"
        " longitudinal and lateral grip",
    ),
    frozenset({"command_lag", "command_delay"}): (
        "steps",
        "command steps of many sizes and hold times: a lag responds at once and gradually,"
        " a delay not at all and then fully",
    ),
    frozenset({"rolling_radius", "friction"}): (
        "speeds",
        "slow steady runs at several speeds: a smaller radius scales travel at every load and"
        " speed, slip grows with traction demand",
    ),
    frozenset({"rolling_radius", "rolling_resistance"}): (
        "speeds",
        "slow steady runs at several speeds: radius scales all travel, resistance adds a"
        " constant slip",
    ),
    frozenset({"torque_limit", "command_lag"}): (
        "steps",
        "small and large command steps: a torque limit only slows the large ones",
    ),
    frozenset({"friction", "load_dependent_friction"}): (
        "turn-accel",
        "hard accelerations in turns move load between wheels: only load-dependent friction"
        " responds to that",
    ),
    frozenset({"slope", "loose_soil"}): (
        "reversals",
        "drive a line forwards and backwards, pivot long, and drive the crossing line both"
        " ways: a slope helps one way and hinders the other, loose soil's compaction resists"
        " both",
    ),
    frozenset({"rolling_resistance", "loose_soil"}): (
        "turn-accel",
        "hard accelerations and turns: on loose soil the slip that traction needs digs the"
        " wheels in (slip-sinkage) and tilts the bogies; rolling resistance is the same at"
        " every traction demand",
    ),
}


SHARED_RESPONSE: tuple[frozenset[str], ...] = (frozenset({"command_lag", "command_delay"}),)
"""Pairs of one-variable effects, in the same units, that move the same response by about the
sum of their values (a lag of tau and a delay of d shift the wheels' response by about
tau + d): the first fitted alone takes both shares, so the second is fitted with it, both
free (:mod:`rover_env.calibration.diagnosis.shared`)."""


def shares_response(a: str, b: str) -> bool:
    """Whether effects ``a`` and ``b`` are a :data:`SHARED_RESPONSE` pair."""
    return frozenset({a, b}) in SHARED_RESPONSE


def separating_plan(a: str, b: str) -> tuple[str, str]:
    """(drive plan, why) for a drive that separates effects a and b (rover-env drive-plan)."""
    return SEPARATING_PLANS.get(
        frozenset({a, b}),
        ("test", "a longer test drive with a new seed: more turns, reversals and speed steps"),
    )


def to_array(x: tuple[float, ...] | list[float]) -> Array:
    return np.asarray(x, dtype=np.float64)
