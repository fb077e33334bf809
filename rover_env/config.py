"""Typed, validated configuration: the single source of every physical number.

YAML files in ``configs/`` are loaded into frozen dataclasses. Unknown keys, wrong types,
out-of-range values and missing files raise :class:`ConfigError` naming the file and the
dotted key, so a typo never silently falls back to a default.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, TypeVar

import yaml

from rover_env.effects import EffectError, validate_extensions
from rover_env.tire import TireParams

WHEELS: tuple[str, ...] = ("1L", "1R", "2L", "2R", "3L", "3R")
DRIVEN_WHEELS: tuple[str, ...] = ("1L", "1R", "2L", "2R")
FREE_WHEELS: tuple[str, ...] = ("3L", "3R")
JOINTS: tuple[str, ...] = ("theta_1", "theta_2", "theta_3", "theta_4", "theta_5")
SEGMENTS: tuple[str, ...] = ("seg1", "seg2", "seg3")


AntiWindup = Literal["clamp", "conditional", "back_calculation"]
ANTI_WINDUP_FORMS: tuple[AntiWindup, ...] = ("clamp", "conditional", "back_calculation")
FITTED_ANTI_WINDUP_FORMS: tuple[AntiWindup, ...] = ("clamp", "conditional")
"""The forms ``diagnose`` chooses between (the first of :data:`ANTI_WINDUP_FORMS`, in the same
order): back-calculation carries a tracking time the drives barely separate from the gains,
the voltage line and the rotor (stop 68), so it is configured from a drive's datasheet, not
fitted."""
"""The speed loop's anti-windup forms (``MotorSpec.anti_windup``)."""


class ConfigError(ValueError):
    """A configuration value is missing, unknown or out of range."""


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(f"{name} must be a finite number > 0, got {value!r}")


def _nonneg(name: str, value: float) -> None:
    if not (math.isfinite(value) and value >= 0):
        raise ConfigError(f"{name} must be a finite number >= 0, got {value!r}")


@dataclass(frozen=True)
class Geometry:
    """Lengths in metres; x forward, y left, z up (SPEC §1)."""

    wheel_radius: float = 0.085
    """Nominal (unloaded) wheel radius d. SPEC §1: Table 2's "170" read as a diameter."""
    wheel_width: float = 0.05
    half_track: float = 0.225
    """r of Table 1: lateral distance from a segment's centre line to each wheel's mid-plane."""
    axle_spacing: float = 0.36
    """Distance between adjacent axles (segment 1 to 2, 2 to 3)."""
    chassis_length: float = 0.26
    chassis_width: float = 0.30
    chassis_height: float = 0.16
    chassis_lift: float = 0.01
    """Height of the chassis floor above the wheel hubs."""
    joint_height: float = 0.0
    """Height of the joints between segments above the axle line. SPEC gives none; it sets
    the lever of the pull one segment passes to the next, so how a climb or an acceleration
    pitches the rear segment (theta_4)."""
    com_height: float | None = None
    """Height of each segment body's centre of mass (without its wheels) above its axle.
    None: that of the chassis box and the motors on the axle line (0.078-0.09 m here). SPEC
    gives none; it sets how much load a slope or an acceleration moves between the wheels."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if f.name not in ("joint_height", "com_height"):
                _positive(f"geometry.{f.name}", getattr(self, f.name))
        reach = self.wheel_radius + self.chassis_lift + self.chassis_height
        for name in ("joint_height", "com_height"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and -self.wheel_radius < v < reach):
                raise ConfigError(
                    f"geometry.{name} must lie between the ground (-wheel_radius,"
                    f" {-self.wheel_radius:g}) and the chassis top ({reach:g}), got {v!r}"
                )
        if self.chassis_width / 2 > self.half_track - self.wheel_width / 2:
            raise ConfigError("geometry.chassis_width overlaps the wheels (half_track too small)")
        if self.axle_spacing <= 2 * self.wheel_radius:
            raise ConfigError("geometry.axle_spacing must exceed the wheel diameter")

    @property
    def joint_offset(self) -> float:
        """Coupling joints sit midway between axles."""
        return self.axle_spacing / 2


@dataclass(frozen=True)
class Masses:
    """Table 2: 16.4 kg in all, 4 motors of 0.3 kg, 2 batteries of 0.7 kg."""

    wheel: float = 0.35
    motor: float = 0.3
    battery: float = 0.7
    chassis: tuple[float, float, float] = (4.0, 3.7, 4.0)
    """Structure and electronics of segments 1..3 (everything but wheels, motors, batteries)."""
    battery_segments: tuple[int, ...] = (2, 3)

    def __post_init__(self) -> None:
        _positive("masses.wheel", self.wheel)
        _positive("masses.motor", self.motor)
        _positive("masses.battery", self.battery)
        if len(self.chassis) != 3:
            raise ConfigError("masses.chassis needs one value per segment (3)")
        for i, m in enumerate(self.chassis):
            _positive(f"masses.chassis[{i}]", m)
        for s in self.battery_segments:
            if s not in (1, 2, 3):
                raise ConfigError(f"masses.battery_segments entries must be 1, 2 or 3, got {s}")

    def segment_mass(self, seg: int) -> float:
        """Segment body mass without its two wheels."""
        m = self.chassis[seg - 1] + self.battery * self.battery_segments.count(seg)
        if seg in (1, 2):
            m += 2 * self.motor
        return m

    @property
    def total(self) -> float:
        return sum(self.segment_mass(s) for s in (1, 2, 3)) + 6 * self.wheel


@dataclass(frozen=True)
class JointSpec:
    """A passive joint: leaf spring (stiffness) where the paper has one, plus damping."""

    stiffness: float = 0.0
    damping: float = 0.5
    limit: float = 0.8
    """Mechanical stop (rad), symmetric."""
    zero: float = 0.0
    """The angle sensor's reading at the joint's true zero (rad): a potentiometer's zero is
    set by hand on a real rover and is off by a fraction of a degree to a few degrees.
    Changes what the sensor reads (:meth:`rover_env.sim.simulator.RoverSim.sensors`, the
    calibration replay), never the physics; ``diagnose`` fits it (the ``joint_zero`` form)."""

    def __post_init__(self) -> None:
        _nonneg("joint.stiffness", self.stiffness)
        _nonneg("joint.damping", self.damping)
        _positive("joint.limit", self.limit)
        if not abs(self.zero) < self.limit:
            raise ConfigError(
                f"joint.zero must lie inside the stops (+-{self.limit}), got {self.zero}"
            )


def _default_joints() -> dict[str, JointSpec]:
    return {
        "theta_1": JointSpec(stiffness=0.0, damping=0.5, limit=0.6),
        "theta_2": JointSpec(stiffness=10.0, damping=1.0, limit=0.8),
        "theta_3": JointSpec(stiffness=0.0, damping=0.5, limit=0.6),
        "theta_4": JointSpec(stiffness=2.5, damping=0.5, limit=0.8),
        "theta_5": JointSpec(stiffness=10.0, damping=1.0, limit=0.8),
    }


@dataclass(frozen=True)
class MotorSpec:
    """Geared DC motor with an on-board speed controller, all referred to the wheel shaft."""

    voltage: float = 24.0
    stall_torque: float = 21.0
    """N m at the wheel: a 20 W-class motor, 150:1 gearhead at 70 % efficiency."""
    no_load_speed: float = 6.7
    """rad/s at the wheel: about 9600 rpm / 150."""
    torque_limit: float = 3.0
    """Continuous torque (N m at the wheel) the driver's current limit allows."""
    armature: float = 0.025
    """Rotor inertia reflected through the gearhead, N^2 J_rotor (kg m^2)."""
    speed_gain: float = 2.0
    """Proportional gain of the speed loop, N m per rad/s."""
    integral_gain: float = 40.0
    """Integral gain of the speed loop (N m per rad of accumulated angle error)."""
    max_angle_error: float = 0.5
    """Anti-windup: the integrated angle setpoint stays within this of the wheel (rad)."""
    max_wheel_speed: float = 4.0
    """Largest speed target accepted (rad/s): actions and controllers are scaled to it."""
    tracking_ratio: float = 1.0
    """The back-calculation anti-windup's tracking time over the loop's integral time
    ``speed_gain / integral_gain`` (``anti_windup: back_calculation`` only; 1: the textbook's
    T_t = T_i). The smaller, the further the integral is bled while the motor's voltage
    saturates, and the more a wheel that saturated on a step settles from below."""
    anti_windup: AntiWindup = "clamp"
    """The speed loop's anti-windup form. ``"clamp"``: the integral (setpoint minus wheel
    angle) is only bounded by ``max_angle_error``, so it can hold ``integral_gain`` x bound
    (20 N m), far beyond the torque the motor can give. ``"conditional"``: conditional
    integration, the textbook's: the integral is also frozen while the motor's output
    saturates outward (the torque limit or the DC motor's voltage/back-EMF line, and the
    error drives it further out), i.e. the setpoint then advances by the wheel's own motion
    instead of the target (``max_angle_error`` stays an outer bound).
    ``"back_calculation"``: a voltage-mode drive's: the loop sees only its voltage saturation
    (the DC motor's line ``stall_torque (1 -+ w / no_load_speed)``), the current limit
    (``torque_limit``) clips the torque in the driver, out of its sight; while the raw torque
    is beyond the line the integral is bled by the excess at the tracking time
    ``tracking_ratio x speed_gain / integral_gain`` (Astrom and Hagglund's back-calculation;
    :func:`rover_env.sim.speed_loop.advance_setpoints`). On a hard step the integral then
    ends near zero and the wheel settles from below, as the independent generator's does
    (``benchmarks/step_response.py``). Not on the GPU backend."""

    def __post_init__(self) -> None:
        if self.anti_windup not in ANTI_WINDUP_FORMS:
            raise ConfigError(
                f"motor.anti_windup must be one of {', '.join(map(repr, ANTI_WINDUP_FORMS))},"
                f" got {self.anti_windup!r}"
            )
        for f in dataclasses.fields(self):
            if f.name != "anti_windup":
                _positive(f"motor.{f.name}", getattr(self, f.name))
        if self.max_wheel_speed > self.no_load_speed:
            raise ConfigError("motor.max_wheel_speed exceeds the motor's no_load_speed")


@dataclass(frozen=True)
class SimSpec:
    timestep: float = 0.001
    """Physics substep (s); the tire layer runs on every one. 1 ms shipped; docs/timestep.md
    has every physical check at 1, 2 and 5 ms and the stability bounds behind the limit."""

    def __post_init__(self) -> None:
        _positive("sim.timestep", self.timestep)
        if self.timestep > 0.005:
            raise ConfigError("sim.timestep above 5 ms is unstable with the tire layer")


@dataclass(frozen=True)
class RoverConfig:
    """Everything physical about the rover; terrain is configured separately."""

    name: str = "proto_explorer"
    geometry: Geometry = field(default_factory=Geometry)
    masses: Masses = field(default_factory=Masses)
    joints: dict[str, JointSpec] = field(default_factory=_default_joints)
    motor: MotorSpec = field(default_factory=MotorSpec)
    tire: TireParams = field(default_factory=TireParams)
    sim: SimSpec = field(default_factory=SimSpec)
    extensions: dict[str, dict[str, float]] = field(default_factory=dict)
    """Model extensions (calibration adds these): extension name -> its parameters.

    Names and parameters come from the catalogue in :mod:`rover_env.effects` (e.g.
    ``{"rolling_resistance": {"c_rr": 0.05}}``); unknown names, unknown parameters and values
    outside their bounds raise ConfigError naming the key. Missing parameters take their
    "off" value.
    """

    def __post_init__(self) -> None:
        if set(self.joints) != set(JOINTS):
            raise ConfigError(
                f"joints must name exactly {', '.join(JOINTS)}; got {sorted(self.joints)}"
            )
        if self.extensions:
            try:
                validate_extensions(self.extensions)
            except EffectError as exc:
                raise ConfigError(str(exc)) from None


@dataclass(frozen=True)
class FrictionPatch:
    """A region of ground with its own friction (e.g. snow, rock) or loose soil.

    Either ``mu_x`` and ``mu_y`` (hard ground: the Gim tire layer with these friction
    coefficients) or ``soil`` (a soil preset name or YAML path, ``configs/soil/``: the
    terramechanics contact of :mod:`rover_env.soil`).
    """

    name: str
    center: tuple[float, float]
    size: tuple[float, float]
    """Full extent in x and y (m) of an axis-aligned rectangle."""
    mu_x: float | None = None
    mu_y: float | None = None
    soil: str | None = None

    def __post_init__(self) -> None:
        if self.soil is None:
            if self.mu_x is None or self.mu_y is None:
                raise ConfigError(f"patch {self.name}: give mu_x and mu_y, or soil")
            _positive(f"friction patch {self.name}: mu_x", self.mu_x)
            _positive(f"friction patch {self.name}: mu_y", self.mu_y)
        elif self.mu_x is not None or self.mu_y is not None:
            raise ConfigError(f"patch {self.name}: a soil patch takes no mu_x/mu_y")
        for v in self.size:
            _positive(f"friction patch {self.name}: size", v)


BUMP_STEP_TOL = 1e-4
"""Largest height step (m) a bump field may start with: a tenth of a millimetre."""


@dataclass(frozen=True)
class Bumps:
    """Sinusoidal bumps: amplitude (m) times sin(2 pi s / wavelength + phase) along a direction."""

    amplitude: float
    wavelength: float
    direction_deg: float = 0.0
    phase: float = 0.0
    start: float = -1e9
    """Bumps begin at this distance along their direction (flat before it). The sine's
    argument counts from the origin, not from ``start``, so ``phase`` must put a zero at
    ``start``: a bump field beginning mid-wave is a ledge (refused below)."""

    def __post_init__(self) -> None:
        _nonneg("bumps.amplitude", self.amplitude)
        _positive("bumps.wavelength", self.wavelength)
        if self.start > -1e8:  # a start inside any arena: the ground must be continuous there
            arg = 2 * math.pi * self.start / self.wavelength + self.phase
            step = self.amplitude * math.sin(arg)
            if abs(step) > BUMP_STEP_TOL:
                fix = math.remainder(-2 * math.pi * self.start / self.wavelength, 2 * math.pi)
                raise ConfigError(
                    f"bumps: amplitude {self.amplitude:g} m, wavelength {self.wavelength:g} m "
                    f"starting at {self.start:g} m with phase {self.phase:g} begins with a "
                    f"{1000 * step:+.1f} mm ledge (the sine counts from the origin); set "
                    f"phase: {fix:.10f} to start at zero height, rising"
                )


@dataclass(frozen=True)
class Roughness:
    """Smooth random ground: a seeded sum of Fourier modes."""

    rms: float = 0.0
    correlation_length: float = 0.5
    modes: int = 24
    seed: int = 0

    def __post_init__(self) -> None:
        _nonneg("roughness.rms", self.rms)
        _positive("roughness.correlation_length", self.correlation_length)
        if self.modes < 1:
            raise ConfigError("roughness.modes must be >= 1")


@dataclass(frozen=True)
class Obstacle:
    """A rigid box (rock, step) that wheels and chassis hit through MuJoCo contacts."""

    name: str
    pos: tuple[float, float, float]
    size: tuple[float, float, float]
    """Half-sizes (m)."""
    yaw_deg: float = 0.0

    def __post_init__(self) -> None:
        for v in self.size:
            _positive(f"obstacle {self.name}: size", v)


@dataclass(frozen=True)
class TerrainConfig:
    name: str = "flat"
    size: tuple[float, float] = (40.0, 40.0)
    """Arena extent in x and y (m), centred on the origin; leaving it ends an episode."""
    resolution: float = 0.05
    """Heightfield grid spacing (m) of the MuJoCo mesh used for rendering and chassis contacts."""
    slope_deg: tuple[float, float] = (0.0, 0.0)
    """Ground rises by tan(slope) per metre along +x and +y."""
    bumps: tuple[Bumps, ...] = ()
    roughness: Roughness = field(default_factory=Roughness)
    mu_x: float | None = None
    """Default ground friction; None takes the tire's Table 3 values."""
    mu_y: float | None = None
    patches: tuple[FrictionPatch, ...] = ()
    obstacles: tuple[Obstacle, ...] = ()
    soil: str | None = None
    """Loose soil over the whole ground (a preset name or YAML path); None: hard ground."""
    soil_changes: dict[str, dict[str, float]] = field(default_factory=dict)
    """Changed parameters of the soils named here (soil name or path as written in ``soil``
    or a patch -> SoilParams field -> value), e.g. a scenario family's drawn soil; the soil
    is loaded and these replace its values (checked by ``SoilParams`` when it is built)."""

    def __post_init__(self) -> None:
        for v in self.size:
            _positive("terrain.size", v)
        named = {self.soil, *(p.soil for p in self.patches)} - {None}
        for soil, changes in self.soil_changes.items():
            if soil not in named:
                raise ConfigError(
                    f"terrain.soil_changes.{soil}: no soil of that name on this ground "
                    f"(have {sorted(str(n) for n in named)})"
                )
            for k, v in changes.items():
                if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                    raise ConfigError(
                        f"terrain.soil_changes.{soil}.{k}: expected a finite number, got {v!r}"
                    )
        _positive("terrain.resolution", self.resolution)
        for s in self.slope_deg:
            if not -45.0 < s < 45.0:
                raise ConfigError(f"terrain.slope_deg must be within (-45, 45), got {s}")
        for m in (self.mu_x, self.mu_y):
            if m is not None:
                _positive("terrain.mu", m)

    @property
    def is_flat(self) -> bool:
        return (
            self.slope_deg == (0.0, 0.0)
            and all(b.amplitude == 0 for b in self.bumps)
            and self.roughness.rms == 0
        )


# --------------------------------------------------------------------------- loading

T = TypeVar("T")


def _convert(tp: Any, value: Any, where: str) -> Any:
    """Convert a YAML value to the annotated type, naming ``where`` on failure."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _convert(inner[0], value, where)
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        return from_dict(tp, value, where)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{where}: expected a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(f"{where}: expected {len(args)} values, got {len(value)}")
        return tuple(
            _convert(a, v, f"{where}[{i}]")
            for i, (a, v) in enumerate(zip(args, value, strict=True))
        )
    if origin is dict:
        if not isinstance(value, Mapping):
            raise ConfigError(f"{where}: expected a mapping, got {value!r}")
        return {str(k): _convert(args[1], v, f"{where}.{k}") for k, v in value.items()}
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    return value


def from_dict(cls: type[T], data: Any, where: str = "") -> T:
    """Build dataclass ``cls`` from a mapping; unknown keys and bad values raise ConfigError."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where or cls.__name__}: expected a mapping, got {data!r}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - names)
    if unknown:
        raise ConfigError(
            f"{where or cls.__name__}: unknown key(s) {', '.join(map(str, unknown))}; "
            f"allowed: {', '.join(sorted(names))}"
        )
    kwargs = {k: _convert(hints[k], v, f"{where}.{k}" if where else k) for k, v in data.items()}
    if cls is RoverConfig and "joints" in kwargs:
        kwargs["joints"] = {**_default_joints(), **kwargs["joints"]}
    try:
        return cls(**kwargs)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}" if where else str(exc)) from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where or cls.__name__}: {exc}") from None


def to_dict(obj: Any) -> Any:
    """Plain YAML-able form of a config object (tuples become lists)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, dict):
        return {k: to_dict(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_dict(v) for v in obj]
    return obj


def _shipped(folder: str) -> Path:
    """A top-level repository folder, or its copy inside an installed wheel.

    A source checkout (and an editable install) reads ``configs/`` and ``assets/`` in place;
    a wheel carries them as the ``rover_env.configs`` and ``rover_env.assets`` packages.
    """
    pkg = Path(__file__).resolve().parent
    for here in (pkg / folder, pkg.parent / folder):
        if here.is_dir():
            return here
    raise ConfigError(f"shipped folder {folder!r} not found beside {pkg}; is rover_env installed?")


def configs_dir() -> Path:
    """The shipped configuration folder (``configs/`` in the repository)."""
    return _shipped("configs")


def assets_dir() -> Path:
    """The shipped MJCF folder (``assets/`` in the repository)."""
    return _shipped("assets")


def resolve_path(name_or_path: str | Path, kind: str) -> Path:
    """A YAML path as given, or the shipped ``configs/<kind>/<name>.yaml``."""
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml") or p.exists():
        if not p.is_file():
            raise ConfigError(f"{kind} configuration file not found: {p}")
        return p
    shipped = configs_dir() / kind / f"{name_or_path}.yaml"
    if not shipped.is_file():
        names = sorted(q.stem for q in (configs_dir() / kind).glob("*.yaml"))
        raise ConfigError(f"no shipped {kind} configuration named {name_or_path!r}; have {names}")
    return shipped


BASE_KEY = "base"
"""A YAML file's top-level ``base: FILE`` names the file it states differences from."""


def base_path(name: Any, child: Path) -> Path:
    """``base:`` is a path relative to the file that names it, or a file in ``configs/``."""
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{child}: {BASE_KEY}: expected a file name, got {name!r}")
    here = child.parent / name
    if here.is_file():
        return here
    shipped = configs_dir() / (name if Path(name).suffix else f"{name}.yaml")
    if shipped.is_file():
        return shipped
    raise ConfigError(f"{child}: {BASE_KEY}: {name!r} is neither beside it nor in configs/")


class Replace(dict[Any, Any]):
    """A mapping tagged ``!replace``: it replaces its base's mapping whole (keys and order)
    instead of merging into it, e.g. a scenario mix whose order sets which one is drawn."""


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader plus the ``!replace`` tag, refusing merge-key lists."""

    def flatten_mapping(self, node: yaml.MappingNode) -> None:
        # ``<<: [*a, *b]``: PyYAML 6.0.3 lets the first map win a key both have, 6.0.4 the
        # last, so one file trained two different recipes (stop 52, configs/ppo.yaml). One
        # ``<<: *a`` per mapping, with the other keys written out, means the same everywhere.
        for key, value in node.value:
            if key.tag == "tag:yaml.org,2002:merge" and isinstance(value, yaml.SequenceNode):
                raise yaml.constructor.ConstructorError(
                    "while constructing a mapping",
                    node.start_mark,
                    "a merge key takes one mapping (<<: *a), not a list: PyYAML versions"
                    " disagree on which of the list's maps wins a key they share",
                    key.start_mark,
                )
        super().flatten_mapping(node)


def _construct_replace(loader: yaml.SafeLoader, node: yaml.Node) -> Replace:
    if not isinstance(node, yaml.MappingNode):
        raise yaml.constructor.ConstructorError(
            None, None, "!replace takes a mapping", node.start_mark
        )
    return Replace(loader.construct_mapping(node, deep=True))


_Loader.add_constructor("!replace", _construct_replace)


def merge(base: Any, over: Any) -> Any:
    """``over`` on top of ``base``: mappings merge key by key (the base's order, new keys
    after) unless tagged ``!replace``; anything else, lists too, replaces."""
    if isinstance(over, Replace):
        return dict(over)
    if isinstance(base, Mapping) and isinstance(over, Mapping):
        out = dict(base)
        for k, v in over.items():
            out[k] = merge(base[k], v) if k in base else v
        return out
    return over


def read_yaml(path: str | Path) -> Any:
    """One YAML file as written: ``base:`` not followed, ``!replace`` mappings kept as
    :class:`Replace` (errors name the file)."""
    path = Path(path)
    try:
        with path.open(encoding="utf-8") as fh:
            return yaml.load(fh, Loader=_Loader)  # a SafeLoader plus !replace
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: malformed YAML: {exc}") from None


def load_yaml(path: str | Path, _chain: tuple[Path, ...] = ()) -> Any:
    """A YAML file's data with its ``base:`` chain merged in (errors name the file).

    A file whose top level says ``base: OTHER.yaml`` states only what differs from OTHER
    (which may name its own base); a file reached twice in one chain is refused.
    """
    path = Path(path)
    key = path.resolve()
    if key in _chain:
        names = " -> ".join(str(p) for p in (*_chain, key))
        raise ConfigError(f"{path}: {BASE_KEY}: circular chain {names}")
    data = read_yaml(path)
    if isinstance(data, Mapping) and BASE_KEY in data:
        over = {k: v for k, v in data.items() if k != BASE_KEY}
        data = merge(load_yaml(base_path(data[BASE_KEY], path), (*_chain, key)), over)
    return _plain_maps(data)


def _plain_maps(obj: Any) -> Any:
    """``!replace`` mappings, merged, become plain dicts (YAML-dumpable like any other)."""
    if isinstance(obj, dict):
        return {k: _plain_maps(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_plain_maps(v) for v in obj]
    return obj


def load_config(cls: type[T], name_or_path: str | Path, kind: str, drop: tuple[str, ...] = ()) -> T:
    """Dataclass ``cls`` from a shipped name in ``configs/<kind>/`` or a YAML path.

    Top-level keys in ``drop`` are documentation and are not kept; every error names the
    file and the dotted key.
    """
    path = resolve_path(name_or_path, kind)
    data = load_yaml(path)
    if drop and isinstance(data, Mapping):
        data = {k: v for k, v in data.items() if k not in drop}
    try:
        return from_dict(cls, data)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


def load_rover(name_or_path: str | Path = "proto_explorer") -> RoverConfig:
    """Load a rover configuration by shipped name or path."""
    return load_config(RoverConfig, name_or_path, "rover")


def load_terrain(name_or_path: str | Path = "flat") -> TerrainConfig:
    """Load a terrain configuration by shipped name or path."""
    return load_config(TerrainConfig, name_or_path, "terrain")
