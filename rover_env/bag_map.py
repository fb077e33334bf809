"""The topic map of ``rover-env import-bag``: which topic and field feeds each log column.

A YAML names, per log section (wheels, joints, commands, and optionally yaw or pose, and
effort), the topic, the joint names or array order, the unit and the sign; it is read and
checked here, one error per bad key naming the map file and the key (configs/bags/ ships an
example).
Kept apart from the bag reading (:mod:`rover_env.bags`) so each stays a file one can read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from rover_env.config import DRIVEN_WHEELS, JOINTS, WHEELS, ConfigError, configs_dir, load_yaml
from rover_env.logs import LogError

__all__ = [
    "MSG_TYPES",
    "AngleSource",
    "BagError",
    "CommandSource",
    "EffortSource",
    "Source",
    "StateSource",
    "TopicMap",
    "load_topic_map",
]


class BagError(LogError):
    """A bag or topic map cannot be imported as it is (names the file, topic, field, time)."""


ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0, "rev": 2.0 * math.pi, "ticks": math.nan}
SPEED_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0, "rev/s": 2.0 * math.pi, "rpm": math.pi / 30}
JOINT_STATE = "sensor_msgs/msg/JointState"
MSG_TYPES: dict[str, tuple[str, ...]] = {
    "wheels": (JOINT_STATE,),
    "joints": (JOINT_STATE,),
    "effort": (JOINT_STATE,),
    "yaw": ("sensor_msgs/msg/Imu",),
    "pose": (
        "nav_msgs/msg/Odometry",
        "geometry_msgs/msg/PoseStamped",
        "geometry_msgs/msg/PoseWithCovarianceStamped",
    ),
    "twist": ("geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped"),
    "joint_state": (JOINT_STATE,),
    "float64_multi_array": ("std_msgs/msg/Float64MultiArray",),
}
CommandType = Literal["twist", "joint_state", "float64_multi_array"]
StampSource = Literal["header", "receive"]

# --------------------------------------------------------------------------- the topic map


@dataclass(frozen=True, kw_only=True)
class Source:
    """One topic the log reads; ``stamp`` None means the header where the type has one."""

    topic: str
    stamp: StampSource | None = None


@dataclass(frozen=True, kw_only=True)
class StateSource(Source):
    """A state topic (interpolated); None limits take the map's."""

    max_gap_s: float | None = None
    min_rate_hz: float | None = None


@dataclass(frozen=True, kw_only=True)
class ReferenceSource(StateSource):
    """A heading or pose reference (``yaw``, ``pose``)."""

    shared_frame: bool = True
    """The reference's frame is the same for every drive (a total station, motion capture,
    RTK, an IMU fused with a compass): the log's start heading in it is written as the YAML's
    ``start_heading_deg``, which places the drives' own frames in one. ``false`` for a
    reference that starts anew each drive at an arbitrary heading (``diagnose --frames fit``
    then fits each log's frame)."""


@dataclass(frozen=True, kw_only=True)
class AngleSource(StateSource):
    """JointState positions, one per log column (WHEELS or JOINTS order): rad = sign*unit*x - offset."""

    names: tuple[str, ...]
    unit: str = "rad"
    scale: float = 1.0
    """rad per unit of the message."""
    sign: tuple[float, ...] = ()
    offset: tuple[float, ...] = ()
    """rad, subtracted after sign and unit (joints only)."""
    wrapped: bool = False


@dataclass(frozen=True, kw_only=True)
class EffortSource(StateSource):
    """JointState efforts of 1L 1R 2L 2R: N m at the wheel shaft = sign * scale * effort."""

    names: tuple[str, ...]
    scale: float = 1.0
    """N m at the wheel per unit of the message."""
    sign: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0)


@dataclass(frozen=True, kw_only=True)
class CommandSource(Source):
    """Wheel speed targets of 1L 1R 2L 2R (rad/s), held from one message to the next."""

    type: CommandType
    names: tuple[str, ...] = ()
    """joint_state: the joint name of each driven wheel."""
    order: tuple[str | None, ...] = ()
    """float64_multi_array: the wheel of each entry of ``data`` (None: not a command)."""
    unit: str = "rad/s"
    scale: float = 1.0
    sign: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0)
    timeout_s: float | None = None


@dataclass(frozen=True, kw_only=True)
class TopicMap:
    """Where each log column comes from (``load_topic_map`` reads and checks one)."""

    rover: str
    wheels: AngleSource
    joints: AngleSource
    commands: CommandSource
    rate_hz: float = 50.0
    max_gap_s: float = 0.25
    min_rate_hz: float = 10.0
    yaw: ReferenceSource | None = None
    pose: ReferenceSource | None = None
    effort: EffortSource | None = None
    terrain: str | dict[str, Any] | None = None
    notes: str | None = None
    path: Path | None = None

    def states(self) -> dict[str, StateSource]:
        """The state sections the map uses, by map key."""
        keys = ("wheels", "joints", "yaw", "pose", "effort")
        return {k: getattr(self, k) for k in keys if getattr(self, k) is not None}


_MISSING: Any = object()


class _Keys:
    """One mapping of a map file; every error names the file and the dotted key."""

    def __init__(self, data: Any, file: Path, where: str) -> None:
        self.file, self.where = file, where
        if not isinstance(data, dict):
            raise BagError(f"key {where!r} must be a mapping, got {data!r}", file)
        self.data = {str(k): v for k, v in data.items()}
        self.used: set[str] = set()

    def error(self, key: str, msg: str) -> BagError:
        dotted = f"{self.where}.{key}" if self.where else key
        return BagError(f"key {dotted!r}: {msg}", self.file)

    def get(self, key: str, default: Any = _MISSING) -> Any:
        self.used.add(key)
        if key in self.data and self.data[key] is not None:
            return self.data[key]
        if default is _MISSING:
            raise self.error(key, "missing")
        return default

    def text(self, key: str, default: Any = _MISSING) -> Any:
        v = self.get(key, default)
        if v is not default and (not isinstance(v, str) or not v.strip()):
            raise self.error(key, f"must be a non-empty string, got {v!r}")
        return v

    def number(self, key: str, default: Any = _MISSING, positive: bool = True) -> Any:
        v = self.get(key, default)
        if v is default:
            return v
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise self.error(key, f"must be a finite number, got {v!r}")
        if positive and v <= 0:
            raise self.error(key, f"must be > 0, got {v!r}")
        return float(v)

    def choice(self, key: str, options: Any, default: Any = _MISSING) -> Any:
        v = self.get(key, default)
        if v is not default and v not in options:
            raise self.error(key, f"must be one of {', '.join(options)}, got {v!r}")
        return v

    def sub(self, key: str, default: Any = _MISSING) -> _Keys | None:
        v = self.get(key, default)
        if v is default:
            return None
        return _Keys(v, self.file, f"{self.where}.{key}" if self.where else key)

    def per(self, key: str, columns: tuple[str, ...], default: Any) -> list[Any]:
        """An optional per-column mapping (``sign``, ``offset``); absent columns get ``default``."""
        sub = self.sub(key, None)
        if sub is None:
            return [default] * len(columns)
        for col in sub.data:
            if col not in columns:
                raise sub.error(col, f"not one of {', '.join(columns)}")
        return [sub.get(col, default) for col in columns]

    def done(self) -> None:
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            raise self.error(
                unknown[0], f"unknown key (known here: {', '.join(sorted(self.used))})"
            )


def _common(k: _Keys, section: str) -> dict[str, Any]:
    stamp = k.choice("stamp", ("header", "receive"), None)
    out: dict[str, Any] = {"topic": k.text("topic"), "stamp": stamp}
    if section != "commands":
        out["max_gap_s"] = k.number("max_gap_s", None)
        out["min_rate_hz"] = k.number("min_rate_hz", None)
    return out


def _signs(
    k: _Keys, columns: tuple[str, ...], default: tuple[float, ...] | None = None
) -> tuple[float, ...]:
    """Per-column signs; an absent column takes ``default``'s entry (else +1)."""
    signs = k.per("sign", columns, None)
    signs = [
        d if s is None else s for s, d in zip(signs, default or (1,) * len(columns), strict=True)
    ]
    for col, s in zip(columns, signs, strict=True):
        if isinstance(s, bool) or s not in (1, -1):
            raise k.error(f"sign.{col}", f"must be 1 or -1, got {s!r}")
    return tuple(float(s) for s in signs)


def _names(k: _Keys, columns: tuple[str, ...]) -> tuple[str, ...]:
    sub = k.sub("names")
    assert sub is not None
    for col in sub.data:
        if col not in columns:
            raise sub.error(col, f"not a log column here (have {', '.join(columns)})")
    out = [str(sub.text(col)) for col in columns]
    dup = sorted({n for n in out if out.count(n) > 1})
    if dup:
        raise k.error("names", f"joint name {dup[0]!r} given for two columns")
    return tuple(out)


def _angles(k: _Keys, section: str, columns: tuple[str, ...]) -> AngleSource:
    units = tuple(ANGLE_UNITS) if section == "wheels" else ("rad", "deg")
    unit = k.choice("unit", units, "rad")
    scale = ANGLE_UNITS[unit]
    if unit == "ticks":
        scale = 2.0 * math.pi / k.number("ticks_per_rev")
    offset = (0.0,) * len(columns)
    if section == "joints":
        raw = k.per("offset", columns, 0.0)
        for col, v in zip(columns, raw, strict=True):
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise k.error(f"offset.{col}", f"must be a finite number (rad), got {v!r}")
        offset = tuple(float(v) for v in raw)
    wrapped = k.get("wrapped", False) if section == "wheels" else False
    if not isinstance(wrapped, bool):
        raise k.error("wrapped", f"must be true or false, got {wrapped!r}")
    return AngleSource(
        **_common(k, section),
        names=_names(k, columns),
        unit=unit,
        scale=scale,
        sign=_signs(k, columns),
        offset=offset,
        wrapped=wrapped,
    )


def _effort(k: _Keys, wheels: AngleSource) -> EffortSource:
    """The ``effort`` section; on the wheels' topic, names and signs default to theirs."""
    common = _common(k, "effort")
    same = common["topic"] == wheels.topic
    at = [WHEELS.index(w) for w in DRIVEN_WHEELS]
    if same and k.get("names", None) is None:
        names = tuple(wheels.names[i] for i in at)
    else:
        names = _names(k, DRIVEN_WHEELS)
    signs = tuple(wheels.sign[i] for i in at) if same else None
    return EffortSource(
        **common, names=names, scale=k.number("scale", 1.0), sign=_signs(k, DRIVEN_WHEELS, signs)
    )


def _commands(k: _Keys) -> CommandSource:
    kind = k.choice("type", ("twist", "joint_state", "float64_multi_array"))
    common = _common(k, "commands")
    timeout = k.number("timeout_s", None)
    if kind == "twist":
        return CommandSource(**common, type=kind, timeout_s=timeout)
    unit = k.choice("unit", tuple(SPEED_UNITS), "rad/s")
    names: tuple[str, ...] = ()
    order: tuple[str | None, ...] = ()
    if kind == "joint_state":
        names = _names(k, DRIVEN_WHEELS)
    else:
        raw = k.get("order")
        if not isinstance(raw, list) or any(w is not None and str(w) not in WHEELS for w in raw):
            raise k.error("order", f"must list driven wheels (or null) per data entry, got {raw!r}")
        order = tuple(None if w is None else str(w) for w in raw)
        if sorted(w for w in order if w is not None) != sorted(DRIVEN_WHEELS):
            raise k.error(
                "order", f"must name each of {', '.join(DRIVEN_WHEELS)} once, got {raw!r}"
            )
    return CommandSource(
        **common,
        type=kind,
        names=names,
        order=order,
        unit=unit,
        scale=SPEED_UNITS[unit],
        sign=_signs(k, DRIVEN_WHEELS),
        timeout_s=timeout,
    )


def _resolve_map(path: str | Path) -> Path:
    p = Path(path)
    if p.exists() or p.suffix in (".yaml", ".yml"):
        return p
    shipped = configs_dir() / "bags" / f"{p}.yaml"
    return shipped if shipped.is_file() else p


def load_topic_map(path: str | Path) -> TopicMap:
    """Read and check a topic map (a path, or the name of one in configs/bags)."""
    file = _resolve_map(path)
    if not file.is_file():
        raise BagError("topic map file not found", file)
    try:
        data = load_yaml(file)
    except ConfigError as exc:
        raise BagError(str(exc).removeprefix(f"{file}: "), file) from None
    k = _Keys(data, file, "")
    terrain = k.get("terrain", None)
    if terrain is not None and not isinstance(terrain, str | dict):
        raise k.error("terrain", f"must be a name or a mapping, got {terrain!r}")
    sections: dict[str, Any] = {}
    for key in ("wheels", "joints", "commands", "yaw", "pose", "effort"):
        sub = k.sub(key, None if key in ("yaw", "pose", "effort") else _MISSING)
        if sub is None:
            continue
        if key == "commands":
            sections[key] = _commands(sub)
        elif key in ("wheels", "joints"):
            sections[key] = _angles(sub, key, WHEELS if key == "wheels" else JOINTS)
        elif key == "effort":
            sections[key] = _effort(sub, sections["wheels"])
        else:
            shared = sub.get("shared_frame", True)
            if not isinstance(shared, bool):
                raise sub.error("shared_frame", f"must be true or false, got {shared!r}")
            sections[key] = ReferenceSource(**_common(sub, key), shared_frame=shared)
        sub.done()
    if "yaw" in sections and "pose" in sections:
        raise k.error("yaw", "give yaw or pose, not both (pose fills x, y and yaw)")
    out = TopicMap(
        rover=k.text("rover"),
        rate_hz=k.number("rate_hz", 50.0),
        max_gap_s=k.number("max_gap_s", 0.25),
        min_rate_hz=k.number("min_rate_hz", 10.0),
        terrain=terrain,
        notes=k.text("notes", None),
        path=file,
        **sections,
    )
    k.done()
    return out
