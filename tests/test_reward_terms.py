"""The reward of a step, written once in rover_env.tasks.reward: its terms and their sum."""

from __future__ import annotations

import math

import numpy as np

from rover_env.tasks import RandomTracking
from rover_env.tasks.reward import RewardWeights, StepResult, reward_terms


def _result(**kw: object) -> StepResult:
    base: dict[str, object] = {
        "tracking_error_speed": 0.02,
        "tracking_error_yaw_rate": 0.05,
        "mean_abs_slip": 0.1,
        "energy": 3.0,
        "distance": 0.015,
        "against": False,
        "speed_command": 0.15,
        "control_dt": 0.1,
        "wheel_sinkage": np.full(6, 0.004),
        "flipped": False,
        "out_of_arena": False,
    }
    base.update(kw)
    return StepResult(**base)  # type: ignore[arg-type]


def test_default_weights_give_the_three_tracking_terms_and_their_sum() -> None:
    r = _result()
    total, terms = reward_terms(RewardWeights(), r)
    assert list(terms) == ["reward_tracking", "reward_slip", "reward_energy"]
    track = 0.5 * (math.exp(-((0.02 / 0.05) ** 2)) + math.exp(-((0.05 / 0.1) ** 2)))
    assert terms["reward_tracking"] == track
    assert terms["reward_slip"] == -0.1
    assert terms["reward_energy"] == -0.02 * 3.0 / 0.1
    assert total == (track + -0.1) + terms["reward_energy"]


def test_mobility_terms_appear_with_their_weights_and_count_against_the_command() -> None:
    w = RewardWeights(progress=2.0, stall_energy=0.5, sinkage=0.1)
    total, terms = reward_terms(w, _result(against=True))
    assert list(terms)[3:] == ["reward_progress", "reward_stall_energy", "reward_sinkage"]
    assert terms["reward_progress"] == 2.0 * -0.015 / 0.1
    # moving against the command: no progress, so all the power is charged
    assert terms["reward_stall_energy"] == -0.5 * 1.0 * 3.0 / 0.1
    assert terms["reward_sinkage"] == -0.1 * 1000.0 * 0.004
    assert total == sum(terms.values())


def test_the_task_ends_the_episode_on_a_flip_or_leaving_the_arena() -> None:
    task = RandomTracking(0.2, 0.3, (4.0, 8.0))
    assert not task.terminated(_result())
    assert task.terminated(_result(flipped=True))
    assert task.terminated(_result(out_of_arena=True))


def test_speed_tracking_pays_the_pace_alone_so_standing_still_earns_no_pace() -> None:
    """``speed_tracking`` adds the speed term on its own: a stopped rover on a straight
    command (e_v = the command, e_w = 0) earns the yaw term only, a rover at the pace both."""
    w = RewardWeights(tracking=0.0, speed_tracking=2.0, yaw_tracking=1.0, slip=0.0, energy=0.0)
    stopped = reward_terms(w, _result(tracking_error_speed=0.15, tracking_error_yaw_rate=0.0))
    at_pace = reward_terms(w, _result(tracking_error_speed=0.0, tracking_error_yaw_rate=0.0))
    assert stopped[1]["reward_tracking"] == 1.0 + 2.0 * math.exp(-9.0)
    assert at_pace[1]["reward_tracking"] == 3.0
    plain = RewardWeights(slip=0.0, energy=0.0)  # tracking 1: half of it for the yaw rate
    assert reward_terms(plain, _result(tracking_error_speed=0.15, tracking_error_yaw_rate=0.0))[
        0
    ] == 0.5 + 0.5 * math.exp(-9.0)
