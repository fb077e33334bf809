"""The cases of issue 47's matrix on the independent generator and of its smaller studies:
which effects, at which magnitudes, from which seeds (``bench_independent.py`` runs them).

The generator's parameters against the catalogue's, the ranges and why each family of cases
exists: ``bench_independent.py``'s docstring; each function here says which cases it plans.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from bench_diagnose import INERT_ON_SOIL, RANGES, draw

from rover_env.config import load_rover
from rover_env.effects import effect_class
from rover_env.independent import motor as ind_motor
from rover_env.independent import soil as ind_soil
from rover_env.independent.effects import Effects
from rover_env.independent.model import G, RoverParams

GEN = "independent"
SEED0 = 47500
"""Case seeds of this matrix: a block of their own, never looked at while building diagnose.
Spent blocks: 47000-47064, the development block (five cases run and looked at, and one
rule changed after them: a traded signal must be 10 % worse,
:func:`rover_env.calibration.diagnosis.judge.traded_signals`); 47100-47164, run with stop
53's code (26 cases), whose clean case 47145 was then studied to build the joint zeros
and the encoder-step fix of stop 54; 47200-47264, run with those (12 cases), whose clean
case 47245 was then studied to build the yaw-spring form; 47300-47364, run with stop 54's
code (12 cases), whose loose-soil case 47308 was then studied to build the soil forms of
SOIL.md's regolith constants and the screen over the forms (stop 55); 47400-47464, run
with stop 55's code (20 cases), whose clean cases 47445 and 47446 were then studied for the
motor and spring forms (stop 56, none adopted)."""
DEV_SEED0 = 47000
EFFECTS = (
    "rolling_resistance",
    "slope",
    "rolling_radius",
    "torque_limit",
    "friction",
    "command_lag",
    "command_delay",
    "load_dependent_friction",
    "loose_soil",
)
"""The catalogue effects the independent generator implements."""
DRIVES, DURATION = 3, 50.0
"""Drives per case (the last held out) and their length (s), as the other matrix."""
PER_EFFECT = 5
SAND = (1, 3)
"""Which loose-soil singles (0-based, in seed order) are on dry sand; the others on regolith."""
N_CLEAN = 10
N_PAIRS = 6
OWN_RANGES: dict[str, tuple[str, float, float, tuple[int, ...]]] = {
    # Cuts of 5-78 %: the largest whose catalogue truth, (1 + f) 2.8 / 3.0 - 1, stays inside
    # diagnose's range (-0.8; a cut of 80 % maps to -0.813, which no fit can reach).
    "torque_limit": ("fraction", 0.05, 0.78, (-1,)),
    "loose_soil": ("k_phi", 0.3, 3.0, (1,)),  # a factor on the preset's k_phi
}
"""Ranges where the generator's parameter differs from ``bench_diagnose.RANGES``."""
OUTSIDE_RANGES: dict[str, tuple[str, float, float]] = {
    "payload": ("fraction", 0.1, 0.4),
    "toe": ("deg", 2.0, 6.0),
    "brake_drag": ("torque", 0.1, 0.5),
    "battery_sag": ("fraction", 0.3, 0.6),
}
FREE_WHEELS = (4, 5)  # 3L, 3R: a driven wheel's speed loop hides a dragging brake

ROVER = load_rover("proto_explorer")  # the rover the logs name: diagnose's model
_NOM = RoverParams()
F0_IND = _NOM.total_mass() * G / 6
RE_RATIO = (_NOM.wheel_radius[0] - F0_IND / _NOM.c_z / 3) / ROVER.geometry.wheel_radius
T_IND = ind_motor.EFF * ind_motor.GEAR * _NOM.k_t[0] * ind_motor.I_MAX
TORQUE_RATIO = T_IND / ROVER.motor.torque_limit
LDF_RANGE_CAT = next(
    p.off for p in effect_class("load_dependent_friction").params if p.name == "range"
)
LDF_RANGE_IND = Effects().friction_range


def generator_params(effect: str, seed: int, sand: bool = False) -> dict[str, float]:
    """The generator's parameters of ``effect`` for case ``seed``: log-uniform magnitude."""
    if effect in OUTSIDE_RANGES:
        param, lo, hi = OUTSIDE_RANGES[effect]
        rng = np.random.default_rng([seed, 47, len(effect)])
        out = {param: round(float(math.exp(rng.uniform(math.log(lo), math.log(hi)))), 5)}
        if effect == "brake_drag":
            out["wheel"] = float(rng.choice(FREE_WHEELS))
        return out
    if effect not in OWN_RANGES:
        return draw(effect, seed)  # the same meaning: the other matrix's range and draw
    param, lo, hi, signs = OWN_RANGES[effect]
    rng = np.random.default_rng([seed, 16, len(effect)])
    mag = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    out = {param: round(int(rng.choice(signs)) * mag, 5)}
    if effect == "loose_soil":
        out["sand"] = 1.0 if sand else 0.0
    return out


def _ldf(params: dict[str, float]) -> tuple[float, float]:
    """(catalogue fall of the same relative slope of mu at F_z0, the level change there)."""
    a = params["fall"]
    r = params.get("range", LDF_RANGE_IND)
    x = F0_IND / r
    level = 1.0 - a * math.tanh(x)
    return 2 * LDF_RANGE_CAT * F0_IND * a / math.cosh(x) ** 2 / r / level, level - 1.0


def catalogue_truth(effect: str, params: dict[str, float]) -> dict[str, float]:
    """The catalogue parameters giving the same physics in diagnose's model (docstring)."""
    if effect == "rolling_radius":
        return {"fraction": params["fraction"] * RE_RATIO}
    if effect == "torque_limit":
        return {"fraction": (1.0 + params["fraction"]) * TORQUE_RATIO - 1.0}
    if effect == "load_dependent_friction":
        return {"fall": _ldf(params)[0]}
    if effect == "loose_soil":
        preset = "dry_sand" if params.get("sand", 0.0) >= 0.5 else "regolith"
        return {"k_phi": ind_soil.PRESETS[preset].k_phi * params["k_phi"]}
    return dict(params)


STRONG: dict[str, tuple[str, float, float, tuple[int, ...]]] = {
    "command_lag": ("tau", 0.13, 0.5, (1,)),
    "command_delay": ("delay", 0.09, 0.3, (1,)),
    "slope": ("deg", 5.0, 10.0, (1,)),
    "rolling_resistance": ("c_rr", 0.065, 0.12, (1,)),
    "rolling_radius": ("fraction", 0.045, 0.1, (-1, 1)),
    "loose_soil": ("k_phi", 0.3, 3.0, (1,)),
}
"""``--strong-pairs``: the effects whose singles are named at twice the report's "named
from", each from about twice its spent median "named from" (block 52500, studies 71700-72300:
lag 0.042 s, delay 0.032 s, slope 2.4 deg, rolling resistance 0.032, radius 0.018 as the
catalogue reads it, 0.895 x the generator's) to its range's top; loose soil over its whole
range (named from about 0.3 x on every spent block). Torque cuts, friction and
load-dependent friction are left out: their "named from" lies at or beyond their ranges' top
on most builds (limits.md)."""


def strong_params(effect: str, seed: int) -> dict[str, float]:
    """``effect``'s generator parameters from :data:`STRONG`, log-uniform, for ``seed``."""
    param, lo, hi, signs = STRONG[effect]
    rng = np.random.default_rng([seed, 72800, len(effect)])
    mag = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    out = {param: round(int(rng.choice(signs)) * mag, 5)}
    if effect == "slope":
        out["heading_deg"] = round(float(rng.uniform(-180.0, 180.0)), 1)
    if effect == "loose_soil":
        out["sand"] = float(rng.integers(0, 2))
    return out


def strong_pairs(
    seed0: int, n: int, effects: list[str] | None = None, singles: int = 0
) -> list[dict[str, Any]]:
    """``n`` pairs of :data:`STRONG` effects (of ``effects``, default all), seeds from
    ``seed0`` (never a tire-only effect with loose soil), then ``singles`` single effects,
    each of ``effects`` in turn, seeds from ``seed0 + n``."""
    pool = list(STRONG) if effects is None else effects
    unknown = [e for e in pool if e not in STRONG]
    if unknown or len(pool) < (2 if n else 1):
        need = "two or more" if n else "one or more"
        raise ValueError(f"--strong-from: need {need} of {', '.join(STRONG)}; got {pool}")
    out = []
    for seed in range(seed0, seed0 + n):
        rng = np.random.default_rng([seed, 72800])
        while True:
            a, b = (str(x) for x in rng.choice(pool, 2, replace=False))
            if not ("loose_soil" in (a, b) and {a, b} & INERT_ON_SOIL):
                break
        eff = {a: strong_params(a, seed), b: strong_params(b, seed + 50_000)}
        out.append(_case("pair", eff, seed))
    for i, seed in enumerate(range(seed0 + n, seed0 + n + singles)):
        e = pool[i % len(pool)]
        out.append(_case("single", {e: strong_params(e, seed)}, seed))
    return out


def _case(kind: str, effects: dict[str, dict[str, float]], seed: int) -> dict[str, Any]:
    if kind == "outside":
        truth: Any = next(iter(effects))
    else:
        truth = {n: catalogue_truth(n, p) for n, p in effects.items()} or "none"
    case = {"kind": kind, "gen": GEN, "seed": seed, "effects": effects, "truth": truth}
    if "load_dependent_friction" in effects:
        level = _ldf(effects["load_dependent_friction"])[1]
        case["equivalent"] = {"friction": {"fraction": level}}
    return case


def _pair(seed: int) -> tuple[str, str]:
    """Two effects that both act (seeded; never a tire-only effect with loose soil)."""
    rng = np.random.default_rng([seed, 47])
    while True:
        a, b = (str(x) for x in rng.choice(EFFECTS, 2, replace=False))
        if not ("loose_soil" in (a, b) and {a, b} & INERT_ON_SOIL):
            return a, b


def cases(quick: bool = False, seed0: int = SEED0) -> list[dict[str, Any]]:
    """Every planned case, seeds counted from ``seed0``; ``quick``: a handful of them."""
    out: list[dict[str, Any]] = []
    seed = seed0
    for i in range(PER_EFFECT):
        for name in EFFECTS:
            sand = name == "loose_soil" and i in SAND
            out.append(_case("single", {name: generator_params(name, seed, sand)}, seed))
            seed += 1
    for _ in range(N_CLEAN):
        out.append(_case("clean", {}, seed))
        seed += 1
    for _ in range(N_PAIRS):
        a, b = _pair(seed)
        eff = {a: generator_params(a, seed), b: generator_params(b, seed + 50_000)}
        out.append(_case("pair", eff, seed))
        seed += 1
    for name in OUTSIDE_RANGES:
        out.append(_case("outside", {name: generator_params(name, seed)}, seed))
        seed += 1
    if quick:
        want = [
            ("single", "torque_limit"),
            ("single", "command_delay"),
            ("clean", None),
            ("single", "loose_soil"),
            ("outside", "battery_sag"),
        ]
        return [
            next(c for c in out if c["kind"] == k and (n is None or n in c["effects"]))
            for k, n in want
        ]
    return out


EFFORT_OTHERS = ("command_lag", "command_delay", "slope", "rolling_resistance", "loose_soil")
"""``--effort-cases``: the other effects beside the torque cuts and clean builds, in turn (the
timing effects move what the motors are asked for; a slope and a drag load them; soil both)."""


def effort_cases(seed0: int, n: int) -> list[dict[str, Any]]:
    """``n`` cases from ``seed0``, in fours: two torque cuts (the matrix's range, 5-78 %), a
    clean build, one :data:`EFFORT_OTHERS` effect (:data:`STRONG`'s range) in turn."""
    out = []
    for i, seed in enumerate(range(seed0, seed0 + n)):
        if i % 4 in (0, 1):
            out.append(
                _case("single", {"torque_limit": generator_params("torque_limit", seed)}, seed)
            )
        elif i % 4 == 2:
            out.append(_case("clean", {}, seed))
        else:
            e = EFFORT_OTHERS[(i // 4) % len(EFFORT_OTHERS)]
            out.append(_case("single", {e: strong_params(e, seed)}, seed))
    return out


BALANCE_OTHERS = ("rolling_resistance", "loose_soil")
"""``--balance-cases``: the effects beside the slopes and clean builds, in turn (a drag and a
soil load the wheels alike either way: the balance must not read them as a tilt)."""
BALANCE_SLOPE = (0.3, 3.0)
"""``--balance-cases``: the slopes' range (degrees, log-uniform): from under the balance's
clean tilt to above the windows' clean-fit allowance (2.4°)."""


def balance_cases(
    seed0: int, n: int, others: tuple[str, ...] = BALANCE_OTHERS
) -> list[dict[str, Any]]:
    """``n`` cases from ``seed0``, in fours: a slope (:data:`BALANCE_SLOPE`, heading drawn), a
    clean build, a slope, one of ``others`` (the matrix's range) in turn: what the force
    balance on the reported torque (stop 120) or on the wheels' slip (stop 121) meets."""
    bad = [e for e in others if (e not in RANGES and e not in OUTSIDE_RANGES) or e == "slope"]
    if not others or bad:
        raise ValueError(
            f"--balance-others: unknown effects {bad}" if bad else "--balance-others: none"
        )
    out = []
    for i, seed in enumerate(range(seed0, seed0 + n)):
        if i % 2 == 0:
            rng = np.random.default_rng([seed, 120])
            lo, hi = BALANCE_SLOPE
            deg = round(math.exp(rng.uniform(math.log(lo), math.log(hi))), 4)
            head = round(float(rng.uniform(-180.0, 180.0)), 1)
            out.append(_case("single", {"slope": {"deg": deg, "heading_deg": head}}, seed))
        elif i % 4 == 1:
            out.append(_case("clean", {}, seed))
        else:
            e = others[(i // 4) % len(others)]
            out.append(_case("single", {e: generator_params(e, seed)}, seed))
    return out


def tag(case: dict[str, Any]) -> str:
    return f"{case['kind']}_{'+'.join(case['effects']) or 'none'}_{case['seed']}"


FRONT = 0.5
"""Where in the planned order (after the quick five) the last clean, pair and outside case
falls, as a fraction of the rest: singles are spread over the whole run, the other kinds
over its first half. Why (stop 115): under a plain round-robin over (kind, effect) groups
the clean group gave one case a round, so blocks 52600 and 52800, stopped at their
registered time after 43 and 50 of the 65 cases, had 4 of the 10 clean cases and 3 of the 6
pairs. Now the first 45 cases hold every clean, pair and outside case and 25 singles."""


def planned(quick: bool, seed0: int = SEED0) -> list[dict[str, Any]]:
    """The quick cases first, then the rest interleaved so a matrix stopped early has cases
    on every acceptance line and every effect: each group (singles by effect; clean, pairs
    and outside each one group) spread evenly over its span, the singles' the whole run,
    the others' its first :data:`FRONT` (stride scheduling: the i-th of a group's n cases
    at (i + 1/2) / n of its span; ties in group order)."""
    first = cases(True, seed0)
    if quick:
        return first
    done = {tag(c) for c in first}
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for c in cases(False, seed0):
        if tag(c) not in done:
            eff = next(iter(c["effects"]), "") if c["kind"] == "single" else ""
            groups.setdefault((c["kind"], eff), []).append(c)
    keyed = []
    for g, (key, members) in enumerate(groups.items()):
        span = 1.0 if key[0] == "single" else FRONT
        keyed += [((i + 0.5) / len(members) * span, g, i, c) for i, c in enumerate(members)]
    return list(first) + [c for *_, c in sorted(keyed, key=lambda k: k[:3])]
