"""Dead reckoning's own noise (study 71200): the standard error of the free wheels' path over
travel from the pose fixes' noise, read from the logs, and the odometry band widened by it."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from rover_env.calibration.diagnosis.odometry import widened, with_noise
from rover_env.calibration.diagnosis.state import ODOMETRY_BAND
from rover_env.estimation.dead_reckoning import (
    NOISE_SAMPLES,
    path_and_travel_of,
    pose_noise_parts,
    scale_noise,
)

R = 0.085


def drive(straight_s: int, turns: int) -> tuple[np.ndarray, np.ndarray]:
    """A 1 Hz pose and free-wheel angles: ``straight_s`` seconds at 0.2 m/s, a 4 s stop, a
    reversal, then ``turns`` seconds of weaving (a straight second between turning ones)."""
    speed = np.r_[np.full(straight_s, 0.2), np.zeros(4), np.full(6, -0.15), np.full(turns, 0.1)]
    rate = np.r_[np.zeros(straight_s + 10), np.tile([0.0, 0.25, -0.25], turns)[:turns]]
    yaw = np.r_[0.0, np.cumsum(rate)]
    heading = yaw[:-1] + 0.5 * rate
    x = np.r_[0.0, np.cumsum(speed * np.cos(heading))]
    y = np.r_[0.0, np.cumsum(speed * np.sin(heading))]
    phi = np.zeros((x.size, 6))
    phi[:, 4] = phi[:, 5] = np.r_[0.0, np.cumsum(speed)] / R
    return np.column_stack([x, y, yaw]), phi


@pytest.mark.parametrize("straight_s", [3, 30])
def test_the_standard_error_is_what_noisy_fixes_do_to_the_statistic(straight_s: int) -> None:
    pose, phi = drive(straight_s, turns=12)
    sens, travel, _ = pose_noise_parts(pose, phi, R)
    sigma = 0.005
    rng = np.random.default_rng(3)
    got = []
    for _ in range(800):
        noisy = pose.copy()
        noisy[:, :2] += rng.normal(0.0, sigma, (len(pose), 2))
        path, trav = path_and_travel_of(noisy, phi, R)
        got.append(path / trav - 1.0)
    predicted = sigma * math.sqrt(sens) / travel
    assert np.std(got) == pytest.approx(predicted, rel=0.1)
    # Within a straight run the fixes between intervals cancel: its sensitivity counts the
    # runs (a straight one, a reversal, the weave's straight seconds), not their metres, so
    # ten times the straight seconds (1.9 -> 7.3 m) reads the statistic 3.8 x better.
    assert sens == pytest.approx(14.0)
    assert predicted == pytest.approx(sigma * math.sqrt(14.0) / travel)
    assert travel == pytest.approx(1.9 if straight_s == 3 else 7.3)


def test_the_noise_is_read_from_the_logs_across_the_heading() -> None:
    pose, phi = drive(30, turns=12)
    rng = np.random.default_rng(4)
    sigma = 0.008
    noisy = pose.copy()
    noisy[:, :2] += rng.normal(0.0, sigma, (len(pose), 2))
    log = SimpleNamespace(t=np.arange(len(pose), dtype=float), pose=noisy, phi=phi)
    se, samples = scale_noise([log], R)  # type: ignore[list-item]
    sens, travel, _ = pose_noise_parts(pose, phi, R)
    assert samples >= NOISE_SAMPLES
    assert se == pytest.approx(sigma * math.sqrt(sens) / travel, rel=0.35)
    # Too few straight intervals to measure it: no standard error.
    short = SimpleNamespace(t=np.arange(6.0), pose=noisy[:6], phi=phi[:6])
    se, samples = scale_noise([short], R)  # type: ignore[list-item]
    assert samples < NOISE_SAMPLES and math.isnan(se)


def test_the_band_widens_in_quadrature_about_its_centre() -> None:
    b = ODOMETRY_BAND
    same = widened(b, 0.0)
    assert (same.lo, same.hi, same.ci_lo, same.ci_hi) == pytest.approx(
        (b.lo, b.hi, b.ci_lo, b.ci_hi)
    )
    w = widened(b, 0.01)
    assert w.hi - b.mid == pytest.approx(math.hypot(b.hi - b.mid, b.noise_z * 0.01))
    assert b.mid - w.lo == pytest.approx(math.hypot(b.mid - b.lo, b.noise_z * 0.01))
    assert w.ci_hi - b.mid == pytest.approx(math.hypot(b.ci_hi - b.mid, 1.96 * 0.01))
    assert w.mid == b.mid and w.split == b.split
    # Three drives' straight travel (about 0.25 %) barely moves the band.
    assert widened(b, 0.0025).hi == pytest.approx(b.hi, abs=0.0015)


def test_without_a_noise_reading_the_statistic_names_nothing() -> None:
    band, why = with_noise(ODOMETRY_BAND, math.nan, 3)
    assert band == ODOMETRY_BAND and why is not None and "3 straight pose intervals" in why
    off = ODOMETRY_BAND.__class__(**{**ODOMETRY_BAND.__dict__, "noise_z": 0.0})
    assert with_noise(off, math.nan, 3) == (off, None)
    assert with_noise(off, 0.02, 30) == (off, None)


def test_few_drives_reads_the_names_without_the_rule_from_the_same_run(tmp_path) -> None:
    import json

    from _bench import load_bench

    bench = load_bench("few_drives")
    refused = {"named": False, "without_noise": "named", "why_not": "within", "difference": 0.03}
    kept = {"named": True, "without_noise": "named", "difference": -0.08}
    clean = {"named": False, "without_noise": "within what clean drives leave"}
    assert bench.without_noise([], refused) == ["rolling_radius"]
    assert bench.without_noise(["command_lag"], refused) == ["command_lag", "rolling_radius"]
    assert bench.without_noise(["rolling_radius"], kept) == ["rolling_radius"]
    assert bench.without_noise(["slope"], clean) == ["slope"]
    assert bench.without_noise(["slope"], None) == ["slope"]
    rows = [
        {  # a clean case the rule kept from a radius
            "case": "c",
            "kind": "clean",
            "truth": "none",
            "drives": 1,
            "named": [],
            "named_off": ["rolling_radius"],
            "acted": True,
            "partner_limits": None,
            "rule": "odometry_noise",
            "odometry": {**refused, "noise_se": 0.02, "noise_samples": 4},
            "diagnose_s": 30.0,
        },
        {  # a radius named either way
            "case": "r",
            "kind": "single",
            "truth": {"rolling_radius": {"fraction": -0.08}},
            "drives": 1,
            "named": ["rolling_radius"],
            "named_off": ["rolling_radius"],
            "acted": False,
            "partner_limits": None,
            "rule": "odometry_noise",
            "odometry": {**kept, "noise_se": 0.005, "noise_samples": 30},
            "diagnose_s": 40.0,
        },
    ]
    path = tmp_path / "rows.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    text = bench.report(path, tmp_path / "t.md")
    assert "cases where the rule acted (its decision differed): 1" in text
    assert "right names the rule removed (H1): 0 in 0 cases" in text
    assert "wrong names the rule removed: 1 in 1 cases" in text
    assert "| c | none | - | rolling_radius | +3.00 % (se 2.00 %, 4 intervals): within |" in text


def test_the_report_asks_for_a_straight_where_the_drives_cannot_read_a_radius() -> None:
    """Advice, not a decision: too few straight intervals, or a standard error of 1 % or more,
    and no radius named; nothing where the statistic is read to better than that."""
    from rover_env.calibration.report_reckoning import reckoning_lines as _reckoning_lines

    both = {"both": 0.035, "3L": 0.034, "3R": 0.036}
    r = {
        "logs": both,
        "model": {"both": 0.0, "3L": 0.0, "3R": 0.0},
        "difference": both,
        "band": [-0.025, 0.025],
        "named": False,
        "noise_se": math.nan,
        "noise_samples": 3,
        "why_not": "3 straight pose intervals: too few to measure the pose's own noise",
    }
    text = " ".join(_reckoning_lines(r))
    assert "only 3 straight pose intervals" in text
    assert "rover-env drive-plan --plan straight" in text
    noisy = {**r, "noise_se": 0.022, "noise_samples": 16, "band_with_noise": [-0.07, 0.07]}
    assert "a 2.2 % standard error" in " ".join(_reckoning_lines(noisy))
    for quiet in ({**noisy, "noise_se": 0.004}, {**noisy, "named": True}):
        assert "drive-plan" not in " ".join(_reckoning_lines(quiet))


def test_a_fast_pose_reference_is_read_as_one_hz_fixes() -> None:
    """A 10 Hz pose (motion capture, RTK) reads what 1 Hz fixes read: between 10 Hz fixes a
    rover at 0.2 m/s moves 2 cm, under the 5 cm an interval needs, so unthinned it reads
    nothing; 1 Hz fixes come back unchanged."""
    from rover_env.estimation.dead_reckoning import FIX_SPACING, fixes, path_and_travel

    f = -0.05
    t = np.arange(0.0, 30.0 + 1e-9, 0.1)
    speed = np.where(t < 20.0, 0.2, 0.1)
    x = np.r_[0.0, np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))]
    pose = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    phi = np.zeros((t.size, 6))
    phi[:, 4] = phi[:, 5] = np.r_[0.0, np.cumsum(np.abs(np.diff(x)))] / (R * (1 + f))
    fast = SimpleNamespace(t=t, pose=pose, phi=phi)
    assert path_and_travel_of(pose, phi, R) == (0.0, 0.0)
    path, travel = path_and_travel(fast, R)  # type: ignore[arg-type]
    assert path / travel - 1 == pytest.approx(f, abs=1e-9)
    kept = np.flatnonzero(np.isfinite(fixes(t, pose)[:, 0]))
    assert np.all(np.diff(t[kept]) >= FIX_SPACING - 1e-9)
    assert np.all(np.diff(t[kept]) <= FIX_SPACING + 0.1 + 1e-9)
    slow = np.where((np.round(t * 10) % 10 == 0)[:, None], pose, np.nan)
    assert np.array_equal(fixes(t, slow), slow, equal_nan=True)
    # A yaw between whole fixes is not a fix: left where it is.
    yaw_only = pose.copy()
    yaw_only[::3, :2] = np.nan
    got = fixes(t, yaw_only)
    assert np.array_equal(got[::3], yaw_only[::3], equal_nan=True)


def test_the_replay_reads_a_fast_pose_as_the_same_fixes() -> None:
    """prepare thins a 50 Hz pose as dead reckoning does (the pose's share of each window's
    loss was measured on 1 Hz fixes); a 1 Hz pose is left as it is."""
    from rover_env.calibration.replay import ReplaySettings, prepare
    from rover_env.config import load_rover
    from rover_env.estimation.dead_reckoning import fixes
    from rover_env.logs import DriveLog, LogMeta

    n = 501
    t = np.arange(n) / 50.0
    pose = np.column_stack([0.2 * t, np.zeros(n), np.zeros(n)])
    meta = LogMeta(rover="proto_explorer", sample_rate_hz=50.0, terrain="flat")
    log = DriveLog(t, np.zeros((n, 4)), np.zeros((n, 6)), np.zeros((n, 5)), pose, meta)
    cfg, st = load_rover("proto_explorer"), ReplaySettings()
    kept = np.isfinite(prepare(log, cfg, "fast", st).log.pose[:, 0])
    assert 10 <= kept.sum() <= 12 and np.array_equal(kept, np.isfinite(fixes(t, pose)[:, 0]))
    slow = np.where((np.arange(n) % 50 == 0)[:, None], pose, np.nan)
    log1 = DriveLog(t, log.cmd, log.phi, log.theta, slow, meta)
    assert np.array_equal(prepare(log1, cfg, "slow", st).log.pose, slow, equal_nan=True)
