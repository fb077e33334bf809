"""Named benchmark scenarios: a ground, a start pose, a fixed command schedule, per-seed jitter,
and the family of worlds around them.

Each lives in ``configs/scenarios/<name>.yaml`` (keys: :class:`ScenarioConfig`). The ground is
a shipped terrain name, a terrain YAML path, or a terrain mapping written inline. A seed
turns a scenario into one :class:`Episode`: the start pose and the friction of the ground's
patches are jittered by a generator seeded with (seed, scenario name), so every controller
sees the same episode for the same seed and the scenarios' draws are independent.

``NAME@train`` and ``NAME@SHIFT`` (:func:`load_scenario`) are the scenario's family: a seed
draws a whole world from the ``family:`` distribution or one of its ``shifts:``
(:mod:`rover_env.tasks.families`); the bare name stays the fixed world.
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rover_env.config import (
    ConfigError,
    TerrainConfig,
    configs_dir,
    from_dict,
    load_config,
    load_terrain,
)
from rover_env.control.base import CommandSchedule
from rover_env.tasks.families import (
    FAMILY_TIMESTEP,
    TRAIN,
    FamilySpec,
    check_family,
    draw_world,
    envelope_terrain,
    merged,
    world_schedule,
    world_start,
    world_terrain,
)

__all__ = [
    "Episode",
    "Jitter",
    "ScenarioConfig",
    "StartPose",
    "load_scenario",
    "scenario_names",
]


@dataclass(frozen=True)
class StartPose:
    """Front axle at rest at (x, y), heading ``yaw_deg`` (``RoverSim.reset``)."""

    x: float = 0.0
    y: float = 0.0
    yaw_deg: float = 0.0


@dataclass(frozen=True)
class Jitter:
    """Half-widths of the uniform per-seed perturbations."""

    x: float = 0.0
    y: float = 0.0
    yaw_deg: float = 0.0
    mu_scale: float = 0.0
    """Every friction patch's mu_x and mu_y scaled by one factor in 1 +- mu_scale."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"jitter.{f.name} must be a finite number >= 0, got {v!r}")
        if self.mu_scale >= 1:
            raise ConfigError("jitter.mu_scale must be below 1")


@dataclass(frozen=True)
class Episode:
    """One seed of a scenario: everything needed to run it on the env or the bare sim."""

    scenario: str
    seed: int
    terrain: TerrainConfig
    start: tuple[float, float, float]
    """x, y (m), heading (rad)."""
    schedule: CommandSchedule
    duration: float
    goal_fraction: float
    world: dict[str, Any] = field(default_factory=dict)
    """The drawn parameters of a family's episode (``group.field`` -> value; empty for a
    fixed scenario): ``info["world"]`` and the benchmark's ``world.*`` columns."""
    envelope: TerrainConfig | None = None
    """The terrain to compile the simulator with so that every world of the family fits
    (None: this episode's own terrain)."""
    timestep: float | None = None
    """Physics substep (s) the episode is played at (None: the rover configuration's; a
    family's worlds: :data:`~rover_env.tasks.families.FAMILY_TIMESTEP`)."""

    def env_kwargs(self) -> dict[str, Any]:
        """What an env playing this episode is built with: its ground and physics step."""
        out: dict[str, Any] = {"terrain": self.envelope or self.terrain}
        if self.timestep is not None:
            out["timestep"] = self.timestep
        return out


@dataclass(frozen=True)
class ScenarioConfig:
    name: str
    description: str
    terrain: Any
    """Shipped terrain name, YAML path, or an inline terrain mapping."""
    commands: tuple[tuple[float, float, float], ...]
    """Rows [t (s), forward speed (m/s), yaw rate (rad/s)]: piecewise constant from t on."""
    duration: float = 20.0
    start: StartPose = field(default_factory=StartPose)
    jitter: Jitter = field(default_factory=Jitter)
    goal_fraction: float = 0.5
    """Success needs this share of the commanded path length (see ``episode_metrics``)."""
    slip_wasted: bool = False
    """True where the benchmark expects slip control to pay (tuning set, acceptance)."""
    family: FamilySpec | None = None
    """The training distribution of the world (``NAME@train``); None: a fixed scenario."""
    shifts: dict[str, FamilySpec] = field(default_factory=dict)
    """Held-out distributions (``NAME@SHIFT``), each overriding some of the family's
    parameters with ranges outside the training ones."""
    variant: str | None = None
    """Which distribution episodes draw from: None the fixed world, ``train`` the family,
    or a shift's name (``load_scenario("NAME@VARIANT")`` sets it)."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ConfigError(f"scenario {self.name}: duration must be > 0")
        if not 0 <= self.goal_fraction <= 1:
            raise ConfigError(f"scenario {self.name}: goal_fraction must lie in [0, 1]")
        CommandSchedule.from_rows(self.commands)  # validates
        if "@" in self.name:
            raise ConfigError(f"scenario {self.name}: a name holds no '@' (it selects a family)")
        if self.variant is not None and self.variant not in self.variants:
            raise ConfigError(
                f"variant: scenario {self.name} has no distribution {self.variant!r}; "
                f"have {self.variants or 'none (no family)'}"
            )

    @property
    def variants(self) -> list[str]:
        """The distributions it declares: ``train`` and its shifts (none without a family)."""
        return [TRAIN, *self.shifts] if self.family is not None else []

    @property
    def key(self) -> str:
        """Its name in the benchmark: ``NAME`` (the fixed world) or ``NAME@VARIANT``."""
        return self.name if self.variant is None else f"{self.name}@{self.variant}"

    @property
    def distribution(self) -> FamilySpec | None:
        """The distribution its episodes draw from (None: the fixed world)."""
        if self.variant is None or self.family is None:
            return None
        if self.variant == TRAIN:
            return self.family
        return merged(self.family, self.shifts[self.variant])

    def check_family(self) -> None:
        """Refuse a family or shift that cannot be drawn on this ground (keys named)."""
        check_family(self.family, self.shifts, self.terrain_config(), self.commands)

    @property
    def schedule(self) -> CommandSchedule:
        return CommandSchedule.from_rows(self.commands)

    def terrain_config(self, base: Path | None = None) -> TerrainConfig:
        t = self.terrain
        if isinstance(t, dict):
            return from_dict(TerrainConfig, t, "terrain")
        if isinstance(t, str):
            p = Path(t)
            if base is not None and not p.is_absolute() and (base / p).is_file():
                return load_terrain(base / p)
            return load_terrain(t)
        raise ConfigError(f"scenario {self.name}: terrain must be a name, path or mapping")

    def episode(self, seed: int, duration: float | None = None) -> Episode:
        """The jittered episode of ``seed`` (``duration`` overrides the scenario's length);
        for a family, the world ``seed`` draws."""
        spec = self.distribution
        if spec is not None:
            return self._drawn(spec, seed, duration)
        rng = np.random.default_rng([int(seed), zlib.crc32(self.name.encode())])
        j, s = self.jitter, self.start
        dx, dy, dyaw, dmu = rng.uniform(-1.0, 1.0, 4)
        terrain = self.terrain_config()
        if j.mu_scale > 0 and terrain.patches:
            k = 1.0 + j.mu_scale * float(dmu)
            patches = tuple(
                p
                if p.mu_x is None or p.mu_y is None  # a soil patch: no friction to scale
                else dataclasses.replace(p, mu_x=p.mu_x * k, mu_y=p.mu_y * k)
                for p in terrain.patches
            )
            terrain = dataclasses.replace(terrain, patches=patches)
        return Episode(
            scenario=self.name,
            seed=int(seed),
            terrain=terrain,
            start=(
                s.x + j.x * float(dx),
                s.y + j.y * float(dy),
                math.radians(s.yaw_deg + j.yaw_deg * float(dyaw)),
            ),
            schedule=self.schedule,
            duration=self.duration if duration is None else float(duration),
            goal_fraction=self.goal_fraction,
        )

    def _drawn(self, spec: FamilySpec, seed: int, duration: float | None) -> Episode:
        world = draw_world(spec, self.name, seed, self.commands)
        base = self.terrain_config()
        s = self.start
        return Episode(
            scenario=self.key,
            seed=int(seed),
            terrain=world_terrain(base, world),
            start=world_start((s.x, s.y, s.yaw_deg), world),
            schedule=world_schedule(self.commands, world),
            duration=self.duration if duration is None else float(duration),
            goal_fraction=self.goal_fraction,
            world=world,
            envelope=envelope_terrain(spec, base),
            timestep=FAMILY_TIMESTEP,
        )


def _scenario_dir() -> Path:
    return configs_dir() / "scenarios"


def scenario_names() -> list[str]:
    """Shipped scenarios, in the benchmark's order (file order by name)."""
    return sorted(p.stem for p in _scenario_dir().glob("*.yaml"))


def load_scenario(name_or_path: str | Path) -> ScenarioConfig:
    """A shipped scenario by name or a scenario YAML path; ``NAME@VARIANT`` (a path too)
    selects its family's training distribution (``@train``) or a shift."""
    text = str(name_or_path)
    variant: str | None = None
    if "@" in text:
        text, variant = text.rsplit("@", 1)
    p = Path(text)
    if p.suffix not in (".yaml", ".yml"):
        p = _scenario_dir() / f"{text}.yaml"
        if not p.is_file():
            raise ConfigError(f"no shipped scenario named {text!r}; have {scenario_names()}")
    cfg = load_config(ScenarioConfig, p, "scenarios")
    try:
        cfg.terrain_config()  # fail early on a bad ground
        cfg.check_family()
        if variant is not None:
            cfg = dataclasses.replace(cfg, variant=variant)
        spec = cfg.distribution
        if spec is not None:  # the envelope must build (a ledge, a bad soil value)
            envelope_terrain(spec, cfg.terrain_config())
    except ConfigError as exc:
        raise ConfigError(f"{p}: {exc}") from None
    return cfg
