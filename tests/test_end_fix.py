"""Dead reckoning against each drive's last pose fix (the paper's log, SPEC §6): a straight
drive's path to its end fix over the free wheels' net travel reads a rolling radius change;
drives of turns, short drives and logs with fixes between are left to what reads them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rover_env.calibration.diagnosis.odometry import END, INTERVALS, band_of, form_of, scales
from rover_env.calibration.diagnosis.state import Options
from rover_env.estimation.dead_reckoning import MIN_CHORD, commanded_straight, end_fix_parts
from rover_env.logs import DriveLog, LogMeta

R_E = 0.0761
DT = 0.02


def _drive(
    f: float,
    speed: np.ndarray,
    yaw_rate: float = 0.0,
    turn: float = 0.0,
    every: float | None = None,
) -> DriveLog:
    """A drive at ``speed`` (m/s per row) whose wheels roll at r_e (1 + f), its heading
    drifting at ``yaw_rate``; ``turn``: the right side commanded that much faster (rad/s);
    pose fixes every ``every`` seconds, or at the last row only."""
    n = speed.size
    t = np.arange(n) * DT
    heading = np.r_[0.0, np.cumsum(np.full(n - 1, yaw_rate * DT))]
    ds = np.r_[0.0, speed[1:] * DT]
    x = np.cumsum(ds * np.cos(heading))
    y = np.cumsum(ds * np.sin(heading))
    wheel = np.cumsum(ds) / (R_E * (1.0 + f))
    phi = np.tile(wheel[:, None], (1, 6))
    cmd = np.tile((speed / R_E)[:, None], (1, 4))
    cmd[:, [1, 3]] += turn
    pose = np.full((n, 3), np.nan)
    if every is None:
        pose[-1] = (x[-1], y[-1], heading[-1])
    else:
        k = round(every / DT)
        pose[::k] = np.c_[x, y, heading][::k]
    meta = LogMeta(rover="proto_explorer", sample_rate_hz=1 / DT, terrain={"name": "flat"})
    return DriveLog(t=t, cmd=cmd, phi=phi, theta=np.zeros((n, 5)), pose=pose, meta=meta)


def _ratio(log: DriveLog, wheels: tuple[int, ...] = (4, 5)) -> float:
    path, travel = end_fix_parts(log.pose, log.phi, log.cmd, R_E, wheels)
    return path / travel - 1.0


@pytest.mark.parametrize("f", [-0.06, 0.0, 0.03])
def test_a_straight_drive_reads_the_radius_change_at_its_end(f: float) -> None:
    assert _ratio(_drive(f, np.full(2000, 0.2))) == pytest.approx(f, abs=1e-9)


def test_the_heading_drift_the_end_fix_shows_is_read_as_an_arc() -> None:
    # 0.4 rad of drift over 8 m: the chord alone reads 0.7 % short; the arc is the path.
    d = _drive(0.02, np.full(2000, 0.2), yaw_rate=0.01)
    assert _ratio(d) == pytest.approx(0.02, abs=1e-6)
    chord = float(np.hypot(*d.pose[-1, :2]))
    assert chord / (d.phi[-1, 4] * R_E) - 1 < 0.02 - 0.006
    d.pose[-1, 2] = np.nan  # a fix without a yaw: its chord
    assert _ratio(d) == pytest.approx(chord / (d.phi[-1, 4] * R_E) - 1, abs=1e-12)


def test_out_and_back_reads_the_net_travel() -> None:
    speed = np.r_[np.full(1500, 0.2), np.full(700, -0.2)]
    assert _ratio(_drive(-0.04, speed)) == pytest.approx(-0.04, abs=1e-9)
    # the driven wheels' net travel is read the same way (here they roll as the free ones)
    assert _ratio(_drive(-0.04, speed), (0, 1, 2, 3)) == pytest.approx(-0.04, abs=1e-9)


def test_turns_short_drives_and_missing_fixes_read_nothing() -> None:
    assert end_fix_parts(*_parts(_drive(0.0, np.full(2000, 0.2), turn=0.5))) == (0.0, 0.0)
    short = _drive(0.0, np.full(int(0.9 * MIN_CHORD / 0.2 / DT), 0.2))
    assert end_fix_parts(*_parts(short)) == (0.0, 0.0)
    blank = _drive(0.0, np.full(2000, 0.2))
    blank.pose[:] = np.nan
    assert end_fix_parts(*_parts(blank)) == (0.0, 0.0)


def _parts(d: DriveLog) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    return d.pose, d.phi, d.cmd, R_E


def test_a_straight_command_allows_only_a_percent_between_the_sides() -> None:
    cmd = np.full((10, 4), 3.0)
    assert commanded_straight(cmd)
    cmd[5, [1, 3]] += 0.02  # 0.7 % of the largest target
    assert commanded_straight(cmd)
    cmd[5, [1, 3]] += 0.02  # 1.3 %
    assert not commanded_straight(cmd)
    assert not commanded_straight(np.zeros((10, 4)))


def test_the_stage_reads_intervals_where_there_are_fixes_between_else_the_end() -> None:
    one_hz = _drive(0.03, np.full(2000, 0.2), every=1.0)
    end = _drive(0.03, np.full(2000, 0.2))
    assert form_of([one_hz], R_E) == INTERVALS
    assert form_of([end], R_E) == END
    assert math.isnan(scales([end], R_E)["both"])
    got = scales([end], R_E, END)
    assert got["both"] == pytest.approx(0.03, abs=1e-9)
    assert got["3L"] == pytest.approx(0.03, abs=1e-9)
    opts = Options()
    assert band_of(opts, INTERVALS) is opts.odometry
    assert band_of(opts, END) is opts.odometry_end


def test_the_report_says_what_the_end_form_read_or_what_to_drive() -> None:
    from rover_env.calibration.report_reckoning import reckoning_lines

    diff = {"both": 0.05, "3L": 0.051, "3R": 0.049, "driven": 0.045}
    r = {
        "form": END,
        "logs": diff,
        "model": {"both": 0.0},
        "difference": diff,
        "band": [-0.02, 0.02],
        "named": True,
        "noise_samples": 0,
    }
    text = " ".join(reckoning_lines(r))
    assert "each drive commanded straight, from its start to its last pose fix" in text
    assert "drive-plan" not in text  # the interval form's noise advice is not for this form
    none = {**r, "difference": {k: math.nan for k in diff}, "named": False, "why_not": "x"}
    assert "drive-plan --plan straight" in " ".join(reckoning_lines(none))
    assert "at each drive's end only" in " ".join(reckoning_lines(none))


def test_the_matrix_can_keep_each_drive_s_last_fix_only(tmp_path) -> None:
    from _bench import load_bench

    from rover_env.logs import read_log, write_log

    bench = load_bench("bench_independent")
    drive = _drive(0.0, np.full(300, 0.2), every=1.0)
    path = tmp_path / "drive_00.csv"
    write_log(drive, path)
    assert bench.as_logged([path], "as-logged", 1) == [path]
    assert np.isfinite(read_log(path).pose[:, 0]).sum() == 6
    bench.as_logged([path], "end", 1)
    got = read_log(path).pose
    (k,) = np.flatnonzero(np.isfinite(got[:, 0]))
    assert k == 250 and np.allclose(got[k], drive.pose[250])


def test_the_band_benchmark_plans_clean_and_singles_and_reads_both_forms(tmp_path) -> None:
    from _bench import load_bench

    band = load_bench("end_fix_band")
    cases = band.plan(list(range(10)), 2, ("rolling_radius", "slope"), tmp_path)
    assert [c["effect"] for c in cases[:4]] == ["clean", "rolling_radius", "clean", "slope"]
    assert cases[0]["effects"] == {} and "fraction" in cases[1]["effects"]["rolling_radius"]
    d = _drive(0.03, np.full(2000, 0.2), every=1.0)
    got = band.statistics(d.pose, d.phi, d.cmd, R_E)
    path, travel = got["end"]["both"]
    assert path / travel - 1 == pytest.approx(0.03, abs=1e-9)
    path, travel = got["hz"]["both"]
    assert path / travel - 1 == pytest.approx(0.03, abs=1e-9)


def test_the_matrix_summary_reads_a_drive_set_the_end_form_could_not_read() -> None:
    """result.json writes NaN as null: the matrix's summary of the stage keeps its form and
    gives no split where nothing was read (a merge once failed on it, study 72000)."""
    from _bench import load_bench

    odometry = load_bench("_rules").odometry

    nothing = {"both": None, "3L": None, "3R": None, "driven": None}
    got = odometry(
        {"dead_reckoning": {"form": "end", "band": [-0.02, 0.02], "difference": nothing}}
    )
    assert got is not None and got["form"] == "end" and got["split"] is None
    read = {"both": 0.03, "3L": 0.035, "3R": 0.025, "driven": 0.03}
    got = odometry({"dead_reckoning": {"band": [-0.02, 0.02], "difference": read}})
    assert got is not None and got["form"] == "intervals"
    assert got["split"] == pytest.approx(0.01)
