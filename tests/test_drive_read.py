"""``RoverSim.drive_read`` (a replay window's rows driven in one call, the state read after
chosen rows) gives the numbers one ``drive`` per stretch between reads gives, to the bit, on
every path: plain, command effects, hinge effects, the numpy backend. A speed change must not
change what ``diagnose`` finds."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rover_env.config import RoverConfig
from rover_env.sim.simulator import RoverSim

CASES = [
    ({}, "plugin"),
    ({"command_lag": {"tau": 0.05}}, "plugin"),
    ({"command_lag": {"tau": 0.05}, "command_delay": {"delay": 0.013}}, "plugin"),
    ({"rolling_resistance": {"c_rr": 0.05}}, "plugin"),
    ({}, "numpy"),
]
IDS = ["plain", "lag", "lag+delay", "hinge", "numpy"]


def _sims(ext: dict[str, dict[str, float]], backend: str) -> tuple[RoverSim, RoverSim]:
    cfg = dataclasses.replace(RoverConfig(), extensions=ext)
    return RoverSim(cfg, backend=backend), RoverSim(cfg, backend=backend)


def _reads(sim: RoverSim) -> tuple[np.ndarray, int]:
    ix = sim.index
    return np.concatenate([ix.wheel_qpos, ix.joint_qpos]), int(ix.seg_body[2])


@pytest.mark.parametrize(("ext", "backend"), CASES, ids=IDS)
def test_drive_read_is_drive_per_stretch(ext: dict[str, dict[str, float]], backend: str) -> None:
    """Reads before any row, twice after the same row, after a zero-substep row, and rows
    driven after the last read: the same reads and the same final state as stretch by
    stretch, with the last row's targets held."""
    one, by = _sims(ext, backend)
    rng = np.random.default_rng(11)
    n = 12 if backend == "numpy" else 40
    targets = rng.uniform(-3, 3, (n, 4))
    steps = rng.integers(0, 12, n)
    steps[5] = 0
    after = np.array([0, 1, 4, 4, 6, n // 2, n - 3])
    qi, body = _reads(one)
    q, xp, xr = one.drive_read(targets, steps, after, qi, body)
    k, want = 0, []
    for r in [*after.tolist(), n]:
        by.drive(targets[k:r], steps[k:r])
        k = r
        want.append((by.data.qpos[qi].copy(), by.data.xpos[body].copy(), by.data.xmat[body].copy()))
    for j in range(len(after)):
        np.testing.assert_array_equal(q[j], want[j][0])
        np.testing.assert_array_equal(xp[j], want[j][1])
        np.testing.assert_array_equal(xr[j], want[j][2])
    for a in ("qpos", "qvel", "ctrl"):
        np.testing.assert_array_equal(getattr(one.data, a), getattr(by.data, a), a)
    np.testing.assert_array_equal(one.speed_targets, by.speed_targets)
    assert not np.array_equal(q[0], q[-1]), "the rover did not move"


def test_drive_read_refuses_unsorted_or_outside_reads() -> None:
    sim = RoverSim(backend="plugin")
    qi, body = _reads(sim)
    targets, steps = np.zeros((3, 4)), np.full(3, 2)
    with pytest.raises(ValueError, match="sorted row counts"):
        sim.drive_read(targets, steps, [2, 1], qi, body)
    with pytest.raises(ValueError, match="sorted row counts"):
        sim.drive_read(targets, steps, [4], qi, body)


def test_drive_read_names_a_bad_row() -> None:
    """A non-finite target is refused by the row that holds it, as ``drive`` refuses it."""
    sim = RoverSim(backend="plugin")
    qi, body = _reads(sim)
    targets = np.zeros((5, 4))
    targets[3, 2] = np.nan
    with pytest.raises(ValueError, match="row 3 for wheel 2L"):
        sim.drive_read(targets, np.full(5, 2), [3], qi, body)
