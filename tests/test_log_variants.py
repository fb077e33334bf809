"""benchmarks/log_variants.py: the same drive as another logger would write it (no pose, the
pose at the end only, rows dropped, stamps jittered, half the rate). Each variant is still
a valid SPEC §6 log, and holds the motion it was made from."""

from __future__ import annotations

import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from _bench import load_bench

from rover_env.calibration.residuals import resolution
from rover_env.logs import DriveLog, LogMeta, read_log, write_log

COUNT = 2 * math.pi / 1024


@pytest.fixture(scope="module")
def lv() -> ModuleType:
    return load_bench("log_variants")


def _log(n: int = 1001) -> DriveLog:
    t = np.arange(n) * 0.02
    cmd = np.tile([1.0, 1.0, 1.2, 1.2], (n, 1))
    phi = np.floor(np.outer(2.0 * t + 0.3 * np.sin(t), np.ones(6)) / COUNT) * COUNT
    theta = np.round(np.outer(0.1 * np.sin(t), np.ones(5)) / 1e-3) * 1e-3
    pose = np.full((n, 3), np.nan)
    pose[::50] = np.column_stack([0.1 * t[::50], 0.0 * t[::50], 0.01 * t[::50]])
    return DriveLog(t, cmd, phi, theta, pose, LogMeta("proto_explorer", 50.0))


def test_pose_variants_keep_no_fix_or_the_last_one(lv: ModuleType) -> None:
    log = _log()
    assert not lv.variant("no-pose", log, 1).has_pose
    end = lv.variant("end-pose", log, 1)
    fixes = np.flatnonzero(np.isfinite(end.pose[:, 0]))
    assert fixes.tolist() == [1000] and np.array_equal(end.pose[1000], log.pose[1000])


def test_dropped_rows_keep_the_ends_and_are_drawn_from_the_seed(lv: ModuleType) -> None:
    log = _log()
    a, b, c = (lv.variant("drop5", log, s) for s in (1, 1, 2))
    assert a.t[0] == 0.0 and a.t[-1] == log.t[-1]
    assert 0.02 < 1 - len(a) / len(log) < 0.09
    assert np.array_equal(a.t, b.t) and not np.array_equal(a.t, c.t)
    i = np.searchsorted(log.t, a.t)
    assert np.array_equal(a.phi, log.phi[i])  # the rows kept are as logged


def test_jittered_stamps_read_the_angles_there_within_a_count(lv: ModuleType) -> None:
    log = _log()
    j = lv.variant("jitter3", log, 1)
    dt = j.t - log.t
    assert np.all(np.abs(dt) <= 0.003 + 1e-12) and np.all(np.diff(j.t) > 0)
    assert dt[0] == 0.0 and dt[-1] == 0.0 and np.std(dt) > 0.001
    true = np.floor(np.outer(2.0 * j.t + 0.3 * np.sin(j.t), np.ones(6)) / COUNT) * COUNT
    assert np.max(np.abs(j.phi - true)) <= COUNT + 1e-12
    assert resolution(j.phi) == pytest.approx(COUNT)  # still whole counts
    assert np.array_equal(j.cmd, log.cmd)


def test_half_rate_says_so_and_every_variant_writes_a_readable_log(
    lv: ModuleType, tmp_path: Path
) -> None:
    log = _log()
    half = lv.variant("rate25", log, 1)
    assert half.meta.sample_rate_hz == 25.0 and len(half) == 501
    for name in lv.VARIANTS:
        path = write_log(lv.variant(name, log, 3), tmp_path / f"{name}.csv")
        back = read_log(path)
        assert len(back) == len(lv.variant(name, log, 3)), name


def test_an_effect_is_given_in_the_generators_own_parameter(lv: ModuleType) -> None:
    assert lv.parse_effect(None) == {}
    assert lv.parse_effect("rolling_resistance=0.04") == {"rolling_resistance": {"c_rr": 0.04}}
    assert lv.parse_effect("slope=4,heading_deg=60") == {"slope": {"deg": 4.0, "heading_deg": 60.0}}


def test_the_table_gives_the_named_fit_else_the_fitted_one(lv: ModuleType) -> None:
    base = {"wheel_noise": [0.00125] * 4, "seconds": 70.0}
    rows = [
        {
            "variant": "as-logged",
            "named": ["rolling_resistance"],
            **base,
            "named_fits": {"rolling_resistance": {"c_rr": [0.07, 0.004, 0.085]}},
            "fits": {},
        },
        {
            "variant": "drop5",
            "named": [],
            **base,
            "named_fits": {},
            "fits": {"rolling_resistance": {"rolling_resistance": {"c_rr": [0.086, 0.0, 0.097]}}},
        },
        {"variant": "jitter3", "error": "ValueError: bad"},
    ]
    text = lv.table(rows, {"rolling_resistance": {"c_rr": 0.04}})
    assert (
        "| as-logged | rolling_resistance | 0.07 [0.004, 0.085] | 1.25, 1.25, 1.25, 1.25 | 70 |"
        in text
    )
    assert "| drop5 | - | 0.086 [0, 0.097] (not named) |" in text
    assert "| jitter3 | error: ValueError: bad |" in text
