"""Missing evidence: the proposed drive separates the hypotheses in simulation (issue 16)."""

from __future__ import annotations

import pytest

from rover_env.calibration.evidence import propose, separation, simulate_plan
from rover_env.calibration.replay import SIGNALS
from rover_env.config import RoverConfig

# Replay floors of a typical case (make-logs sensors): wheels, joints, pose.
FLOOR = {s: 0.003 for s in SIGNALS[:6]} | {s: 0.002 for s in SIGNALS[6:11]}
FLOOR |= {"pose_x": 0.012, "pose_y": 0.012, "pose_yaw": 0.017}


def test_hard_accelerations_separate_a_torque_limit() -> None:
    """The proposed drive, replayed as diagnose replays, moves the driven wheels by many
    floors with a lowered torque limit."""
    ext = {"torque_limit": {"fraction": -0.25}}
    p = propose(RoverConfig(), "torque_limit", ext, FLOOR, {"wheel_1L": 0.2}, duration=12.0)
    assert p["plan"] == "accel"
    assert p["best_signal"].startswith("wheel_")
    assert p["separates"] and p["best_floor_units"] >= 3.0


def test_separation_of_a_drive_with_itself_is_zero() -> None:
    log = simulate_plan(RoverConfig(), "accel", duration=6.0)
    assert max(separation(log, log, FLOOR).values()) == 0.0


@pytest.mark.slow
def test_a_measured_straight_separates_a_rolling_radius_the_pose_sees() -> None:
    """Rolling radius -3 % on all wheels: the joints and driven wheels hardly move in the
    replay; over a 50 s measured straight the pose does, by > 3 floors."""
    ext = {"rolling_radius": {"fraction": -0.03}}
    floor = FLOOR | {"wheel_3L": 0.011, "wheel_3R": 0.011}
    p = propose(RoverConfig(), "rolling_radius", ext, floor, {"pose_x": 1.4})
    assert p["plan"] == "straight" and p["separates"]
    assert p["separation"]["pose_x"] >= 3.0
    assert max(p["separation"][s] for s in SIGNALS[6:11]) < 1.0
