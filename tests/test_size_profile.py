"""The tilt's size in fitted frames (``diagnose --frames fit``): its profile over each log's
free turn (rover_env.calibration.size_profile), the turns it finds, and what a reading
bounded below only does (balance_stage's "open").

Runs are built directly (a log's runs on lines in its own frame, the slope rising toward
``beta`` from there), or as whole logs from test_balance's rigid rover."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from rover_env.calibration.balance import (
    CLEAN_SLIP_TILT,
    _misfit,
    _read_runs,
    frame_turns,
    read_balance,
    size_profile,
)
from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis.balance_stage import action, balance_fit, in_frames, record
from rover_env.calibration.diagnosis.judge import fmt_phys
from rover_env.calibration.diagnosis.write import UNKNOWN_HEADING, mark_headings, rover_header
from rover_env.calibration.report_notes import balance_lines
from rover_env.calibration.size_profile import profile
from rover_env.config import RoverConfig
from rover_env.logs import DriveLog
from tests.test_balance import bare, rover_log

CFG = RoverConfig()
WEIGHT = CFG.masses.total * 9.81
NOISE = 0.3
"""N: each run's traction noise."""


def _runs(
    tilt: float, lines: list[list[float]], turns: list[float], seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Runs forwards and backwards (three each) on each log's ``lines`` (degrees, its own
    frame), the log's frame turned ``turns[k]`` from the one the slope (``tilt`` degrees)
    rises toward 0° in, a resistance of 30 N; noise :data:`NOISE`."""
    rng = np.random.default_rng(seed)
    X, y, logs = [], [], []
    a = WEIGHT * math.sin(math.radians(tilt))
    for k, (mine, turn) in enumerate(zip(lines, turns, strict=True)):
        for line in mine:
            psi = math.radians(line)
            for d in (1.0, -1.0) * 3:
                X.append([math.cos(psi), math.sin(psi), d])
                y.append(a * math.cos(psi + math.radians(turn)) + 30.0 * d)
                logs.append(k)
    ys = np.asarray(y) + rng.normal(0.0, NOISE, len(y))
    return np.asarray(X), ys, np.full(len(y), 1.0 / NOISE), np.asarray(logs)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_logs_each_on_one_line_bound_the_size_below_only(seed: int) -> None:
    """Each log on one line reads only the tilt's part along it: every size from the
    largest part up fits as well (a turn per log), so the interval holds the truth and is
    open above."""
    turns = [20.0, 150.0, -100.0]
    p = profile(*_runs(1.0, [[0.0], [0.0], [0.0]], turns, seed), WEIGHT, True)
    assert p.lo <= 1.0 and math.isinf(p.hi)
    part = max(abs(math.cos(math.radians(t))) for t in turns)  # the largest part read
    assert p.lo >= 0.5 * part  # bounded below, near the largest part


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_one_log_on_crossing_lines_decides_the_size(seed: int) -> None:
    """A log whose runs cross (two lines) reads the whole tilt in its own frame: the
    interval is narrow about the truth, and each log's angle is its turn (the slope's
    direction taken from the first log's frame)."""
    turns = [0.0, 150.0, -100.0]
    p = profile(*_runs(1.0, [[0.0, 90.0], [0.0], [30.0, 120.0]], turns, seed), WEIGHT, True)
    assert p.lo <= 1.0 <= p.hi < 1.3 and p.lo > 0.7
    for k in (0, 2):  # the logs that cross: their angle is their turn (mod 360)
        assert abs(math.remainder(math.degrees(p.angles[k]) - turns[k], 360.0)) < 5.0


def test_level_ground_reaches_zero() -> None:
    p = profile(*_runs(0.0, [[0.0, 90.0], [0.0], [45.0]], [0.0, 60.0, -30.0]), WEIGHT, True)
    assert p.lo == 0.0 and p.hi < 0.3


def _single_line_drives(tilt: float, heading: float) -> list[DriveLog]:
    """Three drives forwards and backwards on one line, started facing 0, 100 and -150°
    in the world (their YAML says nothing), on a slope rising toward ``heading``."""
    plan = [(4.0, 3.0, 3.0), (4.0, -3.0, -3.0)] * 3
    return [
        bare(rover_log(tilt, heading - psi, 0.02, plan=plan, seed=s, slip_offset=0.01))
        for s, psi in enumerate((0.0, 100.0, -150.0))
    ]


def _in_fitted_frames(logs: list[DriveLog]) -> tuple[list[DriveLog], tuple[float, ...]]:
    got = frame_turns(logs, CFG, "slip")
    assert got is not None
    placed = [
        dataclasses.replace(lg, meta=dataclasses.replace(lg.meta, start_heading_deg=t))
        for lg, t in zip(logs, got.deg, strict=True)
    ]
    return placed, got.sd_deg


def test_fitted_frames_on_single_lines_leave_the_size_open_and_name_nothing() -> None:
    """Three drives each on one line, fitted frames: the reading's interval holds the truth
    and is open above, so the balance names nothing ("open") and asks for the crossing
    drive; with the frames given the same runs decide the size (narrow, named)."""
    logs = _single_line_drives(1.5, 60.0)
    placed, sd = _in_fitted_frames(logs)
    r, runs = read_balance(placed, CFG, 0.2, "slip", sd, free=True)
    r = in_frames(r, {"fitted": True})
    assert r is not None and r.size_bounds is not None
    lo, hi = r.tilt_interval()
    assert lo <= 1.5 and math.isinf(hi) and lo > CLEAN_SLIP_TILT
    act, rec = record(r, len(runs), CLEAN_SLIP_TILT, None, False, "slip")
    assert act == "open" and rec["plan"] == "reversals" and "crossing line" in rec["why_not"]
    assert rec["size_bounds"][1] is None  # JSON: no infinity
    text = "".join(balance_lines(rec))
    assert "unbounded]" in text and "read free of the frames" in text and "reversals" in text
    told = [
        dataclasses.replace(lg, meta=dataclasses.replace(lg.meta, start_heading_deg=psi))
        for lg, psi in zip(logs, (0.0, 100.0, -150.0), strict=True)
    ]
    g, runs = read_balance(told, CFG, 0.2, "slip")
    assert g is not None and g.size_bounds is None
    glo, ghi = g.tilt_interval()
    assert glo <= 1.5 <= ghi < 2.5
    assert record(g, len(runs), CLEAN_SLIP_TILT, None, False, "slip")[0] == "name"


def test_the_named_fit_carries_the_profiles_interval() -> None:
    """In fitted frames with a crossing drive the size is bounded: the named slope's
    interval (``Fit.physical``, the allowance below) reaches the reading's ends (the high
    one by its reach; the errors, widened for the low one, may pass it) and holds the
    truth."""
    logs = _single_line_drives(1.2, -40.0)
    logs[1] = bare(rover_log(1.2, -140.0, 0.02, seed=7, slip_offset=0.01))  # it crosses
    placed, sd = _in_fitted_frames(logs)
    r, _ = read_balance(placed, CFG, 0.2, "slip", sd, free=True)
    r = in_frames(r, {"fitted": True})
    assert r is not None and r.size_bounds is not None
    lo, hi = r.tilt_interval()
    assert lo <= 1.2 <= hi and math.isfinite(hi)
    assert action((lo, hi), CLEAN_SLIP_TILT, None, False) == "name"
    fit = balance_fit(catalogue(["slope"])[0], r, CLEAN_SLIP_TILT, 0.0)
    v, a, b = fit.physical()["slope"]["deg"]
    assert v == pytest.approx(r.tilt)
    assert a == pytest.approx(max(lo - CLEAN_SLIP_TILT, 0.0))
    assert hi - 1e-9 <= b <= max(hi, 2.0 * r.tilt - lo) + 1e-9
    # Its heading is in the first log's frame and not known; the record and text say so.
    assert not fit.heading_known and "heading_deg=" in fmt_phys(fit)
    assert "(not known)" in fmt_phys(fit)
    given = dataclasses.replace(r, frames_placed="given")
    plain = balance_fit(catalogue(["slope"])[0], given, CLEAN_SLIP_TILT, 0.0)
    assert plain.heading_known
    # rover.yaml's comment says so where a named slope's heading is not known, only there.
    assert UNKNOWN_HEADING in rover_header([SimpleNamespace(fit=fit)])  # type: ignore[list-item]
    assert UNKNOWN_HEADING not in rover_header([SimpleNamespace(fit=plain)])  # type: ignore[list-item]
    # With --frames fit every slope fit is marked, the windows' too; other effects are not.
    other = balance_fit(catalogue(["rolling_resistance"])[0], given, CLEAN_SLIP_TILT, 0.0)
    d = SimpleNamespace(
        frames={"fitted": False},
        ranked=[SimpleNamespace(fit=plain), SimpleNamespace(fit=other)],
        chosen=[],
    )
    mark_headings(d)  # type: ignore[arg-type]
    assert not plain.heading_known and other.heading_known
    given_fit = balance_fit(catalogue(["slope"])[0], given, CLEAN_SLIP_TILT, 0.0)
    mark_headings(SimpleNamespace(frames=None, ranked=[SimpleNamespace(fit=given_fit)], chosen=[]))  # type: ignore[arg-type]
    assert given_fit.heading_known


@pytest.mark.parametrize("seed", range(4))
def test_the_turns_found_fit_at_least_as_well_as_the_profiles(seed: int) -> None:
    """The turns :func:`frame_turns` gives fit the runs no worse than the size profile's
    best (a search log by log can stop in a mirror's valley; the profile's turns are
    taken where they fit better)."""
    rng = np.random.default_rng(seed)
    plan = [(4.0, 3.0, 3.0), (4.0, -3.0, -3.0)] * 2
    logs = [
        bare(rover_log(0.9, float(h), 0.02, plan=plan, seed=10 * seed + s, slip_offset=0.01))
        for s, h in enumerate(rng.uniform(-180.0, 180.0, 4))
    ]
    got = frame_turns(logs, CFG, "slip")
    assert got is not None
    _, yaws, rs = _read_runs(logs, CFG, "slip")
    best = size_profile(rs, "slip", WEIGHT).rss
    assert _misfit(rs, yaws, "slip", np.radians(got.deg)) <= best * (1.0 + 1e-3) + 1e-9


@pytest.mark.parametrize("seed", range(3))
def test_frames_left_unread_read_the_size_free_of_them(seed: int) -> None:
    """Drives started facing 0, 100 and -150° without saying so, read in one frame: taken
    alike the runs read a mixture; read free of their frames (``--frames fit`` under its F
    ratio) the size's interval holds the truth."""
    logs = [
        bare(rover_log(1.2, 60.0 - psi, 0.02, seed=10 * seed + s, slip_offset=0.01))
        for s, psi in enumerate((0.0, 100.0, -150.0))
    ]
    alike, _ = read_balance(logs, CFG, 0.2, "slip")
    free, _ = read_balance(logs, CFG, 0.2, "slip", free=True)
    assert alike is not None and free is not None
    lo, hi = free.tilt_interval()
    assert lo <= 1.2 <= hi < 2.0 and free.tilt == pytest.approx(1.2, abs=0.2)
    assert abs(alike.tilt - 1.2) > 0.3  # the mixture
