"""rover-env import-bag: ROS bags -> SPEC §6 logs (rover_env.bags).

Bags are written here with rosbags' own writers (ROS 2 sqlite3 and MCAP, ROS 1), stamped on a
wall-clock epoch as real bags are. Sensor resolutions the round trip is held to are the
project's (rover_env.estimation.sensors): wheel encoders 0.01 rad per count, joint
potentiometers 340 deg / 1024 counts (5.8 mrad).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from rover_env.bags import BagError, import_bag, load_topic_map
from rover_env.cli import main
from rover_env.config import DRIVEN_WHEELS, JOINTS, WHEELS, configs_dir, load_rover
from rover_env.logs import LogError, read_log, write_log

EXAMPLE = configs_dir() / "bags" / "jointstate_imu_twist.yaml"
BASE = 1_700_000_000_123_000_000  # ns: a wall-clock epoch with a fractional second
MS = 1_000_000
GEO = load_rover("proto_explorer").geometry
WHEEL_RES = 0.01  # rad per count (SensorConfig.wheel_resolution)
JOINT_RES = math.radians(340.0) / 1024  # rad per count (SensorConfig.joint_resolution)


class Msgs:
    """Message constructors for one typestore (ROS 2 Humble or ROS 1 Noetic)."""

    def __init__(self, store: Stores = Stores.ROS2_HUMBLE) -> None:
        self.ts = get_typestore(store)
        self.ros1 = store == Stores.ROS1_NOETIC
        self.T = self.ts.types

    def header(self, ns: int) -> Any:
        stamp = self.T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        extra = {"seq": 0} if self.ros1 else {}
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id="base_link", **extra)

    def joint_state(self, ns: int, names: list[str], pos: Any, vel: Any = (), eff: Any = ()) -> Any:
        f = np.asarray
        return self.T["sensor_msgs/msg/JointState"](
            header=self.header(ns),
            name=list(names),
            position=f(pos, dtype=np.float64),
            velocity=f(vel, dtype=np.float64),
            effort=f(eff, dtype=np.float64),
        )

    def quat(self, q: Any) -> Any:
        w, x, y, z = (float(v) for v in q)
        return self.T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)

    def vec(self, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
        return self.T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    def imu(self, ns: int, q: Any, no_orientation: bool = False) -> Any:
        cov = np.zeros(9)
        cov[0] = -1.0 if no_orientation else 0.0
        return self.T["sensor_msgs/msg/Imu"](
            header=self.header(ns),
            orientation=self.quat(q),
            orientation_covariance=cov,
            angular_velocity=self.vec(),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=self.vec(),
            linear_acceleration_covariance=np.zeros(9),
        )

    def twist(self, v: float, w: float) -> Any:
        return self.T["geometry_msgs/msg/Twist"](linear=self.vec(v), angular=self.vec(z=w))

    def array(self, data: Any) -> Any:
        layout = self.T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
        return self.T["std_msgs/msg/Float64MultiArray"](
            layout=layout, data=np.asarray(data, dtype=np.float64)
        )

    def odometry(self, ns: int, p: Any, q: Any) -> Any:
        T = self.T
        point = T["geometry_msgs/msg/Point"](x=float(p[0]), y=float(p[1]), z=float(p[2]))
        pose = T["geometry_msgs/msg/Pose"](position=point, orientation=self.quat(q))
        twist = T["geometry_msgs/msg/Twist"](linear=self.vec(), angular=self.vec())
        return T["nav_msgs/msg/Odometry"](
            header=self.header(ns),
            child_frame_id="seg3",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)),
        )


Topics = dict[str, tuple[str, list[tuple[int, Any]]]]
"""topic -> (message type, [(receive ns, message)])."""


def write_bag(path: Path, topics: Topics, m: Msgs, storage: str = "sqlite3") -> Path:
    """Write ``topics`` as a bag, messages in receive order as a recorder would."""
    rows = sorted(
        (
            (ns, i, topic, msg)
            for topic, (_, msgs) in topics.items()
            for i, (ns, msg) in enumerate(msgs)
        ),
        key=lambda r: (r[0], r[1]),
    )
    if m.ros1:
        with Writer1(path) as w1:
            c1 = {t: w1.add_connection(t, mt, typestore=m.ts) for t, (mt, _) in topics.items()}
            for ns, _, topic, msg in rows:
                w1.write(c1[topic], ns, m.ts.serialize_ros1(msg, topics[topic][0]))
        return path
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {t: w.add_connection(t, mt, typestore=m.ts) for t, (mt, _) in topics.items()}
        for ns, _, topic, msg in rows:
            w.write(conns[topic], ns, m.ts.serialize_cdr(msg, topics[topic][0]))
    return path


def write_map(path: Path, edit: Callable[[dict[str, Any]], None]) -> Path:
    data = yaml.safe_load(EXAMPLE.read_text())
    edit(data)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def quat_z(yaw: float) -> np.ndarray:
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


# --------------------------------------------------------------------------- 1. round trip


def _vw(t: float) -> tuple[float, float]:
    """Twist schedule (m/s, rad/s), changing only on the 10 Hz command ticks (t = 1.5 s)."""
    return (0.15, 0.0) if t < 1.49 else (0.12, 0.45)


def _targets(t: float) -> np.ndarray:
    v, w = _vw(t)
    left, right = (
        (v - w * GEO.half_track) / GEO.wheel_radius,
        (v + w * GEO.half_track) / GEO.wheel_radius,
    )
    return np.array([left, right, left, right])


@pytest.fixture(scope="module")
def drive() -> dict[str, Any]:
    """A 3 s simulated drive at 50 Hz: the log read through the sensors, and the truth."""
    from rover_env.estimation.sensors import SensorConfig, apply_sensors
    from rover_env.sim.recorder import run_drive
    from rover_env.sim.simulator import RoverSim

    rec = run_drive(RoverSim(backend="auto"), _targets, duration=3.0, sample_rate_hz=50.0)
    log = rec.to_log("proto_explorer", terrain="flat", pose_rate_hz=None)
    # Joint noise off, so the sensor's only error is its resolution.
    direct = apply_sensors(log, SensorConfig(joint_noise=0.0), np.random.default_rng(0))
    truth = rec.truth()
    return {
        "log": log,
        "direct": direct,
        "pos": truth["seg_pos"][:, 2],
        "quat": truth["seg_quat"][:, 2],
    }


def _drive_topics(d: dict[str, Any], m: Msgs, variant: str) -> Topics:
    """The drive as its rover's driver would publish it under the variant's map."""
    direct, tmap = d["direct"], load_topic_map(EXAMPLE)
    grid = [BASE + k * 20 * MS for k in range(len(direct))]
    wsign, jnames = np.array(tmap.wheels.sign), list(tmap.joints.names)
    wheel_cnt = 2 * math.pi / 628
    zero = np.array([123.4, -50.0, 7.7, 1000.25, -3.0, 42.0])  # the counters' start (rad)
    js, cmd, state = [], [], []
    for k, ns in enumerate(grid):
        phi, theta = direct.phi[k], direct.theta[k]
        if variant == "example":
            wheels = wsign * phi
        else:  # ticks counters wrapped to one turn; joints in degrees, theta_2 mirrored, theta_3 trimmed
            wheels = np.mod(wsign * (phi + zero) / wheel_cnt, 628.0)
            theta = np.degrees(theta * np.array([1, -1, 1, 1, 1]) + np.array([0, 0, 0.02, 0, 0]))
        pos = np.concatenate([wheels, theta])
        js.append((ns + 2 * MS, m.joint_state(ns, list(tmap.wheels.names) + jnames, pos)))
        if variant == "example":
            state.append((ns + MS, m.imu(ns, d["quat"][k])))
            if k % 5 == 0:  # teleop at 10 Hz, no header: the receive time is the stamp
                cmd.append((ns, m.twist(*_vw(float(direct.t[k])))))
        else:
            state.append((ns + MS, m.odometry(ns, d["pos"][k], d["quat"][k])))
            rpm = direct.cmd[k] * 30 / math.pi * np.array([1, 1, -1, 1])  # 2L mirrored
            cmd.append((ns, m.array([rpm[3], 99.0, rpm[0], rpm[1], rpm[2]])))
    J = "sensor_msgs/msg/JointState"
    if variant == "example":
        return {
            "/joint_states": (J, js),
            "/imu/data": ("sensor_msgs/msg/Imu", state),
            "/cmd_vel": ("geometry_msgs/msg/Twist", cmd),
        }
    return {
        "/joint_states": (J, js),
        "/odom": ("nav_msgs/msg/Odometry", state),
        "/wheel_cmd": ("std_msgs/msg/Float64MultiArray", cmd),
    }


def _variant_map(data: dict[str, Any]) -> None:
    data["wheels"].update(unit="ticks", ticks_per_rev=628, wrapped=True)
    data["joints"].update(unit="deg", sign={"theta_2": -1}, offset={"theta_3": 0.02})
    data["commands"] = {
        "topic": "/wheel_cmd",
        "type": "float64_multi_array",
        "order": ["2R", None, "1L", "1R", "2L"],
        "unit": "rpm",
        "sign": {"2L": -1},
    }
    del data["yaw"]
    data["pose"] = {"topic": "/odom"}


@pytest.mark.parametrize("variant", ["example", "ticks_deg_array_odom_mcap"])
def test_round_trip(drive: dict[str, Any], variant: str, tmp_path: Path) -> None:
    m = Msgs()
    example = variant == "example"
    storage = "sqlite3" if example else "mcap"
    bag = write_bag(tmp_path / "bag", _drive_topics(drive, m, variant), m, storage)
    tmap = EXAMPLE if example else write_map(tmp_path / "map.yaml", _variant_map)
    log, direct, sim = import_bag(bag, tmap), drive["direct"], drive["log"]
    assert len(log) == len(direct) == 151
    # The clock: t_k = k / 50 from the first state stamp, computed in integer ns.
    np.testing.assert_array_equal(log.t, np.arange(151) * 20 * MS / 1e9)
    np.testing.assert_allclose(log.t, direct.t, rtol=0, atol=1e-12)
    if example:
        # Stamps on the grid, rad, signs +-1, no offsets: the data itself, bit for bit.
        np.testing.assert_array_equal(log.phi, direct.phi)
        np.testing.assert_array_equal(log.theta, direct.theta)
        # Twist -> (v -+ omega * half_track) / wheel_radius: the schedule's own formula, held
        # from the 10 Hz messages; equal to float rounding.
        np.testing.assert_allclose(log.cmd, direct.cmd, rtol=1e-12, atol=1e-12)
        assert np.all(np.isnan(log.pose[:, :2]))
        np.testing.assert_allclose(log.pose[:, 2], sim.pose[:, 2], rtol=0, atol=1e-9)
    else:
        # Unit conversions, counter start, wrapping and offsets cost float rounding only.
        np.testing.assert_allclose(log.phi, direct.phi, rtol=0, atol=1e-9)
        np.testing.assert_allclose(log.theta, direct.theta, rtol=0, atol=1e-12)
        np.testing.assert_allclose(log.cmd, direct.cmd, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(log.pose, sim.pose, rtol=0, atol=1e-9)
    # Against the simulator's exact angles: within half a count of the sensors' resolution.
    assert np.max(np.abs(log.phi - sim.phi)) <= WHEEL_RES / 2 + 1e-9
    assert np.max(np.abs(log.theta - sim.theta)) <= JOINT_RES / 2 + 1e-9
    assert log.phi[0].tolist() == [0.0] * 6 and log.pose[0, 2] == 0.0
    assert log.meta.rover == "proto_explorer" and log.meta.sample_rate_hz == 50.0
    assert "imported from bag bag" in (log.meta.notes or "")


def test_a_sparse_pose_reference_stays_sparse(drive: dict[str, Any], tmp_path: Path) -> None:
    """A 1 Hz external reference (as make-logs writes, SPEC §6) keeps its fixes at their
    samples and leaves the rest empty: interpolating it would invent a path between fixes."""
    m = Msgs()
    topics = _drive_topics(drive, m, "ticks_deg_array_odom_mcap")
    odom_type, odom = topics["/odom"]
    topics["/odom"] = (odom_type, odom[::50])  # 1 Hz: t = 0, 1, 2, 3 s

    def sparse_map(data: dict[str, Any]) -> None:
        _variant_map(data)
        data["pose"].update(min_rate_hz=0.5, max_gap_s=1.5)

    log = import_bag(
        write_bag(tmp_path / "bag", topics, m), write_map(tmp_path / "m.yaml", sparse_map)
    )
    have = np.flatnonzero(np.isfinite(log.pose[:, 0]))
    assert have.tolist() == [0, 50, 100, 150]
    np.testing.assert_allclose(log.pose[have], drive["log"].pose[have], rtol=0, atol=1e-9)
    assert np.all(np.isnan(log.pose[np.isnan(log.pose[:, 0])]))


def test_ros1_bag_reads_like_ros2(tmp_path: Path) -> None:
    """The same synthetic drive as a ROS 1 .bag and a ROS 2 bag imports to the same log."""
    logs = []
    for store, path in (
        (Stores.ROS1_NOETIC, tmp_path / "d.bag"),
        (Stores.ROS2_HUMBLE, tmp_path / "d2"),
    ):
        m = Msgs(store)
        logs.append(import_bag(write_bag(path, _synthetic(m), m), EXAMPLE))
    for name in ("t", "cmd", "phi", "theta", "pose"):
        np.testing.assert_array_equal(getattr(logs[0], name), getattr(logs[1], name))


# --------------------------------------------------------------------------- 2. resampling


def test_off_grid_states_interpolated_commands_held(tmp_path: Path) -> None:
    m = Msgs()
    tmap = load_topic_map(EXAMPLE)
    names = list(tmap.wheels.names) + list(tmap.joints.names)
    slope = np.array([2.0, -1.5, 2.5, -3.0, 1.0, -0.5, 0.1, -0.2, 0.05, 0.3, -0.1])  # per s
    icpt = np.array([5.0, 4.0, -3.0, 2.0, 1.0, 0.0, 0.2, -0.1, 0.0, 0.05, 0.3])
    js = []  # 20 Hz, header 7 ms off the grid, received 2 ms later
    for i in range(61):
        ns = BASE + 7 * MS + i * 50 * MS
        js.append((ns + 2 * MS, m.joint_state(ns, names, slope * (ns - BASE) / 1e9 + icpt)))
    imu = []  # 25 Hz by receive time (map: stamp receive); headers left unfilled (0)
    for i in range(76):
        ns = BASE + 3 * MS + i * 40 * MS
        imu.append((ns, m.imu(0, quat_z(0.2 * (ns - BASE) / 1e9 + 3.0))))
    cmd_at = [13, 400, 410, 1237, 1240, 2000]  # ms; the first sets the start
    cmd = [(BASE + t * MS, m.twist(0.01 * (i + 1), 0.0)) for i, t in enumerate(cmd_at)]
    topics = {
        "/joint_states": ("sensor_msgs/msg/JointState", js),
        "/imu/data": ("sensor_msgs/msg/Imu", imu),
        "/cmd_vel": ("geometry_msgs/msg/Twist", cmd),
    }
    bag = write_bag(tmp_path / "bag", topics, m)
    mp = write_map(tmp_path / "map.yaml", lambda d: d["yaw"].update(stamp="receive"))
    summary: list[str] = []
    log = import_bag(bag, mp, summary=summary)
    start = 13 * MS  # latest first stamp: the first command (states start at 7 and 3 ms)
    end = 7 * MS + 60 * 50 * MS  # earliest last stamp: the joint states' (3.007 s)
    n = (end - start) // (20 * MS) + 1
    assert len(log) == n == 150
    np.testing.assert_array_equal(log.t, np.arange(n) * 20 * MS / 1e9)
    t_abs = (start + np.arange(n) * 20 * MS) / 1e9  # s after BASE
    expect = slope * t_abs[:, None] + icpt
    # Linear ramps are reproduced by linear interpolation, up to float rounding.
    sign = np.array(tmap.wheels.sign)  # the map's right-hand wheels are mirrored
    np.testing.assert_allclose(log.phi, sign * (expect - expect[0])[:, :6], rtol=0, atol=1e-9)
    np.testing.assert_allclose(log.theta, expect[:, 6:], rtol=0, atol=1e-12)
    np.testing.assert_allclose(log.pose[:, 2], 0.2 * log.t, rtol=0, atol=1e-9)
    # Zero-order hold: the last command at or before t (t = 0 is the first command).
    v = {
        0.0: 0.01,
        0.38: 0.01,
        0.4: 0.03,
        1.22: 0.03,
        1.24: 0.05,
        1.98: 0.05,
        2.0: 0.06,
        2.98: 0.06,
    }
    for t, speed in v.items():
        k = round(t * 50)
        assert log.t[k] == pytest.approx(t) and t_abs[k] == pytest.approx(t + 0.013)
        held = speed / GEO.wheel_radius
        np.testing.assert_allclose(log.cmd[k], held, rtol=1e-12, err_msg=f"t = {t}")
    text = "\n".join(summary)
    assert "150 samples at 50 Hz" in text and "/joint_states -> wheels: 61 messages" in text
    assert "median rate 25 Hz, receive stamps" in text and "zero-order hold: commands" in text


def test_the_wheel_clock_keeps_encoder_counts_whole(tmp_path: Path) -> None:
    """Wheel messages at 50 Hz, stamped 0-6 ms off an even grid, carrying whole counts: on
    the grid clock the interpolated angles are fractions of a count (diagnose would read the
    encoders as unquantised); on the wheel clock the rows are the messages themselves."""
    from rover_env.calibration.residuals import resolution

    m = Msgs()
    tmap = load_topic_map(EXAMPLE)
    names = list(tmap.wheels.names) + list(tmap.joints.names)
    rng = np.random.default_rng(5)
    ns = BASE + np.arange(151) * 20 * MS + rng.integers(0, 6 * MS, 151)
    true = 3.0 * (ns - BASE)[:, None] / 1e9 * np.ones(6)  # 3 rad/s: 6 counts a sample
    counts = np.round(true / WHEEL_RES) * WHEEL_RES
    js = [
        (int(n), m.joint_state(int(n), names, np.r_[c, np.zeros(5)]))
        for n, c in zip(ns, counts, strict=True)
    ]
    imu = [(int(n), m.imu(int(n), quat_z(0.0))) for n in BASE + np.arange(151) * 20 * MS]
    cmd = [(BASE, m.twist(0.2, 0.0))]
    topics = {
        "/joint_states": ("sensor_msgs/msg/JointState", js),
        "/imu/data": ("sensor_msgs/msg/Imu", imu),
        "/cmd_vel": ("geometry_msgs/msg/Twist", cmd),
    }
    bag = write_bag(tmp_path / "bag", topics, m)
    sign = np.array(tmap.wheels.sign)
    on_grid = import_bag(bag, EXAMPLE)
    assert resolution(on_grid.phi) < WHEEL_RES / 2  # smoothed: no whole count found
    summary: list[str] = []
    own = import_bag(bag, EXAMPLE, clock="wheels", summary=summary)
    kept = ns <= BASE + 150 * 20 * MS  # the imu's last message ends the span
    np.testing.assert_array_equal(own.t, (ns[kept] - ns[0]) / 1e9)
    np.testing.assert_allclose(own.phi, sign * (counts[kept] - counts[0]), rtol=0, atol=1e-12)
    assert resolution(own.phi) == pytest.approx(WHEEL_RES, rel=1e-6)
    assert own.meta.sample_rate_hz == pytest.approx(50.0, rel=0.01)
    assert "rows at the wheel topic's stamps" in "\n".join(summary)
    with pytest.raises(BagError, match="exclude each other"):
        import_bag(bag, EXAMPLE, clock="wheels", rate_hz=25.0)
    with pytest.raises(BagError, match="clock must be one of"):
        import_bag(bag, EXAMPLE, clock="nearest")


def test_two_publishers_on_one_topic_and_command_timeout(tmp_path: Path) -> None:
    """Wheels and joints published as separate JointStates on /joint_states; a watchdog."""
    m = Msgs()
    tp = _synthetic(m)
    split = []
    for ns, msg in tp["/joint_states"][1]:
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        split.append((ns, m.joint_state(stamp, msg.name[:6], msg.position[:6])))
        split.append((ns + 1000, m.joint_state(stamp, msg.name[6:], msg.position[6:] + 0.1)))
    tp["/joint_states"] = (tp["/joint_states"][0], split)
    tp["/cmd_vel"] = (tp["/cmd_vel"][0], tp["/cmd_vel"][1][:2])  # 0 and 0.1 s, then silence
    mp = write_map(tmp_path / "map.yaml", lambda d: d["commands"].update(timeout_s=0.5))
    summary: list[str] = []
    log = import_bag(write_bag(tmp_path / "bag", tp, m), mp, summary=summary)
    np.testing.assert_allclose(log.phi[:, 0], 2.0 * log.t, atol=1e-12)
    np.testing.assert_allclose(log.theta, 0.1, atol=0)
    # Held up to 0.1 s + 0.5 s, then 0 (older than timeout_s).
    np.testing.assert_allclose(log.cmd[log.t <= 0.6], 0.1 / GEO.wheel_radius, rtol=1e-12)
    assert np.all(log.cmd[log.t > 0.6 + 1e-9] == 0.0) and len(log) == 101
    assert (
        "/joint_states -> wheels: 202 messages (101 used, the rest another publisher's)"
        in summary[1]
    )


def _with_effort(m: Msgs, tp: Topics, n: int | None = None) -> None:
    """Joint states carrying effort: joint j at t s reads (j + 1) / 10 + 0.5 t (the first
    ``n`` entries only, if given: an effort array of the wrong length)."""
    out = []
    for ns, msg in tp["/joint_states"][1]:
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        eff = (np.arange(len(msg.name)) + 1) / 10 + 0.5 * (stamp - BASE) / 1e9
        out.append((ns, m.joint_state(stamp, msg.name, msg.position, (), eff[:n])))
    tp["/joint_states"] = (tp["/joint_states"][0], out)


def test_effort_on_the_wheel_topic(tmp_path: Path) -> None:
    """An effort section on the wheels' topic: names and signs default to the wheels' (1R 2R
    mirrored), a sign given overrides one wheel, scale applies; the log keeps it to CSV."""
    m = Msgs()
    tp = _synthetic(m)
    _with_effort(m, tp)
    bag = write_bag(tmp_path / "bag", tp, m)
    effort = {"topic": "/joint_states", "scale": 2.5, "sign": {"2L": -1}}
    mp = write_map(tmp_path / "map.yaml", _set("effort", effort))
    summary: list[str] = []
    log = import_bag(bag, mp, summary=summary)
    # The driven wheels are the message's first four joints; the stamps lie on the grid.
    raw = np.arange(1, 5) / 10 + 0.5 * log.t[:, None]
    expect = raw * 2.5 * np.array([1.0, -1.0, -1.0, -1.0])
    np.testing.assert_allclose(log.effort, expect, rtol=1e-12, atol=1e-12)
    assert "/joint_states -> effort: 101 messages" in "\n".join(summary)
    back = read_log(write_log(log, tmp_path / "logs" / "d.csv"))
    np.testing.assert_array_equal(back.effort, log.effort)
    # The same bag without an effort section: no effort in the log.
    assert log.has_effort and not import_bag(bag, EXAMPLE).has_effort


# --------------------------------------------------------------------------- 3. bad bags


def _synthetic(m: Msgs, seconds: float = 2.0) -> Topics:
    """A good small bag under the example map: 50 Hz joint states and IMU, 10 Hz twist."""
    tmap = load_topic_map(EXAMPLE)
    names = list(tmap.wheels.names) + list(tmap.joints.names)
    js, imu, cmd = [], [], []
    for k in range(round(seconds * 50) + 1):
        ns, t = BASE + k * 20 * MS, k / 50
        js.append((ns + MS, m.joint_state(ns, names, np.r_[np.full(6, 2.0 * t), np.zeros(5)])))
        imu.append((ns + MS, m.imu(ns, quat_z(0.1 * t))))
        if k % 5 == 0:
            cmd.append((ns, m.twist(0.1, 0.0)))
    return {
        "/joint_states": ("sensor_msgs/msg/JointState", js),
        "/imu/data": ("sensor_msgs/msg/Imu", imu),
        "/cmd_vel": ("geometry_msgs/msg/Twist", cmd),
    }


def _drop_name(m: Msgs, tp: Topics) -> None:
    ns, msg = tp["/joint_states"][1][17]
    keep = [i for i, n in enumerate(msg.name) if n != "wheel_rear_right_joint"]
    tp["/joint_states"][1][17] = (
        ns,
        m.joint_state(BASE + 17 * 20 * MS, [msg.name[i] for i in keep], msg.position[keep]),
    )


def _wheel_cmd_without_velocity(m: Msgs, tp: Topics) -> None:
    names = [
        "wheel_front_left_joint",
        "wheel_front_right_joint",
        "wheel_middle_left_joint",
        "wheel_middle_right_joint",
    ]
    tp["/wheel_cmd"] = (
        "sensor_msgs/msg/JointState",
        [
            (BASE + i * 100 * MS, m.joint_state(BASE + i * 100 * MS, names, [], []))
            for i in range(21)
        ],
    )


def _swap_imu(m: Msgs, tp: Topics) -> None:
    msgs = tp["/imu/data"][1]
    (a, ma), (b, mb) = msgs[30], msgs[31]
    msgs[30], msgs[31] = (a, mb), (b, ma)  # received in order, stamped out of order


def _gap(m: Msgs, tp: Topics) -> None:
    msgs = tp["/joint_states"][1]
    tp["/joint_states"] = (tp["/joint_states"][0], msgs[:50] + msgs[70:])  # 1.0 s .. 1.4 s lost


def _slow_imu(m: Msgs, tp: Topics) -> None:
    tp["/imu/data"] = (tp["/imu/data"][0], tp["/imu/data"][1][::10])  # 5 Hz


def _late_imu(m: Msgs, tp: Topics) -> None:
    tp["/imu/data"] = (
        "sensor_msgs/msg/Imu",
        [
            (BASE + (5000 + 20 * k) * MS, m.imu(BASE + (5000 + 20 * k) * MS, quat_z(0.0)))
            for k in range(60)
        ],
    )


def _array_cmd(m: Msgs, tp: Topics) -> None:
    tp["/cmd_vel"] = ("std_msgs/msg/Float64MultiArray", [(BASE, m.array([1.0, 1.0, 1.0, 1.0]))])


def _unstamped(m: Msgs, tp: Topics) -> None:
    tp["/imu/data"] = (
        "sensor_msgs/msg/Imu",
        [(ns, m.imu(0, quat_z(0.0))) for ns, _ in tp["/imu/data"][1]],
    )


def _no_orientation(m: Msgs, tp: Topics) -> None:
    tp["/imu/data"][1][4] = (
        tp["/imu/data"][1][4][0],
        m.imu(BASE + 80 * MS, quat_z(0.0), no_orientation=True),
    )


def _jointstate_cmd(d: dict[str, Any]) -> None:
    d["commands"] = {
        "topic": "/wheel_cmd",
        "type": "joint_state",
        "names": {
            "1L": "wheel_front_left_joint",
            "1R": "wheel_front_right_joint",
            "2L": "wheel_middle_left_joint",
            "2R": "wheel_middle_right_joint",
        },
    }


BAD_BAGS = {
    "missing topic": (
        lambda m, tp: tp.pop("/imu/data"),
        None,
        ["'/imu/data'", "map key 'yaw'", "not in the bag", "/cmd_vel"],
    ),
    "missing joint name": (
        _drop_name,
        None,
        [
            "'/joint_states'",
            "message 17",
            "'wheel_rear_right_joint'",
            "'wheels.names.3R'",
            "stamp 1700000000.463000000 s",
        ],
    ),
    "missing field": (
        _wheel_cmd_without_velocity,
        _jointstate_cmd,
        [
            "'/wheel_cmd'",
            "message 0",
            "field 'velocity' is missing (empty); map key 'commands' reads it",
        ],
    ),
    "stamps out of order": (
        _swap_imu,
        None,
        [
            "'/imu/data'",
            "out of order",
            "message 30 at stamp 1700000000.743000000 s",
            "message 31 at stamp 1700000000.723000000 s",
        ],
    ),
    "gap too long": (
        _gap,
        None,
        [
            "'/joint_states'",
            "gap of 0.420 s",
            "max_gap_s 0.25",
            "stamp 1700000001.103000000 s",
            "t = 0.980 s",
        ],
    ),
    "rate too low": (_slow_imu, None, ["'/imu/data'", "median rate 5 Hz", "min_rate_hz 10"]),
    "wrong message type": (
        _array_cmd,
        None,
        [
            "'/cmd_vel'",
            "carries std_msgs/msg/Float64MultiArray",
            "map key 'commands'",
            "geometry_msgs/msg/Twist",
        ],
    ),
    "no overlap": (
        _late_imu,
        None,
        [
            "do not overlap",
            "/imu/data (yaw) stamp 1700000005.123000000 s",
            "/joint_states (wheels)",
        ],
    ),
    "unfilled header stamp": (
        _unstamped,
        None,
        ["'/imu/data'", "header.stamp is 0", "'yaw.stamp: receive'"],
    ),
    "imu without orientation": (
        _no_orientation,
        None,
        ["'/imu/data'", "message 4", "orientation_covariance[0] = -1"],
    ),
    "empty effort": (
        lambda m, tp: None,
        lambda d: d.update(effort={"topic": "/joint_states"}),
        ["'/joint_states'", "message 0", "field 'effort' is missing (empty); map key 'effort'"],
    ),
    "effort of the wrong length": (
        lambda m, tp: _with_effort(m, tp, 3),
        lambda d: d.update(effort={"topic": "/joint_states"}),
        ["'/joint_states'", "message 0", "'effort' has 3 entries for 11 names; map key 'effort'"],
    ),
    "bad map key": (
        lambda m, tp: None,
        lambda d: d["wheels"].update(unit="radians"),
        ["map.yaml", "'wheels.unit'", "rad, deg, rev, ticks", "'radians'"],
    ),
}


@pytest.mark.parametrize("case", list(BAD_BAGS))
def test_bad_bag_is_refused_by_name(case: str, tmp_path: Path) -> None:
    mutate, edit_map, expected = BAD_BAGS[case]
    m = Msgs()
    tp = _synthetic(m)
    mutate(m, tp)
    bag = write_bag(tmp_path / "bag", tp, m)
    mp = write_map(tmp_path / "map.yaml", edit_map or (lambda d: None))
    with pytest.raises(BagError) as err:
        import_bag(bag, mp)
    msg = str(err.value)
    assert isinstance(err.value, LogError)
    assert msg.startswith(str(mp if case == "bad map key" else bag)), msg
    for part in expected:
        assert part in msg, f"{part!r} not in {msg!r}"


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    def edit(d: dict[str, Any]) -> None:
        *head, last = path.split(".")
        for key in head:
            d = d[key]
        if value is KeyError:
            del d[last]
        else:
            d[last] = value

    return edit


BAD_MAPS = {
    "missing rover": (_set("rover", KeyError), "key 'rover': missing"),
    "unknown key": (_set("wheels.wraped", True), "key 'wheels.wraped': unknown key"),
    "missing wheel name": (_set("wheels.names.3R", KeyError), "key 'wheels.names.3R': missing"),
    "not a wheel": (_set("wheels.sign.4L", -1), "key 'wheels.sign.4L': not one of 1L"),
    "bad sign": (_set("wheels.sign.1R", 2), "key 'wheels.sign.1R': must be 1 or -1"),
    "ticks without ticks_per_rev": (
        _set("wheels.unit", "ticks"),
        "key 'wheels.ticks_per_rev': missing",
    ),
    "offset on wheels": (_set("wheels.offset", {"1L": 0.1}), "key 'wheels.offset': unknown key"),
    "bad joint unit": (_set("joints.unit", "rev"), "key 'joints.unit': must be one of rad, deg"),
    "bad command type": (
        _set("commands.type", "ackermann"),
        "key 'commands.type': must be one of twist",
    ),
    "negative rate": (_set("rate_hz", -5), "key 'rate_hz': must be > 0"),
    "bad stamp": (_set("yaw.stamp", "bag"), "key 'yaw.stamp': must be one of header, receive"),
    "yaw and pose": (_set("pose", {"topic": "/odom"}), "key 'yaw': give yaw or pose, not both"),
    "effort scale a string": (
        _set("effort", {"topic": "/joint_states", "scale": "2 Nm/A"}),
        "key 'effort.scale': must be a finite number, got '2 Nm/A'",
    ),
    "negative effort scale": (
        _set("effort", {"topic": "/joint_states", "scale": -0.5}),
        "key 'effort.scale': must be > 0",
    ),
    "effort names off the wheel topic": (
        _set("effort", {"topic": "/motor_states"}),
        "key 'effort.names': missing",
    ),
    "unknown effort key": (
        _set("effort", {"topic": "/joint_states", "unit": "Nm"}),
        "key 'effort.unit': unknown key",
    ),
    "duplicate joint": (
        _set("joints.names.theta_2", "roll_12_joint"),
        "key 'joints.names': joint name 'roll_12_joint' given for two",
    ),
}


@pytest.mark.parametrize("case", list(BAD_MAPS))
def test_bad_map_key_is_refused_by_name(case: str, tmp_path: Path) -> None:
    edit, expected = BAD_MAPS[case]
    mp = write_map(tmp_path / "map.yaml", edit)
    with pytest.raises(BagError) as err:
        load_topic_map(mp)
    assert str(err.value).startswith(f"{mp}: "), str(err.value)
    assert expected in str(err.value), str(err.value)


def test_shipped_map_loads_by_name() -> None:
    tmap = load_topic_map("jointstate_imu_twist")
    assert tmap.path == EXAMPLE and tmap.commands.type == "twist" and tmap.yaw is not None
    assert tmap.wheels.sign == (1.0, -1.0, 1.0, -1.0, 1.0, -1.0) and len(tmap.joints.names) == len(
        JOINTS
    )
    assert len(tmap.wheels.names) == len(WHEELS) and len(DRIVEN_WHEELS) == 4


# --------------------------------------------------------------------------- 4. command line


def test_cli_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    m = Msgs()
    bag = write_bag(tmp_path / "bag_mcap", _synthetic(m), m, "mcap")
    out = tmp_path / "logs"
    first = ["import-bag", str(bag), "--map", "jointstate_imu_twist", "--out", str(out)]
    first += ["--name", "run1"]
    rc = main(first)
    text = capsys.readouterr().out
    assert rc == 0, text
    log = read_log(out / "run1.csv")
    assert len(log) == 101 and log.meta.rover == "proto_explorer" and log.meta.terrain == "flat"
    np.testing.assert_allclose(log.phi[:, 0], 2.0 * log.t, atol=1e-12)
    np.testing.assert_allclose(log.cmd, 0.1 / GEO.wheel_radius, rtol=1e-12)
    for part in (
        "101 samples at 50 Hz, 2.000 s",
        "/joint_states -> wheels: 101 messages",
        "/cmd_vel -> commands: 21 messages, median rate 10 Hz",
        "linear interpolation: wheels, joints, yaw",
    ):
        assert part in text, text
    # Same again at another rate into the same file: refused without --overwrite.
    again = [*first, "--rate", "25"]
    assert main(again) == 2
    assert main([*again, "--overwrite"]) == 0 and len(read_log(out / "run1.csv")) == 51
    # A bad bag: return code 2, the reason on stderr.
    tp = _synthetic(m)
    _gap(m, tp)
    bad = write_bag(tmp_path / "bad", tp, m)
    capsys.readouterr()
    assert main(["import-bag", str(bad), "--map", str(EXAMPLE), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rover-env import-bag: ") and "gap of 0.420 s" in err
    assert not (out / "drive.csv").exists()
