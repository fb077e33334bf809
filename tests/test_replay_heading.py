"""The replay starts each window with the rover's true heading (issue 16, stop 31).

Under vertical gravity a window's absolute heading is invisible, so a sign error in it
(segment 1's heading from segment 3's and the yaw joints) went unseen until a slope: the
tilt then acted in the wrong direction, the truth itself replayed the free wheels at
0.78 rad RMS and slopes were fitted low.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rover_env.calibration import residuals as rs
from rover_env.calibration.fit import Evaluator
from rover_env.calibration.replay import ReplaySettings, make_windows, prepare
from rover_env.config import load_rover
from rover_env.generators.make_logs import make_logs
from rover_env.logs import read_log


def test_a_slope_drive_replays_under_its_truth(tmp_path: Path) -> None:
    truth = {"slope": {"deg": 6.0, "heading_deg": 90.0}}  # a cross-slope to the left
    paths = make_logs(tmp_path, truth, drives=1, seed=3, duration=21.0, progress=False)
    st = ReplaySettings()
    base = load_rover("proto_explorer")
    prep = [prepare(read_log(p), base, p.name, st) for p in paths]
    windows = make_windows(prep, st)
    ev = Evaluator(base, st, prep, {"all": windows}, scale=rs.noise_floor(prep), log=lambda m: None)

    def free_wheel_rms(ext: dict) -> float:
        res = ev.run(ext, "all")
        return float(np.sqrt(np.mean(np.concatenate([r.resid[:, 4:6] for r in res]) ** 2)))

    at_truth, without = free_wheel_rms(truth), free_wheel_rms({})
    # Encoders resolve 0.01 rad; a window's initial state leaves a few hundredths.
    assert at_truth < 0.06, (at_truth, without)
    assert at_truth < 0.3 * without, (at_truth, without)
