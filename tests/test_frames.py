"""Drives that start facing different ways: each log's pose is in its own frame (SPEC §6), and
the YAML's ``start_heading_deg`` places those frames in one (rover_env.calibration.heading,
the replay's heading, the independent generator's ``headings``).

The balance's logs come from test_balance's rigid rover (not the simulator): a drive that
started facing ``psi`` in the world sees a slope rising toward ``h`` as rising toward
``h - psi`` in its own frame.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from rover_env.bag_map import BagError
from rover_env.bags import import_bag
from rover_env.calibration.balance import CLEAN_SLIP_TILT, read_balance
from rover_env.calibration.diagnosis.balance_stage import TURNED_F, in_frames, record
from rover_env.calibration.diagnosis.balance_stage import test_text as naming_text
from rover_env.calibration.diagnosis.frames import FIT_F, fit_frames
from rover_env.calibration.diagnosis.state import Diagnosis, Options
from rover_env.calibration.heading import check_frames, headings
from rover_env.calibration.replay import ReplaySettings, prepare
from rover_env.calibration.report_method import _frames_line
from rover_env.calibration.report_notes import balance_lines
from rover_env.config import RoverConfig
from rover_env.independent.generate import make_independent_logs, start_heading
from rover_env.logs import DriveLog, LogError, LogMeta, read_log, write_log
from tests.test_bags import BASE, MS, Msgs, _synthetic, quat_z, write_bag, write_map
from tests.test_balance import _end_only, bare, rover_log

CFG = RoverConfig()
STARTS = (0.0, 100.0, -150.0)
"""Where the three drives started facing in the world (degrees)."""


def _started(log: DriveLog, psi: float | None) -> DriveLog:
    """``log`` with ``psi`` as its YAML's start heading (None: the key absent)."""
    meta = dataclasses.replace(log.meta, start_heading_deg=psi)
    return DriveLog(log.t, log.cmd, log.phi, log.theta, log.pose, meta, effort=log.effort)


def _drives(tilt: float, heading: float, say: bool, end_only: bool = False) -> list[DriveLog]:
    """Three drives on one slope (rising toward ``heading`` in the world) that started facing
    :data:`STARTS`; ``say``: their YAML gives the start heading."""
    out = []
    for s, psi in enumerate(STARTS):
        log = bare(rover_log(tilt, heading - psi, 0.02, seed=s, slip_offset=0.01))
        out.append(_started(_end_only(log) if end_only else log, psi if say else None))
    return out


@pytest.mark.parametrize("end_only", [False, True])
def test_drives_started_facing_different_ways_read_one_slope_by_their_start_headings(
    end_only: bool,
) -> None:
    """Given the start headings the slip balance reads the slope's tilt and its direction in
    the world, within its interval; without them the same runs disagree (each log sees the
    slope elsewhere): their scatter about the fit is many times larger."""
    told, _ = read_balance(_drives(1.5, 60.0, True, end_only), CFG, 0.2, "slip")
    assert told is not None
    lo, hi = told.tilt_interval()
    assert lo <= 1.5 <= hi
    assert abs(math.remainder(told.heading - 60.0, 360.0)) < 5.0
    blind, _ = read_balance(_drives(1.5, 60.0, False, end_only), CFG, 0.2, "slip")
    assert blind is not None
    assert blind.scatter > 5.0 * told.scatter


def test_the_headings_turn_by_each_logs_start() -> None:
    logs = _drives(0.0, 0.0, True, end_only=True)
    plain = headings([_started(lg, None) for lg in logs], CFG, [None] * 3).yaw()
    turned = headings(logs, CFG, [None] * 3).yaw()
    for a, b, psi in zip(plain, turned, STARTS, strict=True):
        assert a is not None and b is not None
        assert np.allclose(b - a, math.radians(psi))


def test_some_logs_with_a_start_heading_and_some_without_is_one_clear_error() -> None:
    logs = _drives(0.0, 0.0, True)
    logs[2] = _started(logs[2], None)
    names = [Path(f"/x/drive_0{i}.csv") for i in range(3)]
    with pytest.raises(LogError, match=r"drive_02\.csv.*start_heading_deg.*drive_00\.csv"):
        check_frames(logs, names)
    check_frames(_drives(0.0, 0.0, True), names)  # all: fine
    check_frames(_drives(0.0, 0.0, False), names)  # none: fine


def test_the_replay_starts_its_windows_in_the_shared_frame() -> None:
    log = rover_log(0.0, 0.0, 0.0)
    st = ReplaySettings()
    a = prepare(_started(log, None), CFG, "a", st)
    b = prepare(_started(log, -30.0), CFG, "b", st)
    assert np.allclose(b.yaw3 - a.yaw3, math.radians(-30.0))


def test_the_start_heading_round_trips_and_bad_values_name_the_key(tmp_path: Path) -> None:
    log = _started(rover_log(0.0, 0.0, 0.0), 123.5)
    path = write_log(log, tmp_path / "drive.csv")
    assert read_log(path).meta.start_heading_deg == 123.5
    text = path.with_suffix(".yaml").read_text()
    assert "start_heading_deg: 123.5" in text
    for bad in ("north", ".nan", "true"):
        path.with_suffix(".yaml").write_text(text.replace("123.5", bad))
        with pytest.raises(LogError, match=r"drive\.yaml.*'start_heading_deg'"):
            read_log(path)
    with pytest.raises(LogError, match="start_heading_deg"):
        LogMeta(rover="proto_explorer", sample_rate_hz=50.0, start_heading_deg=math.inf)


def test_the_generator_turns_the_slope_by_each_drives_start(tmp_path: Path) -> None:
    """A drive that started facing ``psi`` on a slope rising toward 30° in the world is the
    drive that started along +x on one rising toward ``30 - psi``, sample for sample; its YAML
    says ``psi`` (``drawn``) or nothing (``unlogged``)."""
    slope = {"deg": 3.0, "heading_deg": 30.0}
    kw = {"drives": 1, "seed": 5, "duration": 2.0, "first_index": 1}
    (drawn,) = make_independent_logs(tmp_path / "d", {"slope": slope}, headings="drawn", **kw)
    (unlogged,) = make_independent_logs(tmp_path / "u", {"slope": slope}, headings="unlogged", **kw)
    psi = start_heading(5, 1)
    turned = {"slope": {**slope, "heading_deg": 30.0 - psi}}
    (same,) = make_independent_logs(tmp_path / "s", turned, headings="same", **kw)
    (level,) = make_independent_logs(tmp_path / "l", {"slope": slope}, headings="same", **kw)
    a, b, c, d = (read_log(p) for p in (drawn, unlogged, same, level))
    assert a.meta.start_heading_deg == psi and abs(psi) > 1.0
    assert b.meta.start_heading_deg is None and c.meta.start_heading_deg is None
    for other in (b, c):
        assert np.array_equal(a.theta, other.theta) and np.array_equal(a.phi, other.phi)
    assert not np.array_equal(a.theta, d.theta)  # the start does turn what the joints see
    truth = yaml.safe_load((tmp_path / "d" / "truth.yaml").read_text())
    assert truth["drives"][0]["start_heading_deg"] == psi
    with pytest.raises(ValueError, match="headings"):
        make_independent_logs(tmp_path / "x", {}, headings="north", **kw)


def test_a_bag_whose_reference_every_drive_shares_gives_the_start_heading(
    tmp_path: Path,
) -> None:
    """The IMU's yaw at the log's start is written as ``start_heading_deg`` (the log's own
    yaw still starts at 0); ``shared_frame: false`` (a reference that starts anew each
    drive) writes none; the key must be true or false."""
    m = Msgs()
    topics = _synthetic(m)
    kind, imu = topics["/imu/data"]
    topics["/imu/data"] = (
        kind,
        [(r, m.imu(r - MS, quat_z(1.2 + 0.1 * (r - MS - BASE) / 1e9))) for r, _ in imu],
    )
    bag = write_bag(tmp_path / "bag", topics, m)
    log = import_bag(bag, write_map(tmp_path / "shared.yaml", lambda d: None))
    assert log.meta.start_heading_deg == pytest.approx(math.degrees(1.2), abs=0.01)
    assert log.pose[0, 2] == pytest.approx(0.0, abs=1e-12)
    own = write_map(tmp_path / "own.yaml", lambda d: d["yaw"].update(shared_frame=False))
    assert import_bag(bag, own).meta.start_heading_deg is None
    bad = write_map(tmp_path / "bad.yaml", lambda d: d["yaw"].update(shared_frame="yes"))
    with pytest.raises(BagError, match=r"bad\.yaml.*yaw\.shared_frame"):
        import_bag(bag, bad)


def test_the_report_says_which_frame_its_headings_are_in() -> None:
    logs = ["/d/drive_00.csv", "/d/drive_01.csv"]
    (line,) = _frames_line({"logs": logs, "start_headings": [37.5, -120.0]})
    assert "drive_00.csv 37.5°" in line and "drive_01.csv -120°" in line
    assert _frames_line({"logs": logs, "start_headings": [None, None]}) == []
    assert _frames_line({"logs": logs}) == []  # results written before the key existed


def test_runs_that_read_the_ground_turned_between_logs_say_so() -> None:
    """Without start headings the balance tries each log's frame turned on its own: drives
    that started facing different ways fit far better so (the reading's record says so and
    the turns found are the starts' differences; what the reading does is unchanged);
    drives that started alike do not; with the start headings given it is not tried."""
    blind, runs = read_balance(_drives(1.5, 60.0, False), CFG, 0.2, "slip")
    assert blind is not None and blind.turned_f > TURNED_F
    for found, psi in zip(blind.turned_deg, STARTS, strict=True):
        assert abs(math.remainder(found - psi, 360.0)) <= 5.0 + 1e-9  # one step of its grid
    act, rec = record(blind, len(runs), CLEAN_SLIP_TILT, None, False, "slip")
    assert "start_heading_deg" in rec["frames"] and f"{blind.turned_deg[1]:.0f}°" in rec["frames"]
    assert rec["frames"] in "".join(balance_lines(rec))  # the report says it
    unturned = dataclasses.replace(blind, turned_f=0.0, turned_deg=())
    assert record(unturned, len(runs), CLEAN_SLIP_TILT, None, False, "slip")[0] == act
    alike = [
        _started(bare(rover_log(1.5, 60.0, 0.02, seed=s, slip_offset=0.01)), None) for s in range(3)
    ]
    same, runs = read_balance(alike, CFG, 0.2, "slip")
    assert same is not None and same.turned_f < TURNED_F
    act, rec = record(same, len(runs), CLEAN_SLIP_TILT, None, False, "slip")
    assert act == "name" and "frames" not in rec
    told, _ = read_balance(_drives(1.5, 60.0, True), CFG, 0.2, "slip")
    assert told is not None and told.turned_f == 0.0 and told.turned_deg == ()


def _fitted(logs: list[DriveLog], frames: str = "fit") -> tuple[Diagnosis, list[DriveLog]]:
    """``logs`` through the split's frames step, as ``diagnose --frames <frames>`` reads them."""
    d = Diagnosis(
        [], Path("/nonexistent"), Options(frames=frames, form_allowance=None, progress=False)
    )
    files = [Path(f"/d/drive_0{i}.csv") for i in range(len(logs))]
    return d, fit_frames(d, logs, files, CFG)


def test_frames_fitted_turn_each_log_into_the_firsts_and_read_the_slope_there() -> None:
    """``--frames fit`` on drives that started facing :data:`STARTS` without saying so: the
    turns found are the starts' differences within 2° (the 5° grid, then 1° steps), and the
    balance then reads the slope's tilt inside its interval and its heading, in the first
    log's frame, within 5°; the report says the frames were fitted."""
    d, logs = _fitted(_drives(1.5, 60.0, False))
    assert d.frames is not None and d.frames["fitted"] and d.frames["f"] > TURNED_F
    for log, psi in zip(logs, STARTS, strict=True):
        assert log.meta.start_heading_deg is not None
        assert abs(math.remainder(log.meta.start_heading_deg - psi, 360.0)) <= 2.0
    sd = tuple(d.frames["turn_sd_deg"])
    assert sd[0] == 0.0 and all(0.0 < s < 10.0 for s in sd[1:])  # the first log's is held
    r, _ = read_balance(logs, CFG, 0.2, "slip", sd)
    assert r is not None and r.tilt_interval()[0] <= 1.5 <= r.tilt_interval()[1]
    assert abs(math.remainder(r.heading - 60.0, 360.0)) < 5.0
    # The turns' uncertainty widens the heading's interval over the frames-given reading's.
    given, _ = read_balance(logs, CFG, 0.2, "slip")
    assert given is not None and given.heading == pytest.approx(r.heading)
    width = [h[1] - h[0] for h in (r.heading_interval(), given.heading_interval())]
    assert width[0] > width[1]
    files = [f"/d/drive_0{i}.csv" for i in range(3)]
    heads = [lg.meta.start_heading_deg for lg in logs]
    (line,) = _frames_line({"logs": files, "start_headings": heads, "frames": d.frames})
    assert "fitted" in line and "drive_00.csv's" in line and f"F {d.frames['f']:.1f}" in line
    assert (
        "heading, wherever this report gives one, is in drive_00.csv's frame and not known" in line
    )
    assert f"± {sd[1]:.0f}°" in line


def test_frames_are_not_fitted_where_turning_them_explains_little() -> None:
    """On level ground drives started facing different ways have nothing to turn: their
    runs fit hardly better turned, the frames are read as given (facing alike), the report
    says why, and the balance names no slope."""
    logs = _drives(0.0, 0.0, False)
    d, kept = _fitted(logs)
    assert d.frames is not None and not d.frames["fitted"] and d.frames["f"] < FIT_F
    assert kept is logs
    r, runs = read_balance(kept, CFG, 0.2, "slip")
    assert r is not None
    assert record(r, len(runs), CLEAN_SLIP_TILT, None, False, "slip")[0] != "name"
    (line,) = _frames_line(
        {"logs": ["/d/a.csv"] * 3, "start_headings": [None] * 3, "frames": d.frames}
    )
    assert "not fitted" in line and f"under {FIT_F:g}" in line
    # Read as facing alike only because nothing could be fitted: the heading is in no frame.
    slope, _ = read_balance(_drives(1.5, 60.0, False), CFG, 0.2, "slip")
    assert slope is not None and slope.heading_interval()[1] - slope.heading_interval()[0] < 360
    unread = in_frames(slope, d.frames)
    assert unread is not None and unread.frames_placed == "unread" and unread.tilt == slope.tilt
    assert unread.heading_interval()[1] - unread.heading_interval()[0] == pytest.approx(360.0)
    assert "the frames were not fitted" in naming_text(unread, CLEAN_SLIP_TILT)
    fitted = in_frames(slope, {"fitted": True})  # fitted frames: the heading is not known either
    assert fitted is not None and fitted.frames_placed == "fitted"
    assert fitted.heading_interval()[1] - fitted.heading_interval()[0] == pytest.approx(360.0)
    assert "in fitted frames the heading is not known" in naming_text(fitted, CLEAN_SLIP_TILT)
    assert in_frames(slope, None) is slope
    rec = record(fitted, 21, CLEAN_SLIP_TILT, None, False, "slip")[1]
    assert "not known: the frames were fitted" in "".join(balance_lines(rec))


def test_frames_given_leave_the_logs_and_fit_refuses_logs_that_give_them() -> None:
    logs = _drives(1.5, 60.0, True)
    d, same = _fitted(logs, "given")
    assert same is logs and d.frames is None
    with pytest.raises(LogError, match=r"drive_00\.csv.*start_heading_deg.*--frames fit"):
        _fitted(logs)
    with pytest.raises(ValueError, match="frames"):
        _fitted(logs, "north")
    few = [_started(bare(rover_log(0.0, 0.0, 0.0, seed=0)), None)]
    few[0] = DriveLog(
        few[0].t[:50],
        *(a[:50] for a in (few[0].cmd, few[0].phi, few[0].theta, few[0].pose)),
        few[0].meta,
    )
    d, kept = _fitted(few)
    assert d.frames is not None and not d.frames["fitted"] and kept is few
    (line,) = _frames_line(
        {"logs": ["/d/drive_00.csv"], "start_headings": [None], "frames": d.frames}
    )
    assert "not fitted" in line
