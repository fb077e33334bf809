"""A simulated drive through a ROS 2 bag and back, then ``diagnose`` on both (issue 50).

    python benchmarks/bag_round_trip.py --out out/bag-round-trip [--no-diagnose]

make-logs writes SPEC §6 logs of a rover with a hidden effect (encoders, potentiometers,
1 Hz pose fixes); each log is published as a rover's driver would (``sensor_msgs/JointState``
of every wheel and joint with the example map's names and mirrored right-hand wheels,
``std_msgs/Float64MultiArray`` wheel-speed commands, ``nav_msgs/Odometry`` fixes at 1 Hz)
into a ROS 2 bag, imported with ``rover-env import-bag``'s library call, and compared column
by column with the direct log (max |difference| against the sensors' resolution). Then
``diagnose`` runs on the direct logs, on the imported ones, and on the direct logs given the
imported clock (the only column that differs, by the rounding of t), and every number of the
result.json files is compared (wall-clock figures aside). Exit status 0 when the imported
logs diagnose exactly as the direct logs on the same clock.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_typestore

from rover_env.bags import import_bag, load_topic_map
from rover_env.calibration.diagnose import Options, diagnose
from rover_env.config import JOINTS, WHEELS
from rover_env.generators.make_logs import make_logs
from rover_env.logs import DriveLog, read_log, write_log

BASE = 1_700_000_000 * 10**9  # a wall-clock start, as a real bag has
TRUTH = {"rolling_resistance": {"c_rr": 0.05}}


def _stamp(T: Any, ns: int) -> Any:
    return T["std_msgs/msg/Header"](
        stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9),
        frame_id="base_link",
    )


def write_bag(log: DriveLog, bag: Path, tmap: Any) -> None:
    """``log`` as a driver publishes it under ``tmap`` (signs applied in reverse)."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    names = list(tmap.wheels.names) + list(tmap.joints.names)
    wsign = np.array(tmap.wheels.sign)
    with Writer(bag, version=8) as w:
        js = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        cmd = w.add_connection("/wheel_cmd", "std_msgs/msg/Float64MultiArray", typestore=store)
        odom = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
        for k in range(len(log)):
            ns = BASE + round(float(log.t[k]) * 1e9)
            pos = np.concatenate([wsign * log.phi[k], log.theta[k]])
            msg = T["sensor_msgs/msg/JointState"](
                header=_stamp(T, ns), name=names, position=pos,
                velocity=np.zeros(0), effort=np.zeros(0),
            )  # fmt: skip
            w.write(js, ns, store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
            arr = T["std_msgs/msg/Float64MultiArray"](layout=layout, data=log.cmd[k].copy())
            w.write(cmd, ns, store.serialize_cdr(arr, "std_msgs/msg/Float64MultiArray"))
            if np.isfinite(log.pose[k, 0]):
                x, y, yaw = log.pose[k]
                pose = T["geometry_msgs/msg/Pose"](
                    position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                    orientation=T["geometry_msgs/msg/Quaternion"](
                        x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
                    ),
                )
                zero3 = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
                o = T["nav_msgs/msg/Odometry"](
                    header=_stamp(T, ns), child_frame_id="segment_3",
                    pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                    twist=T["geometry_msgs/msg/TwistWithCovariance"](
                        twist=T["geometry_msgs/msg/Twist"](linear=zero3, angular=zero3),
                        covariance=np.zeros(36),
                    ),
                )  # fmt: skip
                w.write(odom, ns, store.serialize_cdr(o, "nav_msgs/msg/Odometry"))


def topic_map(out: Path) -> Path:
    """The shipped example map with array commands and a 1 Hz odometry reference."""
    data = yaml.safe_load(load_topic_map("jointstate_imu_twist").path.read_text())  # type: ignore[union-attr]
    data["commands"] = {
        "topic": "/wheel_cmd",
        "type": "float64_multi_array",
        "order": ["1L", "1R", "2L", "2R"],
    }
    del data["yaw"]
    data["pose"] = {"topic": "/odom", "min_rate_hz": 0.5, "max_gap_s": 1.5}
    path = out / "topics.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _numbers(obj: Any, path: str = "") -> dict[str, Any]:
    if isinstance(obj, dict):
        out: dict[str, Any] = {}
        for k, v in obj.items():
            if not any(w in k for w in ("seconds", "wall", "elapsed", "replays")):
                out.update(_numbers(v, f"{path}.{k}"))
        return out
    if isinstance(obj, list):
        return {k: v for i, x in enumerate(obj) for k, v in _numbers(x, f"{path}[{i}]").items()}
    return {path: obj}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--out", default="out/bag-round-trip")
    p.add_argument("--no-diagnose", action="store_true")
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    direct = make_logs(out / "direct", TRUTH, drives=2, seed=11, duration=20.0, progress=False)
    mp = topic_map(out)
    imported = []
    for path in direct:
        bag = out / "bags" / path.stem
        if not bag.exists():
            write_bag(read_log(path), bag, load_topic_map(mp))
        log = import_bag(bag, mp)
        imported.append(write_log(log, out / "imported" / path.name, overwrite=True))
        a, b = read_log(path), read_log(imported[-1])
        print(f"{path.name}: {len(a)} samples direct, {len(b)} imported")
        print(f"  t: max |diff| {np.max(np.abs(a.t - b.t)):.3g} s")
        for name, cols in (("cmd", [f"cmd_{w}" for w in ("1L", "1R", "2L", "2R")]),
                           ("phi", [f"phi_{w}" for w in WHEELS]), ("theta", list(JOINTS)),
                           ("pose", ["x", "y", "yaw"])):  # fmt: skip
            da, db = getattr(a, name), getattr(b, name)
            same_nan = bool(np.array_equal(np.isnan(da), np.isnan(db)))
            diff = np.nanmax(np.abs(da - db), axis=0)
            print(f"  {name}: missing samples alike {same_nan}; max |diff| "
                  + ", ".join(f"{c} {d:.3g}" for c, d in zip(cols, diff, strict=True)))  # fmt: skip
    if args.no_diagnose:
        return 0
    runs = {"direct": direct, "imported": imported}
    # The direct logs with the imported clock and nothing else: separates what the clock's
    # rounding does (the simulator's t is n x 0.001 s, the import's the nearest double to
    # k / rate) from anything else the bag chain might change.
    retimed = []
    for path, imp in zip(direct, imported, strict=True):
        a, b = read_log(path), read_log(imp)
        a.t = b.t
        retimed.append(write_log(a, out / "retimed" / path.name, overwrite=True))
    runs["retimed"] = retimed
    numbers = {}
    for name, paths in runs.items():
        t0 = time.perf_counter()
        res = diagnose(
            paths, out / f"diagnose_{name}", Options(workers=args.workers, progress=False)
        )
        print(f"diagnose {name}: {time.perf_counter() - t0:.0f} s, named {res['named']}")
        result = json.loads((out / f"diagnose_{name}" / "result.json").read_text())
        numbers[name] = {k: v for k, v in _numbers(result).items() if k != ".config"}
    rc = 0
    for a, b in (("direct", "imported"), ("retimed", "imported")):
        na, nb = numbers[a], numbers[b]
        differ = [k for k in sorted(set(na) | set(nb)) if na.get(k) != nb.get(k)]
        rel = [
            abs(na[k] - nb[k]) / max(abs(na[k]), abs(nb[k]))
            for k in differ
            if isinstance(na.get(k), float) and isinstance(nb.get(k), float)
        ]
        worst = f", largest relative difference {max(rel):.2g}" if rel else ""
        print(f"result.json {a} vs {b}: {len(na)} values, {len(differ)} differ{worst}")
        for k in differ[:8]:
            print(f"  {k}: {na.get(k)!r} vs {nb.get(k)!r}")
        rc |= int(a == "retimed" and bool(differ))
    return rc


if __name__ == "__main__":
    sys.exit(main())
