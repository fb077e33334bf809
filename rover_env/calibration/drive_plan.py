"""Proposed drives as commands for the real rover: ``rover-env drive-plan``.

``diagnose`` proposes a drive when two effects tie or the held-out drive cannot confirm a
candidate (:mod:`rover_env.calibration.evidence`). That drive must be DRIVEN by the rover
and logged: ``make-logs`` would simulate the nominal model, and its log added to a real
rover's would corrupt the diagnosis. This writes the plan's wheel-speed targets
(``drive_schedule(plan, default_rng(seed), duration, vmax)``) as

* ``DIR/<plan>.csv``: ``t,cmd_1L,cmd_1R,cmd_2L,cmd_2R`` (s, rad/s) at ``--rate``, each row held
  from its ``t`` until the next (zero-order hold); the last row, at ``t = duration``, is a
  stop (all zero), so the rover ends at rest;
* ``DIR/<plan>_bag/``: a ROS 2 bag of the same rows, one command message per row on the
  user's topic (``std_msgs/msg/Float64MultiArray``, what ros2_control's
  JointGroupVelocityController takes, or ``sensor_msgs/msg/JointState`` velocities), so a
  ``ros2 bag play`` is a command stream at ``--rate`` (drivers with a command timeout stop on
  silence; one message per change would not do);
* ``DIR/<plan>.md``: why, how long, how fast, and the ground it needs (the nominal path on
  flat ground, integrated from the commands).

Targets are clipped to the rover's ``motor.max_wheel_speed``, as the simulator that showed the
proposal separating the hypotheses clips them: the rover is asked for exactly that drive.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import re
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rover_env.calibration.candidates import SEPARATING_PLANS
from rover_env.calibration.evidence import EVIDENCE_PLANS, PLAN_DURATION, PLAN_SEED
from rover_env.config import DRIVEN_WHEELS, Geometry, RoverConfig, load_rover
from rover_env.generators.drives import PLANS, drive_schedule

Array = NDArray[np.float64]

__all__ = [
    "DEFAULT_JOINT_NAMES",
    "DEFAULT_TOPIC",
    "MSG_TYPES",
    "DrivePlanError",
    "Proposal",
    "add_cli",
    "command_rows",
    "ground",
    "parse_joint_names",
    "proposals_from_report",
    "proposals_from_result",
    "read_csv",
    "write_plan",
]

DEFAULT_TOPIC = "/wheel_velocity_controller/commands"
MSG_TYPES: dict[str, str] = {
    "float64_multi_array": "std_msgs/msg/Float64MultiArray",
    "joint_state": "sensor_msgs/msg/JointState",
}
DEFAULT_JOINT_NAMES: tuple[str, ...] = tuple(f"wheel_{w}" for w in DRIVEN_WHEELS)
"""The model's wheel joints (assets/proto_explorer.xml); a real rover names its own."""
CSV_HEADER: tuple[str, ...] = ("t", *(f"cmd_{w}" for w in DRIVEN_WHEELS))

PLAN_PURPOSE: dict[str, str] = {
    "test": "a general test drive: steps from rest, straight runs at several speeds, turns,"
    " a pivot turn, braking, reversing",
    "reversals": "long forward and backward runs on one line, a long pivot, and the same on the"
    " crossing line: a slope helps one way and hinders the other, rolling resistance opposes"
    " both",
    "turn-accel": "accelerating and braking while turning: high traction demand",
    "steps": "command steps of many sizes with holds of varied length: lag against delay",
    "speeds": "slow constant speeds and gentle turns at many loads: rolling radius against slip",
    "straight": "a measured straight: long constant-speed runs forward and back, many metres"
    " of pose against many wheel turns",
    "accel": "hard accelerations from rest and full reversals at the largest target: the"
    " motors' torque limit",
}
SLOPE_PLANS = frozenset(
    {p for e, (p, _) in EVIDENCE_PLANS.items() if e == "slope"}
    | {p for pair, (p, _) in SEPARATING_PLANS.items() if "slope" in pair}
)
"""Plans that probe a slope: they must be driven on the slope in question."""
_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"


class DrivePlanError(ValueError):
    """Bad input to ``drive-plan`` (the message names what)."""


@dataclass
class Proposal:
    """One drive to make: the plan, the draw and length of it, and why it was asked for."""

    plan: str
    seed: int = PLAN_SEED
    duration: float = PLAN_DURATION
    why: list[str] = field(default_factory=list)
    effects: set[str] = field(default_factory=set)


def command_rows(
    plan: str, seed: int, duration: float, vmax: float, rate: float
) -> tuple[Array, Array, float]:
    """(t, targets, largest target asked) rows: the schedule at t = k / rate for
    t < duration (clipped to vmax), then a stop at t = duration."""
    if plan not in PLANS:
        raise DrivePlanError(f"unknown plan {plan!r}; plans: {', '.join(PLANS)}")
    if not (math.isfinite(duration) and duration > 0):
        raise DrivePlanError(f"--duration must be a finite number > 0, got {duration!r}")
    if not (math.isfinite(rate) and rate > 0):
        raise DrivePlanError(f"--rate must be a finite number > 0, got {rate!r}")
    if seed < 0:
        raise DrivePlanError(f"--seed must be >= 0, got {seed}")
    sched = drive_schedule(plan, np.random.default_rng(seed), duration, vmax)
    m = math.ceil(duration * rate - 1e-9)  # rows strictly before the end
    t = np.append(np.arange(m) / rate, duration)
    asked = np.array([sched(float(tk)) for tk in t[:-1]] + [np.zeros(4)])
    return t, np.clip(asked, -vmax, vmax), float(np.max(np.abs(asked)))


def ground(t: Array, cmd: Array, geometry: Geometry) -> dict[str, float]:
    """The nominal path on flat ground (no slip) under the commands, held row by row.

    Forward speed r (L + R) / 2 and yaw rate r (R - L) / (2 half_track), L and R the mean
    target of each side, integrated exactly over each row (straight or circular arcs).
    """
    r, track = geometry.wheel_radius, 2.0 * geometry.half_track
    left, right = 0.5 * (cmd[:-1, 0] + cmd[:-1, 2]), 0.5 * (cmd[:-1, 1] + cmd[:-1, 3])
    v, w = r * 0.5 * (left + right), r * (right - left) / track
    dt = np.diff(t)
    psi = np.concatenate([[0.0], np.cumsum(w * dt)])
    dpsi = w * dt
    turning = np.abs(dpsi) > 1e-12
    safe = np.where(turning, dpsi, 1.0)
    # chord of an arc: v dt times (sin, 1 - cos) of the turn over the turn
    cx = np.where(turning, (np.sin(psi[1:]) - np.sin(psi[:-1])) / safe, np.cos(psi[:-1]))
    cy = np.where(turning, (np.cos(psi[:-1]) - np.cos(psi[1:])) / safe, np.sin(psi[:-1]))
    x = np.concatenate([[0.0], np.cumsum(v * dt * cx)])
    y = np.concatenate([[0.0], np.cumsum(v * dt * cy)])
    return {
        "farthest_m": float(np.max(np.hypot(x, y))),
        "x_min": float(x.min()),
        "x_max": float(x.max()),
        "y_min": float(y.min()),
        "y_max": float(y.max()),
        "path_m": float(np.sum(np.abs(v) * dt)),
        "turned_deg": float(np.degrees(np.sum(np.abs(dpsi)))),
        "end_x": float(x[-1]),
        "end_y": float(y[-1]),
        "end_yaw_deg": float(np.degrees(psi[-1])),
        "peak_speed_mps": float(np.max(np.abs(v), initial=0.0)),
        "peak_yaw_rate_dps": float(np.degrees(np.max(np.abs(w), initial=0.0))),
    }


def parse_joint_names(text: str | None) -> tuple[str, ...]:
    """``1L=a,1R=b,2L=c,2R=d`` -> (a, b, c, d) in the order 1L 1R 2L 2R; all four needed."""
    if text is None:
        return DEFAULT_JOINT_NAMES
    names: dict[str, str] = {}
    for item in text.split(","):
        key, sep, name = (s.strip() for s in item.partition("="))
        if not sep or not name or re.search(r"\s", name):
            raise DrivePlanError(f"--joint-names: {item.strip()!r} is not WHEEL=JOINT_NAME")
        if key not in DRIVEN_WHEELS:
            raise DrivePlanError(
                f"--joint-names: {key!r} is not a driven wheel ({', '.join(DRIVEN_WHEELS)})"
            )
        if key in names:
            raise DrivePlanError(f"--joint-names: wheel {key} named twice")
        names[key] = name
    missing = [w for w in DRIVEN_WHEELS if w not in names]
    if missing:
        raise DrivePlanError(f"--joint-names: no joint named for wheel(s) {', '.join(missing)}")
    out = tuple(names[w] for w in DRIVEN_WHEELS)
    if len(set(out)) < len(out):
        raise DrivePlanError("--joint-names: two wheels share a joint name")
    return out


def proposals_from_report(path: str | Path, untested: bool = True) -> list[Proposal]:
    """Every drive a diagnosis proposes (:func:`proposals_from_result`) from its
    ``result.json`` (or the folder holding it); an error where it proposes none."""
    p = Path(path)
    f = p / "result.json" if p.is_dir() else p
    if not f.is_file():
        raise DrivePlanError(f"--report {path}: no diagnose result (result.json) there")
    try:
        result = json.loads(f.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DrivePlanError(f"--report {f}: not a diagnose result.json ({exc})") from None
    if not isinstance(result, dict):
        raise DrivePlanError(f"--report {f}: not a diagnose result.json")
    props = proposals_from_result(result, untested)
    if not props:
        raise DrivePlanError(
            f"--report {f}: the diagnosis proposes no drive (no tie, no evidence, nothing untested)"
        )
    return props


def proposals_from_result(result: dict[str, Any], untested: bool = True) -> list[Proposal]:
    """Every drive a diagnosis result proposes (its tie, its evidence rows, the force
    balance's drive where its runs did not separate a tilt from a resistance or its interval
    is wide, named or not, and, with ``untested``, the drives for what its logs never
    tested), merged by (plan, seed, duration); results from before the seed and duration
    were recorded used :data:`PLAN_SEED` and :data:`PLAN_DURATION`."""
    raw: list[tuple[dict[str, Any], str, set[str]]] = []
    tie = result.get("tie")
    if isinstance(tie, dict) and tie.get("plan"):
        a, b = tie["effects"]
        raw.append((tie, f"tie between {a} and {b}: {tie.get('why', '')}", {a, b}))
    for e in result.get("evidence") or []:
        if isinstance(e, dict) and e.get("plan"):
            why = f"evidence for {e['effect']} ({e.get('reason', 'unconfirmed')}): {e['why']}"
            raw.append((e, why, {e["effect"]}))
    bal = result.get("balance")
    if isinstance(bal, dict) and bal.get("plan"):
        on = "the wheels' slip" if bal.get("source") == "slip" else "the motors' torque"
        why = bal.get("why_not") or bal.get("why_drive", "")
        raw.append((bal, f"the force balance on {on}: {why}", {"slope"}))
    for e in (result.get("untested") or []) if untested else []:
        if isinstance(e, dict) and e.get("plan"):
            why = f"untested {e['effect']} ({e.get('reason', '')}): {e.get('why', '')}"
            raw.append((e, why, {e["effect"]}))
    out: dict[tuple[str, int, float], Proposal] = {}
    for d, why, effects in raw:
        key = (
            str(d["plan"]),
            int(d.get("seed", PLAN_SEED)),
            float(d.get("duration", PLAN_DURATION)),
        )
        prop = out.setdefault(key, Proposal(*key))
        prop.why.append(why)
        prop.effects |= effects
    return list(out.values())


def _plan_why(plan: str) -> list[str]:
    """What ``plan`` is for: its description and the effects it decides (EVIDENCE_PLANS)."""
    decides = [f"{e}: {why}" for e, (p, why) in EVIDENCE_PLANS.items() if p == plan]
    return [PLAN_PURPOSE.get(plan, plan), *(f"decides {d}" for d in decides)]


def _fmt_row(values: Array) -> list[str]:
    return [repr(float(v)) for v in values]


def write_csv(path: Path, t: Array, cmd: Array) -> Path:
    """The rows as CSV, ``repr`` floats so they read back to the bit."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(CSV_HEADER)
        for tk, row in zip(t, cmd, strict=True):
            w.writerow(_fmt_row(np.concatenate([[tk], row])))
    return path


def read_csv(path: str | Path) -> tuple[Array, Array]:
    """(t, targets) of a ``drive-plan`` CSV."""
    with Path(path).open(newline="") as fh:
        rows = list(csv.reader(fh))
    if tuple(rows[0]) != CSV_HEADER:
        raise DrivePlanError(f"{path}: header {rows[0]} is not {list(CSV_HEADER)}")
    a = np.array([[float(x) for x in r] for r in rows[1:]], dtype=np.float64)
    return a[:, 0], a[:, 1:]


def write_bag(
    path: Path,
    t: Array,
    cmd: Array,
    topic: str,
    msg: str,
    joint_names: tuple[str, ...],
    storage: str,
) -> Path:
    """One command message per row, stamped at the row's time (the bag's clock starts at 0;
    ``ros2 bag play`` replays relative to its start)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    if path.exists():
        if not (path / "metadata.yaml").is_file() or any(
            p.suffix not in (".yaml", ".db3", ".mcap") for p in path.iterdir()
        ):
            raise DrivePlanError(f"{path} exists and is not a bag this command wrote; remove it")
        shutil.rmtree(path)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    msgtype = MSG_TYPES[msg]
    with Writer(path, version=8, storage_plugin=plugin) as writer:
        conn = writer.add_connection(topic, msgtype, typestore=ts)
        for tk, row in zip(t, cmd, strict=True):
            ns = round(float(tk) * 1e9)
            data = np.array(row, dtype=np.float64)
            if msg == "joint_state":
                stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
                m: Any = T["sensor_msgs/msg/JointState"](
                    header=T["std_msgs/msg/Header"](stamp=stamp, frame_id=""),
                    name=list(joint_names),
                    position=np.zeros(0),
                    velocity=data,
                    effort=np.zeros(0),
                )
            else:
                dim = T["std_msgs/msg/MultiArrayDimension"](
                    label=",".join(joint_names), size=4, stride=4
                )
                layout = T["std_msgs/msg/MultiArrayLayout"](dim=[dim], data_offset=0)
                m = T["std_msgs/msg/Float64MultiArray"](layout=layout, data=data)
            writer.write(conn, ns, ts.serialize_cdr(m, msgtype))
    return path


def _ground_lines(g: dict[str, float], cfg: RoverConfig, slope: bool) -> list[str]:
    """The ground to clear, from the nominal path and the rover's size."""
    geo = cfg.geometry
    length = 2 * geo.axle_spacing + 2 * geo.wheel_radius
    width = 2 * geo.half_track + geo.wheel_width
    reach = math.hypot(length / 2, width / 2)  # any point of the rover from its centre
    dx, dy = g["x_max"] - g["x_min"], g["y_max"] - g["y_min"]
    where = (
        "**Drive it on the slope in question** (the ground of the drives that showed it),"
        " each line both ways: this plan separates a slope from what opposes both"
        " directions, which flat ground cannot show."
        if slope
        else "Drive it on the same kind of ground as the other logs of the diagnosis."
    )
    return [
        "## Ground it needs",
        "",
        "The nominal path on flat ground, without slip, integrated from the commands (forward"
        f" speed r (L + R) / 2 and yaw rate r (R − L) / (2 × {geo.half_track:g} m), r ="
        f" {geo.wheel_radius:g} m; x forward and y left of the start):",
        "",
        f"- farthest from the start: **{g['farthest_m']:.2f} m**; path length"
        f" {g['path_m']:.2f} m; turned through {g['turned_deg']:.0f}° in all; ends at"
        f" ({g['end_x']:.2f}, {g['end_y']:.2f}) m, heading {g['end_yaw_deg']:+.0f}°;",
        f"- bounding box of the rover's centre: x {g['x_min']:.2f} … {g['x_max']:.2f} m,"
        f" y {g['y_min']:.2f} … {g['y_max']:.2f} m ({dx:.2f} m × {dy:.2f} m);",
        f"- clear at least that box grown by {reach:.2f} m on every side (the rover,"
        f" {length:.2f} m × {width:.2f} m, about its centre): {dx + 2 * reach:.1f} m ×"
        f" {dy + 2 * reach:.1f} m, plus a margin: skid turns slip, so the real path differs"
        " from this one.",
        "",
        where,
        "",
    ]


def plan_markdown(
    prop: Proposal,
    t: Array,
    cmd: Array,
    asked: float,
    cfg: RoverConfig,
    files: dict[str, str],
    bag: dict[str, str],
    rate: float,
) -> str:
    """The note beside the commands: why, how long and fast, the ground, how to use it."""
    r, vmax = cfg.geometry.wheel_radius, cfg.motor.max_wheel_speed
    g = ground(t, cmd, cfg.geometry)
    peak = float(np.max(np.abs(cmd)))
    slope = prop.plan in SLOPE_PLANS or "slope" in prop.effects
    L = [
        f"# Drive plan `{prop.plan}` (seed {prop.seed}, {prop.duration:g} s)",
        "",
        "Why:",
        "",
        *(f"- {w}" for w in (prop.why or _plan_why(prop.plan))),
        "",
        f"- Duration {prop.duration:g} s; {len(t)} rows of wheel-speed targets (1L 1R 2L 2R,"
        f" rad/s) at {rate:.4g} Hz, each held until the next; the last row (t ="
        f" {prop.duration:g} s) is a stop.",
        f"- Peak wheel-speed target {peak:.3g} rad/s = {peak * r:.3g} m/s at the wheel radius"
        f" {r:g} m; peak forward speed {g['peak_speed_mps']:.3g} m/s, peak yaw rate"
        f" {g['peak_yaw_rate_dps']:.3g} °/s."
        + (
            f" The plan asks up to {asked:.3g} rad/s: clipped to the rover's"
            f" max_wheel_speed {vmax:g} rad/s, as the simulator clips it."
            if asked > vmax
            else ""
        ),
        f"- Files: `{files['csv']}` (t, cmd_1L, cmd_1R, cmd_2L, cmd_2R) and the ROS 2 bag"
        f" `{files['bag']}/` ({bag['storage']}): one `{bag['msgtype']}` per row on"
        f" `{bag['topic']}`, {bag['layout']}. Published at the row rate so that a replay is"
        " a command stream: a driver with a command timeout stops on silence.",
        "",
        *_ground_lines(g, cfg, slope),
        "## How to use it",
        "",
        f"1. Drive it on the rover: `ros2 bag play {files['bag']}` with the rover's velocity"
        " controller listening on that topic (data in the order above: list the wheel"
        " joints in that order in the controller's `joints`), or feed the CSV to your own"
        " command node, holding each row until the next. A JointGroupVelocityController"
        " holds its last command: keep the emergency stop at hand if the replay is cut"
        " short.",
        "2. Record it with the rover's usual bag recording (wheel encoders, joint angles, the"
        " pose reference, and this command topic).",
        "3. Import the recording with `rover-env import-bag` (a SPEC §6 log). Where the earlier"
        " logs give `start_heading_deg`, this one must too: `import-bag` writes it from a"
        " shared-frame pose or yaw reference, or add the heading the rover started at.",
        "4. Run `rover-env diagnose` again with the earlier logs and this one, and the same"
        " options (`--frames fit` where the drives share no frame). It recognises this drive"
        " by its commands and holds it out beside your last own drive.",
        "",
        "Do not simulate it instead (`make-logs` drives the nominal model: its log added to a"
        " real rover's would corrupt the diagnosis).",
    ]
    return "\n".join(L) + "\n"


def write_plan(
    out: str | Path,
    prop: Proposal,
    cfg: RoverConfig,
    *,
    rate: float = 50.0,
    topic: str = DEFAULT_TOPIC,
    msg: str = "float64_multi_array",
    joint_names: tuple[str, ...] = DEFAULT_JOINT_NAMES,
    storage: str = "sqlite3",
    stem: str | None = None,
) -> tuple[Path, Path, Path, str]:
    """Write ``<stem>.csv``, ``<stem>_bag/`` and ``<stem>.md`` (stem: the plan's name) to
    ``out``; return their paths and the note's text."""
    if not re.fullmatch(rf"/{_TOKEN}(/{_TOKEN})*", topic):
        raise DrivePlanError(f"--topic {topic!r}: not an absolute ROS 2 topic name (/a/b_c)")
    if msg not in MSG_TYPES:
        raise DrivePlanError(f"--msg {msg!r}: one of {', '.join(MSG_TYPES)}")
    t, cmd, asked = command_rows(
        prop.plan, prop.seed, prop.duration, cfg.motor.max_wheel_speed, rate
    )
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    stem = stem or prop.plan
    csv_path = write_csv(out / f"{stem}.csv", t, cmd)
    bag_path = write_bag(out / f"{stem}_bag", t, cmd, topic, msg, joint_names, storage)
    layout = (
        f"`velocity` of joints {', '.join(joint_names)} (wheels 1L 1R 2L 2R)"
        if msg == "joint_state"
        else f"`data` = targets of wheels 1L 1R 2L 2R (layout dim label `{','.join(joint_names)}`)"
    )
    bag = {"storage": storage, "msgtype": MSG_TYPES[msg], "topic": topic, "layout": layout}
    files = {"csv": csv_path.name, "bag": bag_path.name}
    text = plan_markdown(prop, t, cmd, asked, cfg, files, bag, rate)
    md_path = out / f"{stem}.md"
    md_path.write_text(text)
    return csv_path, bag_path, md_path, text


def _cli(args: argparse.Namespace) -> int:
    try:
        joint_names = parse_joint_names(args.joint_names)
        if args.report is not None:
            if args.seed is not None or args.duration is not None:
                raise DrivePlanError(
                    "--seed and --duration come from the report; give them only with --plan"
                )
            props = proposals_from_report(args.report)
        else:
            if args.plan not in PLANS:
                raise DrivePlanError(f"unknown plan {args.plan!r}; plans: {', '.join(PLANS)}")
            seed = PLAN_SEED if args.seed is None else args.seed
            duration = PLAN_DURATION if args.duration is None else args.duration
            props = [Proposal(args.plan, seed, duration, _plan_why(args.plan))]
        cfg = load_rover(args.rover)
        plans = [p.plan for p in props]
        written: list[Path] = []
        for p in props:
            stem = p.plan if plans.count(p.plan) == 1 else f"{p.plan}_seed{p.seed}_{p.duration:g}s"
            *paths, text = write_plan(
                args.out,
                p,
                cfg,
                rate=args.rate,
                topic=args.topic,
                msg=args.msg,
                joint_names=joint_names,
                storage=args.storage,
                stem=stem,
            )
            print(text)
            written += paths
    except DrivePlanError as exc:
        print(f"rover-env drive-plan: error: {exc}", file=sys.stderr)
        return 2
    for path in written:
        print(f"wrote {path}")
    return 0


def add_cli(sub: Any) -> None:
    p = sub.add_parser(
        "drive-plan",
        help="a proposed drive (diagnose's tie or evidence) as commands for the real rover",
        description="Writes DIR/<plan>.csv (t, cmd_1L..cmd_2R, zero-order hold, last row a"
        " stop), DIR/<plan>_bag/ (a ROS 2 bag of the same commands at --rate) and"
        " DIR/<plan>.md (why, peak speeds, the ground it needs). Drive it, record it, import"
        " it (rover-env import-bag) and add it to rover-env diagnose's logs.",
    )
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--plan", metavar="NAME", help=f"one of {', '.join(PLANS)}")
    g.add_argument(
        "--report",
        metavar="DIR_OR_RESULT_JSON",
        help="a diagnose output: every drive it proposes, with its seed and duration",
    )
    p.add_argument("--seed", type=int, default=None, help=f"with --plan (default {PLAN_SEED})")
    p.add_argument(
        "--duration", type=float, default=None, help=f"s, with --plan (default {PLAN_DURATION:g})"
    )
    p.add_argument("--rover", default="proto_explorer", help="its max_wheel_speed and geometry")
    p.add_argument("--rate", type=float, default=50.0, help="command rows and messages per s")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--topic", default=DEFAULT_TOPIC, help=f"default {DEFAULT_TOPIC}")
    p.add_argument(
        "--msg",
        choices=tuple(MSG_TYPES),
        default="float64_multi_array",
        help="Float64MultiArray (ros2_control JointGroupVelocityController) or JointState",
    )
    p.add_argument(
        "--joint-names",
        metavar="1L=..,1R=..,2L=..,2R=..",
        default=None,
        help="the rover's wheel joints (JointState names; the Float64MultiArray label);"
        f" default {','.join(DEFAULT_JOINT_NAMES)}",
    )
    p.add_argument("--storage", choices=("sqlite3", "mcap"), default="sqlite3")
    p.set_defaults(func=_cli)
