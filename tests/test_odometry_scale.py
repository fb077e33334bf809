"""benchmarks/odometry_scale.py: dead reckoning from the free wheels against the pose reads
a rolling radius change off the logs (stop 74's lead for issue 47)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from _bench import load_bench

from rover_env.calibration.diagnosis.odometry import refusal, twin_scales
from rover_env.calibration.diagnosis.state import OdometryBand
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


BAND = OdometryBand(lo=-0.02, hi=0.02, mid=0.0, ci_lo=-0.01, ci_hi=0.01, split=0.03)


def _diff(both: float, left: float, right: float, driven: float | None = None) -> dict[str, float]:
    """A difference per wheel set; the driven wheels read the free wheels' by default."""
    return {"both": both, "3L": left, "3R": right, "driven": both if driven is None else driven}


def test_odometry_names_only_beyond_the_band_with_both_free_wheels_agreeing() -> None:
    assert refusal(_diff(-0.045, -0.05, -0.04), BAND, set()) is None
    assert refusal(_diff(0.03, 0.02, 0.04), BAND, {"slope"}) is None
    assert "within" in str(refusal(_diff(0.015, 0.01, 0.02), BAND, set()))
    # One free wheel alone (a dragging brake): not a radius, however large.
    assert "disagree" in str(refusal(_diff(0.04, 0.08, 0.0), BAND, set()))
    assert "already" in str(refusal(_diff(-0.05, -0.05, -0.05), BAND, {"rolling_radius"}))
    assert "bulldoze" in str(refusal(_diff(0.05, 0.05, 0.05), BAND, {"loose_soil"}))
    # Decided before the twins are made: named already, soil; else None.
    assert refusal(None, BAND, {"slope"}) is None
    assert "bulldoze" in str(refusal(None, BAND, {"loose_soil"}))
    assert "no straight" in str(refusal(_diff(math.nan, math.nan, math.nan), BAND, set()))


def test_odometry_is_asked_after_a_withdrawn_name_and_says_which() -> None:
    """A trade, the rotor test or the clean-fit allowance withdraws what the windows named;
    the wheels' travel is still asked (nothing in :func:`refusal` depends on it), and the
    record names what was withdrawn, each effect once."""
    from types import SimpleNamespace

    from rover_env.calibration.diagnosis.odometry import withdrawn

    d = SimpleNamespace(
        traded={"effects": ["friction", "slope"]},
        rotor_withdrawn={"effects": ["torque_limit", "slope"]},
        allowance_withdrawn=None,
    )
    assert withdrawn(d) == ["friction", "slope", "torque_limit"]  # type: ignore[arg-type]
    none = SimpleNamespace(traded=None, rotor_withdrawn=None, allowance_withdrawn=None)
    assert withdrawn(none) == []  # type: ignore[arg-type]
    assert refusal(_diff(-0.05, -0.05, -0.05), BAND, set()) is None


def test_odometry_asks_the_driven_wheels_to_read_the_same_change() -> None:
    """A radius moves every wheel's travel alike; loose soil bulldozes the free wheels while
    the driven ones slip (spent loose soils: +15 to +35 % free, -0.64 to +0.18 x that
    driven), and a rolling resistance drags the free wheels and slips the driven ones."""
    for both, driven in ((-0.06, -0.06), (-0.06, -0.04), (0.05, 0.07), (0.05, 0.03)):
        assert refusal(_diff(both, both, both, driven), BAND, set()) is None
    for both, driven in (
        (0.2, -0.02),
        (0.027, -0.018),
        (-0.04, -0.01),
        (0.05, 0.08),
        (0.04, math.nan),
    ):
        why = str(refusal(_diff(both, both, both, driven), BAND, set()))
        assert "driven wheels read" in why, (both, driven)


def test_the_models_twins_read_its_rolling_radius_one_for_one(tmp_path) -> None:
    """The twins' statistic moves by the radius change times d / r_e: what the stage's
    sensitivity measures (a physics check of the model, not of the rule)."""
    from rover_env.calibration.replay import ReplaySettings, prepare
    from rover_env.config import load_rover
    from rover_env.estimation.estimator import static_rolling_radius
    from rover_env.generators.make_logs import make_logs
    from rover_env.logs import read_log

    (path,) = make_logs(tmp_path, {}, drives=1, seed=3, duration=20.0, progress=False)
    cfg = load_rover()
    r_e = static_rolling_radius(cfg)
    p = prepare(read_log(path), cfg, "drive", ReplaySettings())
    nominal = twin_scales(cfg, [p], r_e)
    # The model against itself: the free wheels roll at r_e (the driven ones slip).
    assert all(abs(nominal[k]) < 0.01 for k in ("both", "3L", "3R"))
    f = -0.06
    shrunk = dataclasses.replace(cfg, extensions={"rolling_radius": {"fraction": f}})
    moved = twin_scales(shrunk, [p], r_e)
    expect = f * cfg.geometry.wheel_radius / r_e
    assert moved["both"] - nominal["both"] == pytest.approx(expect, rel=0.05)
    # Every wheel's travel moves alike: what the stage's driven-wheel check asks of a radius.
    assert moved["driven"] - nominal["driven"] == pytest.approx(expect, rel=0.25)


def test_the_report_line_gives_the_difference_and_the_verdict() -> None:
    from rover_env.calibration.report_reckoning import reckoning_lines as _reckoning_lines

    r = {
        "logs": _diff(-0.04, -0.045, -0.035),
        "model": _diff(0.002, 0.003, 0.001),
        "difference": _diff(-0.042, -0.048, -0.036, 0.01),
        "band": [-0.02, 0.02],
        "named": False,
        "why_not": "the driven wheels read +1.00 % against the free wheels' -4.20 %",
    }
    (line,) = [x for x in _reckoning_lines(r) if x]
    assert "travels -4.20 % against this model's twins" in line
    assert "the driven wheels +1.00 %" in line and "driven wheels read" in line
    assert "held-out windows" not in line
    named = {**r, "named": True, "held_gain": -0.16, "p_worse": 8e-5}
    (line,) = [x for x in _reckoning_lines(named) if x]
    assert "named the rolling radius" in line
    assert "held-out windows are 16 % worse (one-sided p of worse 8e-05)" in line
    r["difference"] = _diff(math.nan, math.nan, math.nan)
    assert _reckoning_lines(r) == []
    soil = {"band": [-0.02, 0.02], "named": False, "why_not": "loose soil is named"}
    assert "not compared with this model's twins (loose soil is named)" in _reckoning_lines(soil)[1]


def static_r_e_over_r(r: dict) -> float:
    """r_e over the wheel radius of the configuration a diagnosis ran on."""
    from rover_env.config import load_rover
    from rover_env.estimation.estimator import static_rolling_radius

    cfg = load_rover(r["config"] or "proto_explorer")
    return static_rolling_radius(cfg) / cfg.geometry.wheel_radius


def test_diagnose_names_a_radius_the_windows_miss_from_dead_reckoning(tmp_path) -> None:
    """The stage inside a whole diagnosis (this project's own logs: identifiability, not
    validity): an 8 % smaller radius that the windows do not name is named by odometry, its
    interval holding the truth, and written into rover.yaml. Two 24 s drives hold about 2 m
    of straight, moving travel, which the pose's own noise reads to about 1.7 %: the band
    widens to about +-6 % there (a 3 % radius is named only on longer straight driving)."""
    import yaml

    from rover_env.calibration.diagnosis.pipeline import diagnose
    from rover_env.calibration.diagnosis.state import Options
    from rover_env.generators.make_logs import make_logs

    truth = -0.08
    paths = make_logs(
        tmp_path / "logs",
        {"rolling_radius": {"fraction": truth}},
        drives=2,
        seed=5,
        duration=24.0,
        progress=False,
    )
    opts = Options(candidates=["rolling_radius", "command_delay"], progress=False, max_nfev=3)
    r = diagnose([str(p) for p in paths], tmp_path / "out", opts)
    assert r["named"] == ["rolling_radius"]
    f = r["final"]["rolling_radius"]
    assert f["test"].startswith("odometry")
    value, lo, hi = f["params"]["rolling_radius"]["fraction"]
    assert lo <= truth <= hi and hi < 0.0
    dr = r["dead_reckoning"]
    assert dr["named"] and dr["difference"]["both"] < dr["band_with_noise"][0] < -0.025
    # The report's "named from": the band's edge in radius units, which the truth is beyond;
    # the windows' own bar for the radius is lowered to it (either route names a radius).
    edge = (dr["centre"] - dr["band_with_noise"][0]) * static_r_e_over_r(r)
    assert dr["nameable"]["-"] == pytest.approx(edge, rel=1e-9) and edge < -truth
    assert r["fits"]["rolling_radius"]["nameable"]["-"] <= dr["nameable"]["-"]
    cfg = yaml.safe_load((tmp_path / "out" / "rover.yaml").read_text())
    assert cfg["extensions"]["rolling_radius"]["fraction"] == pytest.approx(value)
