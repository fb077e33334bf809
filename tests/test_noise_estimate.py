"""White sensor noise read from the logs (``residuals.interpolation_residuals``) whatever the
rows' spacing: a logger drops rows and its time stamps jitter, and a plain second
difference then reads the motion as noise (stop 99)."""

from __future__ import annotations

import numpy as np
import pytest

from rover_env.calibration.residuals import even_differences, interpolation_residuals

SIGMA = 0.002


def _drive(t: np.ndarray, seed: int = 0) -> np.ndarray:
    """A wheel turning at 1-4 rad/s (varying) and a joint swinging, with white noise."""
    rng = np.random.default_rng(seed)
    wheel = 2.5 * t + 1.5 * np.sin(0.7 * t) / 0.7
    joint = 0.2 * np.sin(1.3 * t)
    return np.column_stack([wheel, joint]) + rng.normal(0.0, SIGMA, (t.size, 2))


def _spread(e: np.ndarray) -> np.ndarray:
    return 1.4826 * np.median(np.abs(e - np.median(e, axis=0)), axis=0)


def _times(kind: str, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 50.0, 0.02)
    if kind == "jitter":  # stamps +-3 ms around the nominal
        t[1:-1] += rng.uniform(-0.003, 0.003, t.size - 2)
    if kind == "drops":  # 5 % of the rows lost
        t = t[np.r_[True, rng.random(t.size - 1) > 0.05]]
    return t


@pytest.mark.parametrize("kind", ["even", "jitter", "drops"])
def test_the_noise_is_read_the_same_however_the_rows_are_spaced(kind: str) -> None:
    t = _times(kind)
    got = _spread(interpolation_residuals(t, _drive(t)))
    assert got == pytest.approx([SIGMA, SIGMA], rel=0.08)


def test_a_plain_second_difference_reads_jitter_as_noise() -> None:
    """What the estimate replaced: on jittered stamps the wheel's motion leaks in."""
    t = _times("jitter")
    plain = _spread(np.diff(_drive(t), n=2, axis=0)) / np.sqrt(6.0)
    assert plain[0] > 2 * SIGMA  # the wheel turns 1-4 rad/s: 3 ms of it is ~8 mrad
    assert plain[1] < 1.3 * SIGMA  # the slow joint barely notices


def test_on_even_rows_it_is_the_second_difference_over_root_six() -> None:
    t = _times("even")
    x = _drive(t)
    e = interpolation_residuals(t, x)
    assert np.allclose(np.abs(e), np.abs(np.diff(x, n=2, axis=0)) / np.sqrt(6.0))


def test_pose_fixes_are_differenced_only_across_even_gaps() -> None:
    t = np.arange(0.0, 20.0, 1.0)
    t = np.delete(t, [7])  # one fix missing
    x = np.column_stack([0.3 * t**2, t])
    d = even_differences(t, x, 3)
    assert len(d) == len(t) - 3 - 3  # the three differences that span the gap are left out
    assert np.allclose(d, 0.0)  # a quadratic's third differences vanish on even spacing
