"""The pace line (issue 46): success is the goal reached at the commanded pace, so a
controller that drives twice the command cannot pass it."""

from __future__ import annotations

import numpy as np
import pytest

from rover_env.benchmark.metrics import PACE_TOLERANCE, episode_metrics

N, DT, V = 100, 0.1, 0.15


def _episode(
    speed_factor: float, v: float = V, w: float = 0.0, yaw_factor: float = 1.0
) -> dict[str, float]:
    """A steady synthetic episode: the rover moves at ``speed_factor`` x the command."""
    step = abs(v) * speed_factor * DT
    return episode_metrics(
        slip_abs_step=np.zeros((N, 4)),
        tracking_error_speed=np.full(N, abs(v) * abs(speed_factor - 1.0)),
        tracking_error_yaw_rate=np.zeros(N),
        energy=np.ones(N),
        distance=np.full(N, step),
        start=np.zeros(3),
        end=np.array([step * N, 0.0, 0.0]),
        flipped=False,
        commanded_path=abs(v) * N * DT,
        command=np.tile([v, w], (N, 1)),
        speed=np.full(N, v * speed_factor),
        yaw_rate=np.full(N, w * yaw_factor),
        step_dt=DT,
    )


@pytest.mark.parametrize(
    ("factor", "pace"), [(1.0, 1), (0.8, 1), (1.24, 1), (1.3, 0), (0.7, 0), (2.0, 0)]
)
def test_pace_line_on_a_synthetic_trace(factor: float, pace: int) -> None:
    m = _episode(factor)
    assert m["pace_ratio"] == pytest.approx(factor)
    assert m["goal"] == 1.0  # every one of them gets there (half the commanded path)
    assert m["pace_ok"] == pace and m["success"] == pace
    # The goal is half the commanded path: reached after half the episode at the command.
    assert m["time_to_goal"] == pytest.approx(N * DT / 2 / factor, abs=DT)


def test_twice_the_command_fails_the_pace_line_and_keeps_its_goal() -> None:
    m = _episode(2.0)
    assert m["goal"] == 1.0 and m["success"] == 0.0 and m["pace_ratio"] > 1 + PACE_TOLERANCE


def test_a_rover_that_misses_the_goal_fails_whatever_its_pace() -> None:
    m = _episode(0.4)
    assert m["goal"] == 0.0 and m["success"] == 0.0
    assert m["time_to_goal"] == pytest.approx(N * DT)  # censored at the played length


def test_turn_in_place_keeps_the_yaw_rate_pace() -> None:
    ok = _episode(0.0, v=0.0, w=0.3, yaw_factor=1.1)
    fast = _episode(0.0, v=0.0, w=-0.3, yaw_factor=2.0)
    assert ok["pace_ratio"] == pytest.approx(1.1) and ok["pace_ok"] == 1.0
    assert fast["pace_ratio"] == pytest.approx(2.0) and fast["pace_ok"] == 0.0
    still = _episode(0.0, v=0.0, w=0.0)
    assert still["pace_ratio"] == 1.0 and still["pace_ok"] == 1.0  # no pace to keep


def test_reversing_command_counts_progress_along_it() -> None:
    m = _episode(1.0, v=-0.15)
    assert m["pace_ratio"] == pytest.approx(1.0) and m["success"] == 1.0


def test_open_loop_at_twice_the_command_fails_the_pace_line_in_the_env() -> None:
    """One short real episode: the open loop with its wheel targets doubled reaches the goal
    and fails the pace line; the plain open loop passes both."""
    from rover_env.benchmark.run import Job, run_jobs

    plain, double = run_jobs(
        [
            Job("open-loop", "flat-turns", 2000, 3.0),
            Job("open-loop@gain=2", "flat-turns", 2000, 3.0),
        ]
    )
    assert plain["success"] == 1.0 and abs(plain["pace_ratio"] - 1.0) < 0.1
    assert double["goal"] == 1.0 and double["success"] == 0.0
    assert double["pace_ratio"] == pytest.approx(2.0, abs=0.1)
    assert double["time_to_goal"] < plain["time_to_goal"]
