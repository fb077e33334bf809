"""ROS 1 / ROS 2 bags to SPEC §6 drive logs (rover-env import-bag).

A real rover's drives are recorded as bags, not as SPEC §6 logs. This reads a bag (a ROS 2
folder, a .db3 or .mcap file, or a ROS 1 .bag) with rosbags' pure-Python AnyReader (no ROS
install needed), takes each log column from the topic and field that a topic map (YAML) names,
with its unit and sign, and resamples everything onto one clock:

  * stamps: a message's header.stamp where its type has a header, else the bag's receive
    time (per topic, map key stamp: header | receive); integer nanoseconds throughout.
  * the log's clock: t_k = k / rate_hz, from the start = the latest of the first stamps of
    the state topics (wheels, joints, yaw, pose, effort) and the first command, to the end =
    the earliest last stamp of the state topics. Grid stamps are start + round(k * 1e9 / rate_hz)
    ns, so data stamped exactly on the grid is imported bit for bit.
  * states (wheel and joint angles, yaw, pose): linear interpolation between the messages
    either side of t_k; angles are unwrapped first where the map says wrapped, wheel angles
    are then shifted to zero at the start, yaw and pose are taken in the rover's frame at
    the start (SPEC §6). A yaw or pose reference more than twice slower than the log's clock
    stays sparse: only the sample nearest each of its messages gets a value (interpolated to
    the sample's time), the others are empty (SPEC §6: not measured), so 1 Hz fixes stay
    1 Hz fixes instead of a made-up path between them.
  * ``clock="wheels"`` (``--clock wheels``): the log's rows are the wheel topic's own stamps
    inside that span instead of an even grid, so each wheel angle is the message's own value,
    an encoder's whole counts stay whole (linear interpolation between two messages off the
    grid makes a count a fraction, and diagnose then reads the encoders as unquantised and
    their noise from the smoothed angles); the other states are interpolated at those stamps.
    SPEC §6 asks only that time increase; diagnose reads uneven rows.
  * effort (optional map section): JointState.effort of the driven wheels (1L 1R 2L 2R),
    times sign and scale (N m at the wheel shaft), interpolated as the other states are and
    not shifted to zero; a state topic like them (its span, gaps and rate are checked).
  * commands: zero-order hold, the last command at or before t_k (0 once older than
    commands.timeout_s, if given, as a motor watchdog does); their rate and gaps are not
    checked, as many publishers send only on change.

Every defect raises one BagError (a LogError) naming the bag or map file, the topic and the
field, joint or time: a bad map key, a topic missing or of another message type, a joint name
or field missing from a message, stamps out of order, a gap longer than max_gap_s inside the
imported span, a state topic whose median rate is below min_rate_hz, no common time span.
Nothing is skipped silently: messages on a shared JointState topic that carry none of a
section's joints (another publisher's) are counted and reported. No simulator is imported.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rover_env.bag_map import (
    MSG_TYPES,
    AngleSource,
    BagError,
    CommandSource,
    EffortSource,
    Source,
    StateSource,
    TopicMap,
    load_topic_map,
)
from rover_env.config import DRIVEN_WHEELS, JOINTS, WHEELS, ConfigError, load_rover
from rover_env.logs import DriveLog, LogError, LogMeta, write_log

Array = NDArray[np.float64]
Ints = NDArray[np.int64]

__all__ = [
    "AngleSource",
    "BagError",
    "CommandSource",
    "EffortSource",
    "Source",
    "StateSource",
    "TopicMap",
    "add_cli",
    "import_bag",
    "load_topic_map",
]


# --------------------------------------------------------------------------- reading the bag


@dataclass
class _Series:
    """One map section's samples: stamps (ns, strictly increasing) and values per message."""

    key: str
    topic: str
    ns: Ints
    values: Array
    index: NDArray[np.intp]
    """Each sample's message number on its topic (0-based)."""
    n_topic: int
    stamp: str


def _when(ns: int) -> str:
    return f"stamp {ns // 10**9}.{ns % 10**9:09d} s"


def _read_topics(bag: Path, wanted: dict[str, tuple[str, tuple[str, ...]]]) -> dict[str, Any]:
    """Every message of the wanted topics as (receive ns, message), plus each topic's type.

    ``wanted`` maps topic -> (map key, allowed types). Bags without embedded definitions
    (ROS 2 before Iron) are read with the ROS 2 Humble types.
    """
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag1 import ReaderError as ReaderError1
    from rosbags.rosbag2 import ReaderError as ReaderError2
    from rosbags.typesys import Stores, get_typestore

    try:
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            topics = reader.topics
            for topic, (key, types) in wanted.items():
                if topic not in topics:
                    have = ", ".join(sorted(topics)) or "none"
                    raise BagError(
                        f"topic {topic!r} (map key {key!r}) is not in the bag; it has {have}", bag
                    )
                mt = topics[topic].msgtype
                if mt not in types:
                    raise BagError(
                        f"topic {topic!r} carries {mt}; map key {key!r} needs {' or '.join(types)}",
                        bag,
                    )
            out: dict[str, Any] = {t: (topics[t].msgtype, []) for t in wanted}
            conns = [c for c in reader.connections if c.topic in wanted]
            for conn, recv, raw in reader.messages(connections=conns):
                out[conn.topic][1].append((int(recv), reader.deserialize(raw, conn.msgtype)))
    except BagError:
        raise
    except (AnyReaderError, ReaderError1, ReaderError2, OSError, ValueError, KeyError) as exc:
        raise BagError(f"cannot read the bag: {exc}", bag) from None
    return out


def _stamps(bag: Path, key: str, src: Source, msgs: list[Any], mtype: str) -> tuple[list[int], str]:
    """Each message's stamp (ns): its header's, or the bag's receive time."""
    has_header = hasattr(msgs[0][1], "header")
    use = src.stamp or ("header" if has_header else "receive")
    if use == "header" and not has_header:
        raise BagError(
            f"map key '{key}.stamp' is header but {mtype} on {src.topic!r} has no header", bag
        )
    if use == "receive":
        return [m[0] for m in msgs], use
    return [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in msgs], use


def _joint_rows(
    bag: Path,
    topic: str,
    key: str,
    msgs: list[Any],
    src: AngleSource | CommandSource | EffortSource,
    field: str,
) -> tuple[list[list[float]], list[int]]:
    """``field`` of the named joints per message; messages naming none of them are another publisher's."""
    names, rows, used = src.names, [], []
    cols = WHEELS if key == "wheels" else JOINTS if key == "joints" else DRIVEN_WHEELS
    for i, (_, m) in enumerate(msgs):
        have = list(m.name)
        present = [n in have for n in names]
        if not any(present):
            continue
        where = f"topic {topic!r}, message {i} ({_when(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec)})"
        if not all(present):
            j = present.index(False)
            raise BagError(
                f"{where}: joint {names[j]!r} (map key '{key}.names.{cols[j]}') is missing; "
                f"the message names {have}",
                bag,
            )
        arr = np.asarray(getattr(m, field), dtype=np.float64)
        if arr.size == 0:
            raise BagError(
                f"{where}: field {field!r} is missing (empty); map key {key!r} reads it", bag
            )
        if arr.shape != (len(have),):
            raise BagError(
                f"{where}: field {field!r} has {arr.size} entries for {len(have)} names; "
                f"map key {key!r} reads it",
                bag,
            )
        rows.append([float(arr[have.index(n)]) for n in names])
        used.append(i)
    if not rows:
        raise BagError(
            f"topic {topic!r}: no message names any of {list(names)} (map key {key!r})", bag
        )
    return rows, used


def _quat(q: Any) -> list[float]:
    return [float(q.w), float(q.x), float(q.y), float(q.z)]


def _values(
    bag: Path, key: str, topic: str, src: Source, msgs: list[Any], mtype: str, tmap: TopicMap
) -> tuple[Array, list[int]]:
    """Raw values per message in log units (rad, rad/s, N m; yaw/pose: quaternion w x y z, + x y z)."""
    if isinstance(src, AngleSource):
        rows, used = _joint_rows(bag, topic, key, msgs, src, "position")
        v = np.array(rows) * src.scale * np.array(src.sign)
        if src.wrapped:
            v = np.unwrap(v, axis=0)
        return v - np.array(src.offset), used
    if isinstance(src, EffortSource):
        rows, used = _joint_rows(bag, topic, key, msgs, src, "effort")
        return np.array(rows) * src.scale * np.array(src.sign), used
    if isinstance(src, CommandSource):
        return _command_values(bag, topic, src, msgs, mtype, tmap)
    rows = []
    for i, (_, m) in enumerate(msgs):
        if key == "yaw":
            if float(m.orientation_covariance[0]) == -1.0:
                raise BagError(
                    f"topic {topic!r}, message {i}: the IMU gives no orientation (orientation_covariance[0] = -1)",
                    bag,
                )
            rows.append(_quat(m.orientation))
        else:
            pose = m.pose.pose if hasattr(m.pose, "pose") else m.pose
            p = pose.position
            rows.append([*_quat(pose.orientation), float(p.x), float(p.y), float(p.z)])
        if not (math.isfinite(sum(rows[-1])) and np.linalg.norm(rows[-1][:4]) > 0.5):
            raise BagError(
                f"topic {topic!r}, message {i}: orientation {rows[-1][:4]} is not a unit quaternion",
                bag,
            )
    return np.array(rows), list(range(len(msgs)))


def _command_values(
    bag: Path, topic: str, src: CommandSource, msgs: list[Any], mtype: str, tmap: TopicMap
) -> tuple[Array, list[int]]:
    if src.type == "joint_state":
        rows, used = _joint_rows(bag, topic, "commands", msgs, src, "velocity")
        return np.array(rows) * src.scale * np.array(src.sign), used
    if src.type == "float64_multi_array":
        rows = []
        for i, (_, m) in enumerate(msgs):
            data = np.asarray(m.data, dtype=np.float64)
            if data.shape != (len(src.order),):
                raise BagError(
                    f"topic {topic!r}, message {i}: data has {data.size} entries, map key 'commands.order' {len(src.order)}",
                    bag,
                )
            rows.append([data[src.order.index(w)] for w in DRIVEN_WHEELS])
        return np.array(rows) * src.scale * np.array(src.sign), list(range(len(msgs)))
    try:
        geo = load_rover(tmap.rover).geometry
    except ConfigError as exc:
        raise BagError(f"key 'rover' (needed for twist commands): {exc}", tmap.path) from None
    tw = [m.twist if hasattr(m, "twist") else m for _, m in msgs]
    v = np.array([float(t.linear.x) for t in tw])
    w = np.array([float(t.angular.z) for t in tw])
    left = (v - w * geo.half_track) / geo.wheel_radius
    right = (v + w * geo.half_track) / geo.wheel_radius
    return np.column_stack([left, right, left, right]), list(range(len(msgs)))


def _series(bag: Path, tmap: TopicMap, data: dict[str, Any]) -> dict[str, _Series]:
    """Each map section's values and stamps, checked: finite, stamped, in order."""
    out: dict[str, _Series] = {}
    sources: dict[str, Source] = {**tmap.states(), "commands": tmap.commands}
    for key, src in sources.items():
        topic = src.topic
        mtype, msgs = data[topic]
        if not msgs:
            raise BagError(f"topic {topic!r} (map key {key!r}) has no messages", bag)
        values, used = _values(bag, key, topic, src, msgs, mtype, tmap)
        idx = np.array(used, dtype=np.intp)
        bad_row = np.flatnonzero(~np.all(np.isfinite(values), axis=1))
        if bad_row.size:
            i = int(bad_row[0])
            raise BagError(
                f"topic {topic!r} ({key}), message {idx[i]}: value not finite: {values[i].tolist()}",
                bag,
            )
        stamps, stamp = _stamps(bag, key, src, [msgs[i] for i in used], mtype)
        ns = np.array(stamps, dtype=np.int64)
        if stamp == "header" and np.any(ns == 0):
            i = int(np.flatnonzero(ns == 0)[0])
            raise BagError(
                f"topic {topic!r} ({key}), message {idx[i]}: header.stamp is 0 (not filled by "
                f"its publisher); set '{key}.stamp: receive' in the map",
                bag,
            )
        bad = np.flatnonzero(np.diff(ns) <= 0)
        if bad.size:
            j = int(bad[0])
            raise BagError(
                f"topic {topic!r} ({key}): {stamp} stamps out of order: message {idx[j]} at "
                f"{_when(int(ns[j]))}, then message {idx[j + 1]} at {_when(int(ns[j + 1]))}",
                bag,
            )
        out[key] = _Series(key, topic, ns, values, idx, len(msgs), stamp)
    return out


# --------------------------------------------------------------------------- resampling


CLOCKS = ("grid", "wheels")
"""The log's rows: an even grid at the map's rate, or the wheel topic's own stamps."""


def _median_rate(s: _Series) -> float:
    return 1e9 / float(np.median(np.diff(s.ns))) if s.ns.size > 1 else 0.0


def _window(bag: Path, tmap: TopicMap, series: dict[str, _Series]) -> tuple[int, int]:
    states = [s for k, s in series.items() if k != "commands"]
    start = max([int(s.ns[0]) for s in states] + [int(series["commands"].ns[0])])
    end = min(int(s.ns[-1]) for s in states)
    if end - start < 1e9 / tmap.rate_hz:
        spans = "; ".join(
            f"{s.topic} ({k}) {_when(int(s.ns[0]))} to {_when(int(s.ns[-1]))}"
            for k, s in series.items()
        )
        raise BagError(
            f"the topics' time spans do not overlap by one sample at {tmap.rate_hz:g} Hz: {spans}",
            bag,
        )
    return start, end


def _check_state(
    bag: Path, tmap: TopicMap, s: _Series, src: StateSource, start: int, end: int
) -> None:
    """Refuse a slow topic, or a gap the interpolation would bridge inside the log's span."""
    min_rate = src.min_rate_hz or tmap.min_rate_hz
    rate = _median_rate(s)
    if rate < min_rate:
        raise BagError(
            f"topic {s.topic!r} ({s.key}): median rate {rate:.3g} Hz is below min_rate_hz "
            f"{min_rate:g} ({s.ns.size} messages)",
            bag,
        )
    max_gap = src.max_gap_s or tmap.max_gap_s
    gaps = np.diff(s.ns)
    inside = (s.ns[1:] > start) & (s.ns[:-1] < end)
    bad = np.flatnonzero(inside & (gaps > max_gap * 1e9))
    if bad.size:
        j = int(bad[0])
        raise BagError(
            f"topic {s.topic!r} ({s.key}): gap of {gaps[j] / 1e9:.3f} s (max_gap_s {max_gap:g}) "
            f"between message {s.index[j]} at {_when(int(s.ns[j]))} and message "
            f"{s.index[j + 1]} at {_when(int(s.ns[j + 1]))} (t = {(s.ns[j] - start) / 1e9:.3f} s "
            f"in the log)",
            bag,
        )


def _grid(start: int, end: int, rate: float) -> Ints:
    step = 1e9 / rate
    k = np.arange(int((end - start) / step) + 2, dtype=np.float64)
    g = start + np.rint(k * step).astype(np.int64)
    return g[g <= end]


def _interp(s: _Series, grid: Ints, start: int, values: Array | None = None) -> Array:
    x = (s.ns - start).astype(np.float64)
    xg = (grid - start).astype(np.float64)
    v = s.values if values is None else values
    return np.column_stack([np.interp(xg, x, v[:, j]) for j in range(v.shape[1])])


def _quat_to_mat(q: Array) -> Array:
    """(n, 4) quaternions (w, x, y, z), normalised here, to (n, 3, 3) rotation matrices."""
    w, x, y, z = np.moveaxis(q / np.linalg.norm(q, axis=-1, keepdims=True), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def _heading(s: _Series, grid: Ints, start: int) -> tuple[Array, Array]:
    """Yaw on the grid in the rover's frame at the start, and that frame's rotation matrix.

    Quaternions are sign-aligned and interpolated component-wise (then normalised) for the
    start frame only; yaw itself is interpolated, unwrapped, as the other angles are.
    """
    q = s.values[:, :4].copy()
    flip = np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=1) < 0, -1.0, 1.0))
    q[1:] *= flip[:, None]
    r0 = _quat_to_mat(_interp(s, grid[:1], start, q))[0]
    rel = np.einsum("ji,njk->nik", r0, _quat_to_mat(q))  # r0.T @ R
    yaw = np.unwrap(np.arctan2(rel[:, 1, 0], rel[:, 0, 0]))
    on_grid = _interp(s, grid, start, yaw[:, None])[:, 0]
    return on_grid - on_grid[0], r0


def _start_heading(tmap: TopicMap, r0: Array | None) -> float | None:
    """The log's start heading in the reference's frame (degrees) where the map says that
    frame is shared by every drive (``shared_frame``), else None."""
    ref = tmap.pose or tmap.yaw
    if r0 is None or ref is None or not ref.shared_frame:
        return None
    return round(math.degrees(math.atan2(r0[1, 0], r0[0, 0])), 6)


def _nearest_samples(s: _Series, grid: Ints) -> NDArray[np.bool_]:
    """The grid samples nearest to a message of ``s`` (within half a sample of the grid):
    a reference slower than the log's clock stays as sparse as it was measured."""
    keep = np.zeros(grid.size, dtype=bool)
    half = (grid[-1] - grid[0]) / max(grid.size - 1, 1) / 2
    ns = s.ns[(s.ns >= grid[0] - half) & (s.ns <= grid[-1] + half)]
    k = np.clip(np.searchsorted(grid, ns), 1, grid.size - 1)
    keep[np.where(ns - grid[k - 1] <= grid[k] - ns, k - 1, k)] = True
    return keep


def _hold(s: _Series, grid: Ints, timeout_s: float | None) -> Array:
    """Zero-order hold: the last command at or before each grid stamp (0 past the timeout)."""
    i = np.searchsorted(s.ns, grid, side="right") - 1
    out = s.values[i].copy()
    if timeout_s is not None:
        out[(grid - s.ns[i]) > timeout_s * 1e9] = 0.0
    return out


def import_bag(
    bag: str | Path,
    topic_map: TopicMap | str | Path,
    *,
    rate_hz: float | None = None,
    clock: str = "grid",
    summary: list[str] | None = None,
) -> DriveLog:
    """Read ``bag`` through ``topic_map`` into a SPEC §6 log (see the module docstring).

    ``rate_hz`` overrides the map's clock; ``clock`` ``"wheels"`` takes the rows at the wheel
    topic's stamps instead of an even grid at that rate; lines describing the import (sample count, each
    topic's message count and rate, what was resampled how) are appended to ``summary``.
    """
    bag = Path(bag)
    tmap = topic_map if isinstance(topic_map, TopicMap) else load_topic_map(topic_map)
    if clock not in CLOCKS:
        raise BagError(f"clock must be one of {', '.join(CLOCKS)}, got {clock!r}")
    if rate_hz is not None and clock == "wheels":
        raise BagError("rate_hz and clock 'wheels' exclude each other: the wheels set the rate")
    if rate_hz is not None:
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise BagError(f"rate_hz must be finite and > 0, got {rate_hz!r}")
        tmap = replace(tmap, rate_hz=float(rate_hz))
    if not bag.exists():
        raise BagError("bag not found", bag)
    sources: dict[str, Source] = {**tmap.states(), "commands": tmap.commands}
    wanted: dict[str, tuple[str, tuple[str, ...]]] = {}
    for key, src in sources.items():
        types = MSG_TYPES[tmap.commands.type if key == "commands" else key]
        prev = wanted.get(src.topic)
        if prev is not None and prev[1] != types:
            raise BagError(
                f"topic {src.topic!r} is named for {prev[0]!r} and {key!r}, which need different types",
                tmap.path,
            )
        wanted[src.topic] = (key, types)
    series = _series(bag, tmap, _read_topics(bag, wanted))
    start, end = _window(bag, tmap, series)
    for key, src in tmap.states().items():
        _check_state(bag, tmap, series[key], src, start, end)
    if clock == "wheels":
        ns = series["wheels"].ns
        grid = ns[(ns >= start) & (ns <= end)]
        if grid.size < 2:
            raise BagError(f"topic {series['wheels'].topic!r}: under two messages in the span", bag)
        start = int(grid[0])
        tmap = replace(tmap, rate_hz=_median_rate(series["wheels"]))
    else:
        grid = _grid(start, end, tmap.rate_hz)
    phi = _interp(series["wheels"], grid, start)
    pose = np.full((grid.size, 3), np.nan)
    r0 = None
    if "yaw" in series:
        pose[:, 2], r0 = _heading(series["yaw"], grid, start)
    if "pose" in series:
        pose[:, 2], r0 = _heading(series["pose"], grid, start)
        xyz = _interp(series["pose"], grid, start, series["pose"].values[:, 4:])
        pose[:, :2] = ((xyz - xyz[0]) @ r0)[:, :2]  # rows: r0.T @ (p - p0)
    for key in ("yaw", "pose"):
        if key in series and _median_rate(series[key]) < tmap.rate_hz / 2:
            cols = [2] if key == "yaw" else [0, 1, 2]
            pose[np.ix_(~_nearest_samples(series[key], grid), np.array(cols))] = np.nan
    notes = f"imported from bag {bag.name} with topic map {tmap.path.name if tmap.path else '(in code)'}; start {_when(start)}"
    effort = _interp(series["effort"], grid, start) if "effort" in series else None
    log = DriveLog(
        t=(grid - start) / 1e9,
        cmd=_hold(series["commands"], grid, tmap.commands.timeout_s),
        phi=phi - phi[0],
        theta=_interp(series["joints"], grid, start),
        pose=pose,
        effort=np.zeros((0, 4)) if effort is None else effort,
        meta=LogMeta(
            rover=tmap.rover,
            sample_rate_hz=tmap.rate_hz,
            terrain=tmap.terrain,
            notes=f"{tmap.notes}\n{notes}" if tmap.notes else notes,
            start_heading_deg=_start_heading(tmap, r0),
        ),
    )
    if summary is not None:
        summary.extend(_summary(log, series, start, clock))
    return log


def _summary(log: DriveLog, series: dict[str, _Series], start: int, clock: str) -> list[str]:
    lines = [
        f"{len(log)} samples at {log.meta.sample_rate_hz:g} Hz, {log.t[-1]:.3f} s from {_when(start)}"
    ]
    for key, s in series.items():
        used = f" ({s.ns.size} used, the rest another publisher's)" if s.ns.size < s.n_topic else ""
        lines.append(
            f"  {s.topic} -> {key}: {s.n_topic} messages{used}, median rate "
            f"{_median_rate(s):.4g} Hz, {s.stamp} stamps"
        )
    skip = {"commands"} | ({"wheels"} if clock == "wheels" else set())
    states = ", ".join(k for k in series if k not in skip)
    if clock == "wheels":
        lines.append("  rows at the wheel topic's stamps: wheel angles as published")
    lines.append(f"  linear interpolation: {states}; zero-order hold: commands")
    return lines


# --------------------------------------------------------------------------- command line


def _cli(args: argparse.Namespace) -> int:
    import sys

    lines: list[str] = []
    name = str(args.name).removesuffix(".csv")
    try:
        if not name or Path(name).name != name:
            raise BagError(f"--name must be a plain file stem, got {args.name!r}")
        log = import_bag(args.bag, args.map, rate_hz=args.rate, clock=args.clock, summary=lines)
        path = write_log(log, Path(args.out) / f"{name}.csv", overwrite=args.overwrite)
    except (LogError, FileExistsError) as exc:
        print(f"rover-env import-bag: {exc}", file=sys.stderr)
        return 2
    print("\n".join(lines))
    print(f"wrote {path} and {path.with_suffix('.yaml')}")
    return 0


def add_cli(sub: Any) -> None:
    """The ``import-bag`` subcommand on ``rover-env``'s subparsers."""
    p = sub.add_parser(
        "import-bag",
        help="a ROS 1/2 bag (folder, .db3, .mcap, .bag) to a SPEC §6 drive log",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("bag", help="ROS 2 bag folder, .db3 or .mcap file, or ROS 1 .bag file")
    p.add_argument(
        "--map",
        required=True,
        help="topic map YAML, or the name of a shipped one (configs/bags: jointstate_imu_twist)",
    )
    p.add_argument("--out", required=True, help="folder for <name>.csv and <name>.yaml")
    p.add_argument("--name", default="drive", help="file stem of the log (default: drive)")
    p.add_argument(
        "--rate", type=float, default=None, help="log rate in Hz (default: the map's rate_hz)"
    )
    p.add_argument(
        "--clock",
        choices=CLOCKS,
        default="grid",
        help="the log's rows: an even grid at --rate (default), or the wheel topic's own stamps"
        " (encoder counts kept whole, no interpolation of the wheels)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace a different log already there")
    p.set_defaults(func=_cli)
