"""``RoverSim.drive``: a stretch of log rows driven at once (the replay's loop) gives the
numbers the row-by-row ``set_speed_targets`` + ``step`` gives, to the bit, on every path
(plain fast backend, a hinge effect, a command effect, the numpy backend); bad targets are
refused with their row and wheel."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rover_env.config import RoverConfig
from rover_env.sim.simulator import RoverSim

EXTENSIONS = [
    ({}, "plugin"),
    ({"rolling_resistance": {"c_rr": 0.05}}, "plugin"),
    ({"command_lag": {"tau": 0.1}}, "plugin"),
    ({}, "numpy"),
]


def rows(n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Speed targets with steps and reversals (some beyond the motor's range: clipped)."""
    rng = np.random.default_rng(3)
    targets = np.repeat(rng.uniform(-5.0, 5.0, size=(n // 8, 4)), 8, axis=0)
    steps = rng.integers(3, 6, size=len(targets))
    return targets, steps


@pytest.mark.parametrize(("ext", "backend"), EXTENSIONS)
def test_drive_matches_row_by_row(ext: dict, backend: str) -> None:
    cfg = replace(RoverConfig(), extensions=ext)
    a, b = RoverSim(cfg, backend=backend), RoverSim(cfg, backend=backend)
    a.reset(settle=0.2)
    b.reset(settle=0.2)
    targets, steps = rows(16 if backend == "numpy" else 40)
    for u, n in zip(targets, steps, strict=True):
        a.set_speed_targets(u)
        a.step(int(n))
    b.drive(targets, steps)
    assert np.array_equal(a.data.qpos, b.data.qpos)
    assert np.array_equal(a.data.qvel, b.data.qvel)
    assert np.array_equal(a.speed_targets, b.speed_targets)
    assert np.abs(a.data.qvel).max() > 0.1  # it moved


def test_drive_refuses_non_finite_targets() -> None:
    sim = RoverSim(backend="plugin")
    targets, steps = rows(16)
    targets[5, 2] = np.nan
    with pytest.raises(ValueError, match="row 5 for wheel 2L"):
        sim.drive(targets, steps)
