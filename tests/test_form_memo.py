"""The form stages' replay memo (``form_ladder.replay``): a repeat of a replay is the same
replay to the bit, and anything the replay reads (configuration, prepared logs, windows)
makes it a new one."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration.diagnosis import form_ladder
from rover_env.calibration.diagnosis.form import with_yaw_spring
from rover_env.calibration.diagnosis.form_ladder import replay, reprepare
from rover_env.calibration.replay import (
    PreparedLog,
    Replayer,
    ReplaySettings,
    Window,
    WindowResult,
    make_windows,
    prepare,
)
from rover_env.config import RoverConfig
from rover_env.generators.make_logs import make_logs
from rover_env.logs import read_log

CFG = RoverConfig()
ST = ReplaySettings()
Logs = tuple[list[PreparedLog], list[Window]]


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> Logs:
    root: Path = tmp_path_factory.mktemp("memo")
    paths = make_logs(root, {}, drives=1, seed=3, duration=12.0, progress=False)
    prepared = [prepare(read_log(p), CFG, p.name, ST) for p in paths]
    return prepared, make_windows(prepared, ST)[:3]


def _same(a: list[WindowResult], b: list[WindowResult]) -> bool:
    return len(a) == len(b) and all(
        np.array_equal(x.resid, y.resid) and np.array_equal(x.sim, y.sim)
        for x, y in zip(a, b, strict=True)
    )


def test_a_repeat_is_remembered_and_equals_a_fresh_replay(logs: Logs) -> None:
    prepared, windows = logs
    first = replay(CFG, prepared, windows, ST)
    again = replay(CFG, reprepare(prepared, CFG, ST), list(windows), ST)
    assert again is first  # logs prepared again for the same rover: the same inputs
    assert _same(first, Replayer(CFG, ST).run(prepared, windows))


def test_what_the_replay_reads_makes_a_new_one(logs: Logs) -> None:
    prepared, windows = logs
    first = replay(CFG, prepared, windows, ST)
    stiff = with_yaw_spring(CFG, 20.0)
    assert replay(stiff, prepared, windows, ST) is not first
    wide = replace(CFG, geometry=replace(CFG.geometry, half_track=CFG.geometry.half_track * 1.1))
    other = reprepare(prepared, wide, ST)  # its heading from the free wheels differs
    assert not np.array_equal(other[0].yaw3, prepared[0].yaw3)
    assert replay(CFG, other, windows, ST) is not first
    assert replay(CFG, prepared, windows[:2], ST) is not first


def test_the_memo_is_bounded(logs: Logs) -> None:
    prepared, windows = logs
    for k in range(form_ladder.MEMO_SIZE + 3):
        replay(with_yaw_spring(CFG, 10.0 + k), prepared, windows[:1], ST)
    assert form_ladder.remembered() == form_ladder.MEMO_SIZE
