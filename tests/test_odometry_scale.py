"""benchmarks/odometry_scale.py: dead reckoning from the free wheels against the pose reads
a rolling radius change off the logs (stop 74's lead for issue 47)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _bench import load_bench

from rover_env.estimation.dead_reckoning import path_and_travel
from rover_env.logs import DriveLog, LogMeta

odo = load_bench("odometry_scale")


def _drive(f: float, turn_every: int = 0) -> DriveLog:
    """A 1 Hz-pose drive at 0.3 m/s whose wheels have rolling radius r_e (1 + f): the free
    wheels turn by path / (r_e (1 + f)); every ``turn_every``-th second it also turns."""
    t = np.arange(0.0, 40.0 + 1e-9, 0.02)
    n = t.size
    heading = np.zeros(n)
    if turn_every:  # every turn_every-th second it yaws at 1 rad/s: an arc, not a chord
        turning = (np.floor(t) % turn_every) == turn_every - 1
        heading = np.cumsum(np.r_[0.0, 0.02 * turning[:-1]])
    s = 0.3 * t
    x = np.cumsum(np.r_[0.0, np.diff(s) * np.cos(heading[1:])])
    y = np.cumsum(np.r_[0.0, np.diff(s) * np.sin(heading[1:])])
    wheel = s / (odo.R_E * (1.0 + f))
    phi = np.tile(wheel[:, None], (1, 6))
    pose = np.full((n, 3), np.nan)
    every = round(1.0 / 0.02)
    pose[::every] = np.c_[x, y, heading][::every]
    meta = LogMeta(rover="proto_explorer", sample_rate_hz=50.0, terrain={"name": "flat"})
    return DriveLog(
        t=t, cmd=np.zeros((n, 4)), phi=phi, theta=np.zeros((n, 5)), pose=pose, meta=meta
    )


def test_the_statistic_reads_the_rolling_radius_change() -> None:
    for f in (-0.06, 0.0, 0.04):
        assert odo.scale([_drive(f)]) == pytest.approx(f, abs=1e-9)


def test_turning_seconds_do_not_count() -> None:
    # A turn shortens the chord between pose samples; those intervals are left out, so the
    # statistic stays at the truth (with them it would read short).
    d = _drive(0.02, turn_every=4)
    _, travel = path_and_travel(d, odo.R_E)
    assert 0.3 * 40.0 * 0.7 / 1.02 < travel < 0.3 * 40.0 * 0.8 / 1.02  # 30 of 40 seconds
    assert odo.scale([d]) == pytest.approx(0.02, abs=1e-6)
    # Counting every interval, the turns' chords would read the radius short.
    every = d.pose[np.isfinite(d.pose[:, 0])]
    chords = np.hypot(*np.diff(every[:, :2], axis=0).T).sum()
    wheels = (d.phi[-1, 4] - d.phi[0, 4]) * odo.R_E
    assert chords / wheels - 1.0 < 0.02 - 0.004


def test_no_straight_moving_interval_gives_nan() -> None:
    d = _drive(0.0)
    still = DriveLog(d.t, d.cmd, np.zeros_like(d.phi), d.theta, d.pose, d.meta)
    assert math.isnan(odo.scale([still]))


def test_diagnose_reports_the_logs_against_the_models_twins() -> None:
    from rover_env.calibration.diagnosis.floor import reckon
    from rover_env.calibration.report import _reckoning_lines
    from rover_env.config import load_rover
    from rover_env.estimation.estimator import static_rolling_radius

    cfg = load_rover()
    assert odo.R_E == pytest.approx(0.0761, abs=1e-4)  # d - delta/3, as the generator's
    k = static_rolling_radius(cfg) / odo.R_E  # the helper's drives are built at R_E
    r = reckon(cfg, [_drive(0.05)], [_drive(0.01)])
    assert r["logs"] == pytest.approx(1.05 / k - 1.0) and r["model"] == pytest.approx(
        1.01 / k - 1.0
    )
    assert r["difference"] == pytest.approx(0.04 / k)
    (line,) = [x for x in _reckoning_lines(r) if x]
    assert f"travels {100 * r['difference']:+.2f} % against this model" in line
    still = _drive(0.0)
    still = DriveLog(
        still.t, still.cmd, np.zeros_like(still.phi), still.theta, still.pose, still.meta
    )
    assert _reckoning_lines(reckon(cfg, [still], [still])) == []
