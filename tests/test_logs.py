"""Drive logs (SPEC §6): exact round trip, precise errors for bad files, and recorded drives."""

from __future__ import annotations

import math
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rover_env.logs import (
    CMD_COLUMNS,
    PHI_COLUMNS,
    POSE_COLUMNS,
    REQUIRED_COLUMNS,
    THETA_COLUMNS,
    DriveLog,
    LogError,
    LogMeta,
    read_log,
    write_log,
)

# --------------------------------------------------------------------------- helpers


def make_log(n: int = 6, seed: int = 0, pose: bool = True) -> DriveLog:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.001, 0.1, n)) - 0.05
    t[0] = 0.0
    p = rng.normal(size=(n, 3)) if pose else np.full((n, 3), np.nan)
    if pose:
        p[1::2] = np.nan
    cmd = rng.normal(size=(n, 4))
    cmd[0, 0] = -0.0
    cmd[1, 1] = 5e-324  # smallest subnormal
    cmd[2, 2] = 1 / 3
    return DriveLog(
        t=t,
        cmd=cmd,
        phi=np.cumsum(rng.uniform(0, 0.1, (n, 6)), axis=0),
        theta=rng.normal(scale=0.1, size=(n, 5)),
        pose=p,
        meta=LogMeta(
            rover="proto_explorer",
            sample_rate_hz=50.0,
            terrain={"name": "flat", "mu_x": 0.8},
            notes="unit test: ünïcode ok",
        ),
    )


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal to the last bit, NaN positions included (array_equal treats -0.0 == 0.0)."""
    if a.shape != b.shape:
        return False
    na, nb = np.isnan(a), np.isnan(b)
    return bool(np.array_equal(na, nb) and a[~na].tobytes() == b[~nb].tobytes())


def assert_logs_identical(a: DriveLog, b: DriveLog) -> None:
    for name in ("t", "cmd", "phi", "theta", "pose"):
        assert same_bits(getattr(a, name), getattr(b, name)), name
    assert a.meta == b.meta


def good_table(n: int = 4, pose: bool = False) -> dict[str, list[str]]:
    cols = list(REQUIRED_COLUMNS) + (list(POSE_COLUMNS) if pose else [])
    table = {c: [repr(0.1 * k + 0.01 * j) for k in range(n)] for j, c in enumerate(cols)}
    table["t"] = [repr(0.02 * k) for k in range(n)]
    return table


def write_raw(
    folder: Path,
    table: dict[str, list[str]] | None = None,
    yaml_text: str | None = "rover: proto_explorer\nsample_rate_hz: 50\n",
    csv_text: str | None = None,
    stem: str = "drive",
) -> Path:
    path = folder / f"{stem}.csv"
    if csv_text is None and table is not None:
        cols = list(table)
        n = len(table[cols[0]])
        lines = [",".join(cols)] + [",".join(table[c][k] for c in cols) for k in range(n)]
        csv_text = "\n".join(lines) + "\n"
    if csv_text is not None:
        path.write_text(csv_text)
    if yaml_text is not None:
        path.with_suffix(".yaml").write_text(yaml_text)
    return path


# --------------------------------------------------------------------------- round trip


def test_round_trip_exact(tmp_path: Path) -> None:
    log = make_log(n=9)
    path = write_log(log, tmp_path / "drive.csv")
    assert path == tmp_path / "drive.csv"
    assert (tmp_path / "drive.yaml").is_file()
    back = read_log(path)
    assert_logs_identical(log, back)
    assert back.path == path
    # Not-measured pose is written as an empty cell, not "nan".
    assert "nan" not in path.read_text().lower()
    assert ",," in path.read_text() or path.read_text().count(",\n") > 0


def test_round_trip_without_pose_omits_columns(tmp_path: Path) -> None:
    log = make_log(pose=False)
    path = write_log(log, tmp_path / "d.csv")
    header = path.read_text().splitlines()[0].split(",")
    assert header == list(REQUIRED_COLUMNS)
    back = read_log(path)
    assert not back.has_pose
    assert_logs_identical(log, back)


@settings(max_examples=25, deadline=None)
@given(
    values=st.lists(
        st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=18, max_size=18
    ),
    n=st.integers(2, 5),
)
def test_round_trip_any_finite_float(values: list[float], n: int) -> None:
    row = np.array(values)
    log = DriveLog(
        t=np.arange(n) * 0.5 + 1e-300,
        cmd=np.tile(row[:4], (n, 1)),
        phi=np.tile(row[4:10], (n, 1)),
        theta=np.tile(row[10:15], (n, 1)),
        pose=np.tile(row[15:18], (n, 1)),
        meta=LogMeta(rover="r", sample_rate_hz=float(np.nextafter(2.0, 3.0))),
    )
    with tempfile.TemporaryDirectory() as d:
        back = read_log(write_log(log, Path(d) / "x.csv"))
    assert_logs_identical(log, back)


def test_column_order_is_free_and_empty_pose_cells_are_nan(tmp_path: Path) -> None:
    table = good_table(n=3, pose=True)
    table["yaw"][1] = ""
    table["x"][2] = ""
    shuffled = dict(reversed(list(table.items())))
    log = read_log(write_raw(tmp_path, shuffled))
    ref = read_log(write_raw(tmp_path, table, stem="ordered"))
    assert_logs_identical(log, ref)
    assert np.isnan(log.pose[1, 2]) and np.isnan(log.pose[2, 0])
    assert log.pose[0, 0] == float(table["x"][0])
    assert log.theta[2, 4] == float(table["theta_5"][2])


def test_write_refuses_a_different_existing_log(tmp_path: Path) -> None:
    a, b = make_log(seed=1), make_log(seed=2)
    path = write_log(a, tmp_path / "drive.csv")
    write_log(a, path)  # identical content: allowed
    with pytest.raises(FileExistsError, match="drive"):
        write_log(b, path)
    assert_logs_identical(read_log(path), a)
    write_log(b, path, overwrite=True)
    assert_logs_identical(read_log(path), b)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drive.csv", "drive.yaml"]


def test_write_refuses_yaml_path(tmp_path: Path) -> None:
    with pytest.raises(LogError, match="csv"):
        write_log(make_log(), tmp_path / "drive.yaml")


def test_drivelog_checks_shapes_and_order() -> None:
    log = make_log()
    with pytest.raises(LogError, match="phi"):
        DriveLog(log.t, log.cmd, log.phi[:, :5], log.theta, log.pose, log.meta)
    with pytest.raises(LogError, match="strictly increasing"):
        DriveLog(log.t[::-1], log.cmd, log.phi, log.theta, log.pose, log.meta)
    with pytest.raises(LogError, match="sample_rate_hz"):
        LogMeta(rover="r", sample_rate_hz=-1.0)


def test_logs_module_does_not_import_mujoco() -> None:
    code = "import sys, rover_env.logs; sys.exit('mujoco' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


# --------------------------------------------------------------------------- bad logs


def _drop(col: str):
    def f(t: dict[str, list[str]]) -> None:
        del t[col]

    return f


def _set(col: str, row: int, value: str):
    def f(t: dict[str, list[str]]) -> None:
        t[col][row] = value

    return f


def _rename(old: str, new: str):
    def f(t: dict[str, list[str]]) -> None:
        t[new] = t.pop(old)

    return f


# (id, mutation of a good 4-row table, strings the message must contain).
# Data row k (0-based) is CSV line k + 2.
BAD_TABLES = [
    ("missing-column", _drop("phi_3L"), ["phi_3L"]),
    ("missing-cmd-column", _drop("cmd_2R"), ["cmd_2R"]),
    ("non-numeric", _set("theta_2", 2, "abc"), ["theta_2", "line 4", "abc"]),
    ("empty-required", _set("cmd_1R", 1, ""), ["cmd_1R", "line 3", "empty"]),
    ("nan-required", _set("phi_2L", 3, "nan"), ["phi_2L", "line 5", "NaN"]),
    ("inf-required", _set("t", 3, "inf"), ["'t'", "line 5"]),
    ("time-repeats", _set("t", 2, repr(0.02)), ["line 4", "0.02", "strictly increasing"]),
    ("time-decreases", _set("t", 3, "0.01"), ["line 5", "0.04", "0.01"]),
    ("misspelt-column", _rename("theta_4", "theta4"), ["theta_4"]),
]


@pytest.mark.parametrize(
    ("mutate", "needles"), [b[1:] for b in BAD_TABLES], ids=[b[0] for b in BAD_TABLES]
)
def test_bad_table_raises_precise_error(tmp_path: Path, mutate, needles: list[str]) -> None:
    table = good_table(n=4)
    mutate(table)
    path = write_raw(tmp_path, table)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the misspelt column also warns as unknown
        with pytest.raises(LogError) as info:
            read_log(path)
    msg = str(info.value)
    assert "drive.csv" in msg
    for needle in needles:
        assert needle in msg, (needle, msg)


def test_error_carries_file_column_line(tmp_path: Path) -> None:
    table = good_table(n=4)
    table["phi_1R"][0] = "1.0.0"
    with pytest.raises(LogError) as info:
        read_log(write_raw(tmp_path, table))
    err = info.value
    assert (err.file, err.column, err.line) == (tmp_path / "drive.csv", "phi_1R", 2)


@pytest.mark.parametrize(
    ("yaml_text", "needles"),
    [
        ("rover: proto_explorer\nsample_rate_hz: [50\n", ["line 3", "YAML"]),
        ("- rover\n- sample_rate_hz\n", ["mapping"]),
        ("", ["mapping"]),
        ("sample_rate_hz: 50\n", ["rover"]),
        ("rover: proto_explorer\n", ["sample_rate_hz"]),
        ("rover: proto_explorer\nsample_rate_hz: fast\n", ["sample_rate_hz", "fast"]),
        ("rover: proto_explorer\nsample_rate_hz: 0\n", ["sample_rate_hz", "> 0"]),
        ("rover: proto_explorer\nsample_rate_hz: -50.0\n", ["sample_rate_hz"]),
        ("rover: proto_explorer\nsample_rate_hz: .nan\n", ["sample_rate_hz"]),
        ("rover: proto_explorer\nsample_rate_hz: true\n", ["sample_rate_hz"]),
        ("rover: 3\nsample_rate_hz: 50\n", ["rover"]),
        ("rover: r\nsample_rate_hz: 50\nterrain: 7\n", ["terrain"]),
    ],
    ids=[
        "syntax",
        "list",
        "empty",
        "no-rover",
        "no-rate",
        "rate-text",
        "rate-zero",
        "rate-negative",
        "rate-nan",
        "rate-bool",
        "rover-int",
        "terrain-int",
    ],
)
def test_bad_yaml_raises_precise_error(tmp_path: Path, yaml_text: str, needles: list[str]) -> None:
    path = write_raw(tmp_path, good_table(), yaml_text=yaml_text)
    with pytest.raises(LogError) as info:
        read_log(path)
    msg = str(info.value)
    assert "drive.yaml" in msg
    for needle in needles:
        assert needle in msg, (needle, msg)


def test_missing_files(tmp_path: Path) -> None:
    path = write_raw(tmp_path, good_table(), yaml_text=None)
    with pytest.raises(LogError, match=r"drive\.yaml.*not found"):
        read_log(path)
    path = write_raw(tmp_path, None, stem="nocsv")
    with pytest.raises(LogError, match=r"nocsv\.csv.*not found"):
        read_log(path)


@pytest.mark.parametrize(
    ("csv_text", "needles"),
    [
        ("", ["no header"]),
        (",".join(REQUIRED_COLUMNS) + "\n", ["at least 2", "got 0"]),
        (",".join(REQUIRED_COLUMNS) + "\n" + ",".join(["0"] * 16) + "\n", ["got 1"]),
        (",".join(REQUIRED_COLUMNS) + "\n" + ",".join(["0"] * 15) + "\n", ["line 2", "15"]),
        (",".join((*REQUIRED_COLUMNS, "t")) + "\n", ["'t'", "twice"]),
    ],
    ids=["empty", "header-only", "one-row", "ragged", "duplicate-column"],
)
def test_bad_csv_shape(tmp_path: Path, csv_text: str, needles: list[str]) -> None:
    path = write_raw(tmp_path, csv_text=csv_text)
    with pytest.raises(LogError) as info:
        read_log(path)
    msg = str(info.value)
    assert "drive.csv" in msg
    for needle in needles:
        assert needle in msg, (needle, msg)


def test_pose_columns_go_together(tmp_path: Path) -> None:
    table = good_table(pose=True)
    del table["yaw"]
    with pytest.raises(LogError, match=r"drive\.csv.*line 1.*missing yaw"):
        read_log(write_raw(tmp_path, table))


def test_infinite_pose_is_an_error(tmp_path: Path) -> None:
    table = good_table(pose=True)
    table["y"][2] = "-inf"
    with pytest.raises(LogError, match=r"drive\.csv, line 4, column 'y'"):
        read_log(write_raw(tmp_path, table))


def test_unknown_column_warns_and_is_ignored(tmp_path: Path) -> None:
    table = good_table()
    table["battery_V"] = ["24.1"] * 4
    with pytest.warns(UserWarning, match=r"drive\.csv.*battery_V"):
        log = read_log(write_raw(tmp_path, table))
    assert log.cmd.shape == (4, 4) and log.phi.shape == (4, 6)


def test_unknown_yaml_key_warns_and_is_kept(tmp_path: Path) -> None:
    yaml_text = "rover: proto_explorer\nsample_rate_hz: 100\noperator: K. Y.\nrun: {id: 3}\n"
    path = write_raw(tmp_path, good_table(), yaml_text=yaml_text)
    with pytest.warns(UserWarning, match=r"drive\.yaml.*operator, run"):
        log = read_log(path)
    assert log.meta.extra == {"operator": "K. Y.", "run": {"id": 3}}
    assert log.meta.sample_rate_hz == 100.0 and isinstance(log.meta.sample_rate_hz, float)
    assert log.meta.terrain is None and log.meta.notes is None


def test_column_groups_match_spec() -> None:
    assert CMD_COLUMNS == ("cmd_1L", "cmd_1R", "cmd_2L", "cmd_2R")
    assert PHI_COLUMNS == ("phi_1L", "phi_1R", "phi_2L", "phi_2R", "phi_3L", "phi_3R")
    assert THETA_COLUMNS == tuple(f"theta_{i}" for i in range(1, 6))


# --------------------------------------------------------------------------- recorded drives


@pytest.fixture(scope="module")
def straight_drive():
    from rover_env.sim.recorder import run_drive
    from rover_env.sim.simulator import RoverSim

    sim = RoverSim()
    return run_drive(sim, lambda t: np.full(4, 2.0), duration=2.0, sample_rate_hz=50.0)


@pytest.fixture(scope="module")
def left_turn():
    from rover_env.sim.recorder import run_drive
    from rover_env.sim.simulator import RoverSim

    sim = RoverSim()
    return run_drive(sim, lambda t: np.array([0.5, 3.0, 0.5, 3.0]), duration=2.0)


def test_recorded_drive_log(straight_drive, tmp_path: Path) -> None:
    log = straight_drive.to_log("proto_explorer", terrain="flat", notes="straight")
    assert len(log) == 101
    assert log.t[0] == 0.0 and log.t[-1] == pytest.approx(2.0)
    assert np.all(np.diff(log.t) > 0)
    np.testing.assert_allclose(np.diff(log.t), 0.02, rtol=1e-9)
    assert log.meta.sample_rate_hz == pytest.approx(50.0)
    # Positive targets roll every wheel forward; the driven ones track about 2 rad/s.
    assert np.all(log.phi[0] == 0.0)
    assert np.all(np.diff(log.phi[10:], axis=0) > 0)
    np.testing.assert_allclose(log.phi[-1, :4], 4.0, rtol=0.1)
    assert np.all(log.phi[-1, 4:] > 3.0)
    np.testing.assert_array_equal(log.cmd, 2.0)
    # Pose of segment 3: origin at the first sample, forward along its own x.
    np.testing.assert_array_equal(log.pose[0], [0.0, 0.0, 0.0])
    x, y, yaw = log.pose[-1]
    assert 0.15 < x < 0.4  # 4 rad of wheel on a 0.085 m tire loaded down to 0.05-0.085 m
    assert abs(y) < 0.01 and abs(yaw) < 0.01
    back = read_log(write_log(log, tmp_path / "sim.csv"))
    assert_logs_identical(log, back)


def test_pose_subsampling(straight_drive) -> None:
    full = straight_drive.pose()
    log = straight_drive.to_log("proto_explorer")  # 1 Hz default
    kept = np.flatnonzero(np.isfinite(log.pose[:, 0]))
    np.testing.assert_array_equal(kept, [0, 50, 100])
    assert np.all(np.isnan(log.pose[np.setdiff1d(np.arange(len(log)), kept)]))
    np.testing.assert_array_equal(log.pose[kept], full[kept])
    end = straight_drive.to_log("proto_explorer", pose_end_only=True)
    assert np.flatnonzero(np.isfinite(end.pose[:, 0])).tolist() == [100]
    every = straight_drive.to_log("proto_explorer", pose_rate_hz=None)
    assert np.all(np.isfinite(every.pose))
    five = straight_drive.to_log("proto_explorer", pose_rate_hz=5.0)
    assert np.flatnonzero(np.isfinite(five.pose[:, 0])).tolist() == list(range(0, 101, 10))


def test_truth_arrays_line_up(straight_drive) -> None:
    truth = straight_drive.truth()
    n = len(straight_drive)
    shapes = {
        "t": (n,),
        "S": (n, 6),
        "S_alpha": (n, 6),
        "F_x": (n, 6),
        "F_y": (n, 6),
        "F_z": (n, 6),
        "v_x": (n, 6),
        "v_w": (n, 6),
        "sinkage": (n, 6),
        "forward_speed": (n, 3),
        "yaw_rate": (n, 3),
        "seg_pos": (n, 3, 3),
        "seg_quat": (n, 3, 4),
        "motor_torque": (n, 4),
        "pose": (n, 3),
    }
    assert {k: v.shape for k, v in truth.items()} == shapes
    assert all(np.all(np.isfinite(v)) for v in truth.values())
    # The rover carries its weight on its tires; the free rear wheels roll without slip, so
    # segment 3 moves at their rim speed.
    assert truth["F_z"][-1].sum() == pytest.approx(16.4 * 9.81, rel=0.05)
    assert np.all(truth["sinkage"] == 0.0)  # hard ground: no soil
    rim = np.mean(truth["v_w"][-25:, 4:])
    assert np.mean(truth["forward_speed"][-25:, 2]) == pytest.approx(rim, rel=0.05)
    # Pose x is the integral of segment 3's forward speed.
    dist = np.sum(0.5 * (truth["forward_speed"][1:, 2] + truth["forward_speed"][:-1, 2]) * 0.02)
    assert truth["pose"][-1, 0] == pytest.approx(dist, rel=0.02)


def test_left_turn_has_positive_yaw(left_turn) -> None:
    log = left_turn.to_log("proto_explorer", pose_rate_hz=None)
    assert log.phi[-1, 1] > 4 * log.phi[-1, 0]
    # Right wheels faster turn the rover left: yaw grows (SPEC §6). The trailing segment
    # first swings out to the right, so look at the end of the drive.
    yaw_rate = left_turn.truth()["yaw_rate"][:, 2]
    assert np.all(yaw_rate[-25:] > 0.03)
    assert np.all(np.diff(log.pose[-25:, 2]) > 0)
    # The recorded yaw is the integral of segment 3's own yaw rate.
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (yaw_rate[1:] + yaw_rate[:-1]) * 0.02)])
    np.testing.assert_allclose(log.pose[:, 2], integral, atol=0.003)


def test_recorder_refuses_time_going_back() -> None:
    from rover_env.sim.recorder import DriveRecorder
    from rover_env.sim.simulator import RoverSim

    sim = RoverSim()
    rec = DriveRecorder(sim)
    rec.record(sim)
    with pytest.raises(ValueError, match="did not advance"):
        rec.record(sim)
    with pytest.raises(ValueError, match="at least 2"):
        rec.to_log("proto_explorer")
    assert math.isfinite(rec.truth()["S"][0, 0])


def test_relative_pose_is_in_the_starting_frame() -> None:
    from rover_env.sim.recorder import relative_pose

    def about_z(a: float) -> np.ndarray:
        return np.array([np.cos(a / 2), 0.0, 0.0, np.sin(a / 2)])

    # Start at (1, 2) heading 1 rad; move 1 m along that heading, then 1 m to its left,
    # turning 0.5 rad and then 3 rad more (past pi: yaw must keep growing, not wrap).
    h, left = np.array([np.cos(1.0), np.sin(1.0), 0.0]), np.array([-np.sin(1.0), np.cos(1.0), 0])
    o = np.array([1.0, 2.0, 0.3])
    pos = np.stack([o, o + h, o + h + left])
    quat = np.stack([about_z(1.0), about_z(1.5), about_z(4.5)])
    np.testing.assert_allclose(
        relative_pose(pos, quat), [[0, 0, 0], [1, 0, 0.5], [1, 1, 3.5]], atol=1e-12
    )
