"""Scenario families: distributions over what makes one episode's world differ from another's.

A scenario YAML's ``family:`` section declares the training distribution of its world (the
soil and its parameters, the slope, the ripples, a patch, a rock, the ground's friction, the
command schedule, the start pose) and ``shifts:`` names held-out distributions, each
overriding some of the family's parameters with ranges that do not meet the training ones.
``load_scenario("sand-slope@train")`` plays the training distribution, ``"sand-slope@steep"``
a shift, and the bare ``"sand-slope"`` the fixed world the YAML's values describe (a family of
zero width: the paper's figures and the regression tests).

A seed draws one world: every parameter from its own generator seeded with (seed, scenario,
parameter), so the same seed gives the same world wherever it is played, a shift moves only
the parameters it overrides (its episode of a seed is the training episode's with those
parameters taken at the same quantile of the shifted range: paired), and declaring one more
parameter leaves the others' draws as they were. :class:`FamilySpec` is the schema;
:func:`draw_world`, :func:`world_terrain`, :func:`world_schedule` and :func:`envelope_terrain`
turn it into an episode and the terrain its simulator is compiled with.
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from rover_env.config import Bumps, ConfigError, TerrainConfig
from rover_env.control.base import CommandSchedule
from rover_env.tire import TireParams

__all__ = [
    "FAMILY_TIMESTEP",
    "TRAIN",
    "Dist",
    "FamilySpec",
    "check_family",
    "draw_world",
    "envelope_terrain",
    "merged",
    "world_schedule",
    "world_start",
    "world_terrain",
]

TRAIN = "train"
"""The variant name of a family's training distribution (``NAME@train``)."""

FAMILY_TIMESTEP = 0.002
"""Physics substep (s) of every family's episode (fixed scenarios keep the rover's 1 ms): every
physical check holds at 2 ms with the tolerances it has at 1 ms, and an env step costs half
the substeps (docs/timestep.md)."""


@dataclass(frozen=True)
class Dist:
    """One parameter's distribution: exactly one of ``uniform: [lo, hi]``, ``loguniform:
    [lo, hi]`` (lo > 0) or ``choice: [a, b, ...]`` (equal weights); lo == hi is a fixed value."""

    uniform: tuple[float, float] | None = None
    loguniform: tuple[float, float] | None = None
    choice: tuple[Any, ...] | None = None

    def __post_init__(self) -> None:
        given = [k for k in ("uniform", "loguniform", "choice") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ConfigError(f"give exactly one of uniform, loguniform, choice (got {given})")
        rng = self.uniform or self.loguniform
        if rng is not None:
            lo, hi = rng
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                raise ConfigError(f"range [{lo}, {hi}] must be finite with lo <= hi")
            if self.loguniform is not None and lo <= 0:
                raise ConfigError(f"loguniform needs lo > 0, got {lo}")
        elif not self.choice:
            raise ConfigError("choice needs at least one value")

    def value(self, u: float) -> Any:
        """The value at quantile ``u`` in [0, 1)."""
        if self.uniform is not None:
            lo, hi = self.uniform
            return lo + u * (hi - lo)
        if self.loguniform is not None:
            lo, hi = self.loguniform
            return math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo)))
        assert self.choice is not None
        return self.choice[min(int(u * len(self.choice)), len(self.choice) - 1)]

    def numbers(self) -> tuple[float, ...]:
        """Its numeric extremes: (lo, hi), or the numeric choices."""
        rng = self.uniform or self.loguniform
        if rng is not None:
            return rng
        return tuple(float(v) for v in self.choice or () if isinstance(v, int | float))

    def overlaps(self, other: Dist) -> bool:
        """Whether the two share a value (closed ranges, or a common choice)."""
        if self.choice is not None or other.choice is not None:
            a = set(self.choice or ()) if self.choice is not None else None
            b = set(other.choice or ()) if other.choice is not None else None
            if a is None or b is None:
                rng = (
                    (self.uniform or self.loguniform)
                    if a is None
                    else (other.uniform or other.loguniform)
                )
                vals = b if a is None else a
                assert rng is not None and vals is not None
                return any(isinstance(v, int | float) and rng[0] <= v <= rng[1] for v in vals)
            return bool(a & b)
        lo1, hi1 = self.numbers()
        lo2, hi2 = other.numbers()
        return lo1 <= hi2 and lo2 <= hi1

    def __str__(self) -> str:
        for k in ("uniform", "loguniform", "choice"):
            v = getattr(self, k)
            if v is not None:
                return f"{k} {list(v)}"
        return "?"


@dataclass(frozen=True)
class SlopeDraw:
    deg: Dist | None = None
    """Steepest-ascent angle (deg, in (0, 45))."""
    direction_deg: Dist | None = None
    """Heading of the steepest ascent (deg; 0: uphill along +x, the rover's start heading)."""


@dataclass(frozen=True)
class RippleDraw:
    """The terrain's first bump field (``bumps[0]``); its phase follows from ``start`` so the
    field begins at zero height, rising (``config.Bumps`` refuses a ledge)."""

    amplitude: Dist | None = None
    wavelength: Dist | None = None
    start: Dist | None = None
    """Where the field begins along its direction (m)."""


@dataclass(frozen=True)
class SoilDraw:
    """The ground's loose soil (or the soil patch's): a preset, then parameters replacing its
    values (``SoilParams`` fields; k_y follows k_x at the preset's k_y/k_x)."""

    preset: Dist | None = None
    c: Dist | None = None
    phi_deg: Dist | None = None
    k_c: Dist | None = None
    k_phi: Dist | None = None
    n0: Dist | None = None
    n1: Dist | None = None
    k_x: Dist | None = None


@dataclass(frozen=True)
class PatchDraw:
    """The terrain's first patch (``patches[0]``): place, size and, on a friction patch, mu
    (mu_y follows at the patch's mu_y/mu_x)."""

    x: Dist | None = None
    y: Dist | None = None
    size_x: Dist | None = None
    size_y: Dist | None = None
    mu: Dist | None = None


@dataclass(frozen=True)
class RockDraw:
    """The terrain's first obstacle (``obstacles[0]``): centre and height (it stands on z 0)."""

    x: Dist | None = None
    y: Dist | None = None
    height: Dist | None = None


@dataclass(frozen=True)
class GroundDraw:
    mu: Dist | None = None
    """The hard ground's friction mu_x (mu_y follows at the tire's Table 3 mu_y/mu_x)."""


@dataclass(frozen=True)
class CommandDraw:
    """The command schedule's rows: one draw per segment (key suffix ``.i`` where there are
    several), signs kept from the fixed schedule."""

    speed: Dist | None = None
    """|forward speed| of each segment (m/s)."""
    yaw_rate: Dist | None = None
    """|yaw rate| of each turning segment (rad/s); straight segments stay straight."""
    segment_s: Dist | None = None
    """Length of every segment but the last (s): the breakpoints move."""
    turn_sign: Dist | None = None
    """A factor on every yaw rate (e.g. ``choice: [-1, 1]``: the schedule mirrored)."""


@dataclass(frozen=True)
class StartDraw:
    """The start pose (replaces the fixed scenario's start and its jitter)."""

    x: Dist | None = None
    y: Dist | None = None
    yaw_deg: Dist | None = None


@dataclass(frozen=True)
class FamilySpec:
    """A scenario's distribution: groups of parameter distributions (None: as the fixed world)."""

    slope: SlopeDraw | None = None
    ripples: RippleDraw | None = None
    soil: SoilDraw | None = None
    patch: PatchDraw | None = None
    rock: RockDraw | None = None
    ground: GroundDraw | None = None
    commands: CommandDraw | None = None
    start: StartDraw | None = None

    def params(self) -> Iterator[tuple[str, Dist]]:
        """(``group.field``, distribution) of every declared parameter, in schema order."""
        for g in dataclasses.fields(self):
            group = getattr(self, g.name)
            if group is None:
                continue
            for f in dataclasses.fields(group):
                d = getattr(group, f.name)
                if d is not None:
                    yield f"{g.name}.{f.name}", d


_POSITIVE = {
    "ripples.amplitude", "ripples.wavelength", "patch.size_x", "patch.size_y", "patch.mu",
    "rock.height", "ground.mu", "commands.speed", "commands.yaw_rate", "commands.segment_s",
    "soil.phi_deg", "soil.k_phi", "soil.n0", "soil.k_x",
}  # fmt: skip
_NONNEG = {"soil.c", "soil.k_c", "soil.n1"}


def merged(base: FamilySpec, over: FamilySpec) -> FamilySpec:
    """``over``'s distributions on top of ``base``'s, parameter by parameter."""
    groups: dict[str, Any] = {}
    for g in dataclasses.fields(base):
        a, b = getattr(base, g.name), getattr(over, g.name)
        if a is None or b is None:
            groups[g.name] = b if a is None else a
            continue
        groups[g.name] = dataclasses.replace(
            a, **{f.name: getattr(b, f.name) for f in dataclasses.fields(b) if getattr(b, f.name)}
        )
    return FamilySpec(**groups)


def check_family(
    family: FamilySpec | None, shifts: dict[str, FamilySpec], terrain: TerrainConfig,
    commands: tuple[tuple[float, float, float], ...],
) -> None:  # fmt: skip
    """Refuse what cannot be drawn on this scenario; errors name the key (``family.x.y``)."""
    if family is None:
        if shifts:
            raise ConfigError("shifts: declared without a family")
        return
    for where, spec in (("family", family), *((f"shifts.{k}", v) for k, v in shifts.items())):
        for path, d in spec.params():
            nums = d.numbers()
            if path in _POSITIVE and any(v <= 0 for v in nums):
                raise ConfigError(f"{where}.{path}: values must be > 0, got {d}")
            if path in _NONNEG and any(v < 0 for v in nums):
                raise ConfigError(f"{where}.{path}: values must be >= 0, got {d}")
            if path == "slope.deg" and any(not 0 < v < 45 for v in nums):
                raise ConfigError(f"{where}.{path}: the slope must lie in (0, 45) deg, got {d}")
            if path != "soil.preset" and d.choice is not None and len(nums) != len(d.choice):
                raise ConfigError(f"{where}.{path}: choices must be numbers, got {d}")
        _check_applies(where, spec, terrain, commands)
    declared = dict(family.params())
    for name, shift in shifts.items():
        if name == TRAIN or not name or any(ch in name for ch in "@, "):
            raise ConfigError(f"shifts.{name}: a shift name is a word other than {TRAIN!r}")
        for path, d in shift.params():
            if path not in declared:
                raise ConfigError(
                    f"shifts.{name}.{path}: the family does not vary it; a shift overrides "
                    "parameters of the training distribution"
                )
            if d.overlaps(declared[path]):
                raise ConfigError(
                    f"shifts.{name}.{path}: {d} meets the training range {declared[path]}; "
                    "a shift lies outside it"
                )


def _check_applies(
    where: str, spec: FamilySpec, terrain: TerrainConfig,
    commands: tuple[tuple[float, float, float], ...],
) -> None:  # fmt: skip
    soils = [terrain.soil, *(p.soil for p in terrain.patches)]
    need = {
        "ripples": (bool(terrain.bumps), "the terrain has no bumps"),
        "patch": (bool(terrain.patches), "the terrain has no patches"),
        "rock": (bool(terrain.obstacles), "the terrain has no obstacles"),
        "soil": (any(soils), "the terrain has no loose soil"),
        "ground": (terrain.soil is None, "the ground is loose soil (no friction to draw)"),
    }
    for group, (ok, why) in need.items():
        if getattr(spec, group) is not None and not ok:
            raise ConfigError(f"{where}.{group}: {why}")
    r, p, c = spec.ripples, spec.patch, spec.commands
    if spec.soil is not None and spec.soil.preset is not None:
        from rover_env.soil import load_soil

        for name in spec.soil.preset.choice or ():
            try:
                load_soil(str(name))
            except ConfigError as exc:
                raise ConfigError(f"{where}.soil.preset: {exc}") from None
    if r is not None and r.start is not None and terrain.bumps[0].start < -1e8:
        raise ConfigError(f"{where}.ripples.start: bumps[0] has no start")
    if p is not None and p.mu is not None and terrain.patches[0].soil is not None:
        raise ConfigError(f"{where}.patch.mu: patches[0] is loose soil (no friction)")
    if c is not None:
        if c.yaw_rate is not None and not any(row[2] for row in commands):
            raise ConfigError(f"{where}.commands.yaw_rate: the schedule never turns")
        if c.segment_s is not None and len(commands) < 2:
            raise ConfigError(f"{where}.commands.segment_s: the schedule has one segment")


# --------------------------------------------------------------------------- drawing


def _counts(path: str, commands: tuple[tuple[float, float, float], ...]) -> list[int]:
    """Which rows a per-segment parameter draws for (``[-1]``: one draw, no suffix)."""
    n = len(commands)
    if path == "commands.speed":
        return list(range(n)) if n > 1 else [-1]
    if path == "commands.yaw_rate":
        return [i for i, r in enumerate(commands) if r[2] != 0] if n > 1 else [-1]
    if path == "commands.segment_s":
        return list(range(n - 1))
    return [-1]


def draw_world(
    spec: FamilySpec, scenario: str, seed: int, commands: tuple[tuple[float, float, float], ...]
) -> dict[str, Any]:
    """The drawn parameters of ``seed``'s world: ``group.field[.segment]`` -> value.

    Each parameter has its own stream, seeded with (seed, scenario, parameter): the draw is
    the quantile ``u`` of that stream mapped through the parameter's distribution.
    """
    world: dict[str, Any] = {}
    sc = zlib.crc32(scenario.encode())
    for path, d in spec.params():
        rows = _counts(path, commands)
        u = np.random.default_rng([int(seed), sc, zlib.crc32(path.encode())]).random(len(rows))
        for i, ui in zip(rows, u.tolist(), strict=True):
            v = d.value(ui)
            world[path if i < 0 else f"{path}.{i}"] = v if isinstance(v, str) else float(v)
    return world


def _slope(terrain: TerrainConfig) -> tuple[float, float]:
    gx, gy = (math.tan(math.radians(s)) for s in terrain.slope_deg)
    return math.degrees(math.atan(math.hypot(gx, gy))), math.degrees(math.atan2(gy, gx))


def _slope_deg(deg: float, direction: float) -> tuple[float, float]:
    if direction == 0.0:
        return (deg, 0.0)
    g = math.tan(math.radians(deg))
    d = math.radians(direction)
    return (
        math.degrees(math.atan(g * math.cos(d))),
        math.degrees(math.atan(g * math.sin(d))),
    )


def _ripples(b: Bumps, amplitude: float, wavelength: float, start: float) -> Bumps:
    phase = b.phase
    if start > -1e8:  # a zero of the sine at the start, rising: no ledge
        phase = math.remainder(-2 * math.pi * start / wavelength, 2 * math.pi)
    return dataclasses.replace(
        b, amplitude=amplitude, wavelength=wavelength, start=start, phase=phase
    )


def world_terrain(terrain: TerrainConfig, world: dict[str, Any]) -> TerrainConfig:
    """``terrain`` (the fixed world's) with the drawn ground parameters of ``world``."""
    w = world
    changes: dict[str, Any] = {}
    if "slope.deg" in w or "slope.direction_deg" in w:
        deg, direction = _slope(terrain)
        changes["slope_deg"] = _slope_deg(
            w.get("slope.deg", deg), w.get("slope.direction_deg", direction)
        )
    if any(k.startswith("ripples.") for k in w):
        b = terrain.bumps[0]
        first = _ripples(
            b,
            w.get("ripples.amplitude", b.amplitude),
            w.get("ripples.wavelength", b.wavelength),
            w.get("ripples.start", b.start),
        )
        changes["bumps"] = (first, *terrain.bumps[1:])
    if any(k.startswith("patch.") for k in w):
        p = terrain.patches[0]
        mu = {}
        if "patch.mu" in w and p.mu_x is not None and p.mu_y is not None:
            mu = {"mu_x": w["patch.mu"], "mu_y": w["patch.mu"] * p.mu_y / p.mu_x}
        first_p = dataclasses.replace(
            p,
            center=(w.get("patch.x", p.center[0]), w.get("patch.y", p.center[1])),
            size=(w.get("patch.size_x", p.size[0]), w.get("patch.size_y", p.size[1])),
            **mu,
        )
        changes["patches"] = (first_p, *terrain.patches[1:])
    if any(k.startswith("rock.") for k in w):
        ob = terrain.obstacles[0]
        h = w.get("rock.height", 2 * ob.size[2])
        rock = dataclasses.replace(
            ob,
            pos=(w.get("rock.x", ob.pos[0]), w.get("rock.y", ob.pos[1]), h / 2),
            size=(ob.size[0], ob.size[1], h / 2),
        )
        changes["obstacles"] = (rock, *terrain.obstacles[1:])
    if "ground.mu" in w:
        tire = TireParams()
        changes["mu_x"], changes["mu_y"] = w["ground.mu"], w["ground.mu"] * tire.mu_y / tire.mu_x
    out = dataclasses.replace(terrain, **changes) if changes else terrain
    return _with_soil(out, w)


def _with_soil(terrain: TerrainConfig, w: dict[str, Any]) -> TerrainConfig:
    if not any(k.startswith("soil.") for k in w):
        return terrain
    from rover_env.soil import load_soil  # numpy-only physics; loads the preset's YAML

    old = terrain.soil or next(p.soil for p in terrain.patches if p.soil)
    name = str(w.get("soil.preset", old))
    if terrain.soil is not None:
        terrain = dataclasses.replace(terrain, soil=name)
    else:
        patches = tuple(
            dataclasses.replace(p, soil=name) if p.soil == old else p for p in terrain.patches
        )
        terrain = dataclasses.replace(terrain, patches=patches)
    keys = ("c", "phi_deg", "k_c", "k_phi", "n0", "n1", "k_x")
    soil = {k: float(w[f"soil.{k}"]) for k in keys if f"soil.{k}" in w}
    if "k_x" in soil:
        base = load_soil(name)
        soil["k_y"] = soil["k_x"] * base.k_y / base.k_x
    if not soil:
        return terrain
    return dataclasses.replace(terrain, soil_changes={name: soil})


def world_schedule(
    commands: tuple[tuple[float, float, float], ...], world: dict[str, Any]
) -> CommandSchedule:
    """The fixed schedule's rows with the drawn speeds, yaw rates and segment lengths."""
    rows = [list(r) for r in commands]
    sign = float(world.get("commands.turn_sign", 1.0))
    t = rows[0][0]
    for i, r in enumerate(rows):
        suffix = "" if len(rows) == 1 else f".{i}"
        if i > 0 and f"commands.segment_s.{i - 1}" in world:
            t += world[f"commands.segment_s.{i - 1}"]
            r[0] = t
        else:
            t = r[0]
        if f"commands.speed{suffix}" in world:
            r[1] = math.copysign(world[f"commands.speed{suffix}"], r[1])
        if f"commands.yaw_rate{suffix}" in world and r[2] != 0:
            r[2] = math.copysign(world[f"commands.yaw_rate{suffix}"], r[2])
        r[2] *= sign
    return CommandSchedule.from_rows(rows)


def world_start(
    start: tuple[float, float, float], world: dict[str, Any]
) -> tuple[float, float, float]:
    """(x, y, heading rad) with the drawn start (``start``: the fixed one, heading in deg)."""
    x, y, yaw_deg = start
    return (
        float(world.get("start.x", x)),
        float(world.get("start.y", y)),
        math.radians(float(world.get("start.yaw_deg", yaw_deg))),
    )


def envelope_terrain(spec: FamilySpec, terrain: TerrainConfig) -> TerrainConfig:
    """The terrain a simulator for every world of ``spec`` is compiled with: the steepest
    slope on both axes (a relief span no draw exceeds), the tallest ripples, the patch
    covering every place it can take (the rut map's extent) and the tallest rock; every
    episode's own ground is then set without recompiling (``RoverSim.set_terrain``)."""
    w: dict[str, Any] = {}
    for path, d in spec.params():
        nums = d.numbers()
        if not nums:
            continue
        if path == "slope.deg":
            top = max(abs(v) for v in nums)
            terrain = dataclasses.replace(terrain, slope_deg=(top, top))
        elif path in ("ripples.amplitude", "rock.height"):
            w[path] = max(nums)
    if spec.patch is not None:
        p = terrain.patches[0]
        lo_hi = []
        for axis, (pos, size) in enumerate(((spec.patch.x, spec.patch.size_x),
                                            (spec.patch.y, spec.patch.size_y))):  # fmt: skip
            c = pos.numbers() if pos is not None else (p.center[axis],)
            s = max(size.numbers()) if size is not None else p.size[axis]
            lo_hi.append((min(c) - s / 2, max(c) + s / 2))
        (x0, x1), (y0, y1) = lo_hi
        w |= {"patch.x": (x0 + x1) / 2, "patch.y": (y0 + y1) / 2}
        w |= {"patch.size_x": x1 - x0, "patch.size_y": y1 - y0}
    return world_terrain(terrain, w)
