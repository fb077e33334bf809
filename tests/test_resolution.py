"""The sensors' quantisation step found in the logs (``residuals.resolution``): the replay
floor reads the model's twins through it, so a missed step makes every wheel look worse
than a perfect model."""

from __future__ import annotations

import math

import numpy as np

from rover_env.calibration.residuals import resolution

COUNT = 2 * math.pi / 1024


def _encoder(counts_per_sample: float, n: int = 3000, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    rate = counts_per_sample * (1.0 + 0.2 * np.sin(np.linspace(0.0, 20.0, n)))
    angle = np.cumsum(rate * COUNT) + rng.uniform(0.0, COUNT)
    return np.floor(angle / COUNT)[:, None] * COUNT


def test_a_slow_encoder_step_is_found() -> None:
    assert abs(resolution(_encoder(0.7)) - COUNT) < 1e-12


def test_a_fast_wheel_whose_one_count_moves_are_rare_is_still_quantised() -> None:
    x = _encoder(6.0)
    d = np.abs(np.diff(x[:, 0]))
    d = d[d > 0]
    assert np.mean(np.isclose(d, COUNT)) < 0.01  # the case the 1st percentile missed
    assert abs(resolution(x) - COUNT) < 1e-12


def test_continuous_noisy_data_is_not_quantised() -> None:
    rng = np.random.default_rng(1)
    x = np.cumsum(rng.normal(0.03, 0.01, 3000))[:, None]
    assert resolution(x) == 0.0
