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
