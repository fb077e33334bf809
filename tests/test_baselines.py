"""Baselines tuned fairly (rover_env.benchmark.baselines): the objective is the env's
return under the agent's reward weights, the tuner keeps the best setting, seeds stay in
their splits."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rover_env.benchmark import baselines as bl
from rover_env.benchmark.run import ScenarioWrapper, run_episode
from rover_env.benchmark.stats import t_interval
from rover_env.config import ConfigError
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.policies.specs import make_controller
from rover_env.tasks.reward import RewardWeights
from rover_env.tasks.scenarios import load_scenario

WEIGHTS = RewardWeights(
    tracking=0.0,
    speed_tracking=2.0,
    yaw_tracking=1.0,
    progress=2.0,
    slip=0.1,
    energy=0.002,
    sinkage=0.001,
)
"""Weights of the kind an agent trains with (configs/agents/soil-families-ppo.yaml's)."""


def test_return_is_the_sum_of_the_env_rewards_under_the_given_weights() -> None:
    """run_episode's ``return`` on an env of default weights, given the agent's weights,
    equals the rewards summed by hand from an env built with those weights; on loose soil
    it differs from the default-weight return by exactly the sinkage term."""
    episode = load_scenario("sand-slope@train").episode(1000, duration=1.0)
    ctrl = make_controller("open-loop@ramp=2")
    own = ScenarioWrapper(ProtoExplorerEnv(**episode.env_kwargs(), reward_weights=WEIGHTS))
    own.set_episode(episode)
    obs, _ = own.reset()
    ctrl.reset(own.base)
    total, sinkage_mm, done = 0.0, 0.0, False
    while not done:
        obs, reward, term, trunc, info = own.step(ctrl.action(own.base, obs))
        terms = [k for k in info if k.startswith("reward_")]
        assert "reward_progress" in terms and "reward_sinkage" in terms
        assert reward == pytest.approx(sum(info[k] for k in terms), abs=1e-12)
        total += float(reward)
        sinkage_mm += 1000.0 * float(np.mean(info["wheel_sinkage"]))
        done = term or trunc
    assert sinkage_mm > 1.0  # loose soil: the sinkage weight matters here

    shared = ScenarioWrapper(ProtoExplorerEnv(**episode.env_kwargs()))
    m = run_episode(shared, ctrl, episode, reward_weights=WEIGHTS)
    assert m["return"] == pytest.approx(total, rel=1e-12, abs=1e-12)
    plain = run_episode(shared, ctrl, episode, reward_weights=replace(WEIGHTS, sinkage=0.0))
    assert m["return"] - plain["return"] == pytest.approx(-0.001 * sinkage_mm, rel=1e-9)
    assert "return" not in run_episode(shared, ctrl, episode)  # no weights, no return


def test_weighted_interval_of_one_group_is_the_t_interval() -> None:
    x = [1.0, 2.5, 0.5, 4.0]
    assert bl.weighted_interval({"a": x}, {"a": 3.0}) == pytest.approx(t_interval(x))
    m, lo, hi = bl.weighted_interval({"a": x, "b": [10.0, 12.0]}, {"a": 1.0, "b": 3.0})
    assert m == pytest.approx(0.25 * np.mean(x) + 0.75 * 11.0)
    assert lo < m < hi


def _objective() -> bl.Objective:
    return bl.Objective(
        "test", "rover_env/ProtoExplorerFamilies-v0", {"flat-turns@train": 1.0}, WEIGHTS
    )


def test_tuner_keeps_the_best_setting_and_scores_from_the_rows(tmp_path: Path) -> None:
    """On flat hard ground the open loop at the commanded pace tracks; at 2.2 x it does not:
    the tuner must rank it first on tuning and choose it on validation."""
    grid = bl.Baseline("ol", "open-loop", ("gain", "ramp"), ((2.2, 1.0), (0.0,)), "test grid")
    res = bl.tune_baselines(_objective(), [1000], [2000], [grid], top=1, duration=1.5, log=None)
    (r,) = res.results
    fast, exact = (s.objective[0] for s in r.tuning)
    assert exact > fast
    assert [s.spec for s in r.finalists] == ["open-loop@gain=1@ramp=0"]
    assert res.best.chosen.spec == "open-loop@gain=1@ramp=0"
    (row,) = [x for x in res.rows if x["split"] == "validation"]
    assert row["seed"] == 2000
    assert r.chosen.objective[0] == pytest.approx(row["return"])
    assert {x["seed"] for x in res.rows if x["split"] == "tuning"} == {1000}
    d = bl.paired_difference(res, "open-loop@gain=1@ramp=0", "open-loop@gain=2.2@ramp=0", "tuning")
    assert d[0] == pytest.approx(exact - fast)

    cfg = bl.write_config(tmp_path / "baselines.yaml", res, "cmd")
    assert bl.load_tuned(cfg) == {"ol": "open-loop@gain=1@ramp=0"}
    rows = bl.read_episodes(bl.write_episodes(tmp_path / "episodes.jsonl", res))
    again = bl.from_rows(res.objective, rows, [grid], duration=1.5)
    assert [s.objective for s in again.results[0].tuning] == [s.objective for s in r.tuning]
    assert again.best.chosen.objective == r.chosen.objective
    text = bl.write_report(tmp_path / "baselines.md", res).read_text()
    assert "open-loop@gain=2.2@ramp=0" in text and "**Best baseline: ol" in text


@pytest.mark.parametrize(
    ("tune", "val", "what"),
    [
        ([4000], [2000], "tuning"),
        ([3000], [2000], "tuning"),
        ([1000], [4000], "validation"),
        ([1000], [3999], "validation"),
        ([2000], [2001], "tuning"),
        ([1000], [1001], "validation"),
    ],
)
def test_tuner_refuses_seeds_outside_their_split(
    tune: list[int], val: list[int], what: str
) -> None:
    grid = bl.Baseline("ol", "open-loop", ("gain", "ramp"), ((1.0,), (0.0,)), "test grid")
    with pytest.raises(ValueError, match=f"not {what} seeds"):
        bl.tune_baselines(_objective(), tune, val, [grid], duration=0.5, log=None)


def test_objective_of_reads_the_agents_families_and_weights(tmp_path: Path) -> None:
    good = tmp_path / "agent.yaml"
    good.write_text(
        "rover_env/ProtoExplorerFamilies-v0:\n  n_timesteps: 10\n  env_kwargs:\n"
        "    scenarios: {sand-slope@train: 2.0, flat-turns@train: 1.0}\n"
        "    reward_weights: {tracking: 1.0, slip: 1.0, energy: 0.02, sinkage: 0.02}\n"
    )
    obj = bl.objective_of(good)
    assert obj.scenarios == {"sand-slope@train": 2.0, "flat-turns@train": 1.0}
    assert obj.reward_weights == RewardWeights(sinkage=0.02)
    assert dict(obj.weight_pairs)["sinkage"] == 0.02
    bad = tmp_path / "bad.yaml"
    bad.write_text("x:\n  env_kwargs:\n    scenarios: {flat-turns@train: 0}\n")
    with pytest.raises(ConfigError, match=r"bad.yaml: x.env_kwargs.scenarios.flat-turns@train"):
        bl.objective_of(bad)
    bad.write_text("x:\n  env_kwargs:\n    scenarios: {no-such@train: 1}\n")
    with pytest.raises(ConfigError, match=r"scenarios.no-such@train"):
        bl.objective_of(bad)


def test_grids_are_the_stated_settings() -> None:
    """Each baseline's grid builds 10-12 valid controllers."""
    for b in bl.BASELINES:
        specs = b.settings()
        assert 8 <= len(specs) <= 12, b.name
        for s in specs:
            make_controller(s)


def test_objective_is_the_agents_return_at_zero_residual() -> None:
    """The agent's own env (its config's env_kwargs, one family for speed) with a zero
    residual on its base ``open-loop@ramp=2`` earns, on a validation seed, exactly the
    return the tuner scores for that base: the same episode, the same reward."""
    from rover_env.benchmark.mixture import families_env
    from rover_env.config import load_yaml

    path = "configs/agents/soil-families-ppo.yaml"
    ((_, entry),) = load_yaml(path).items()
    kwargs = {**entry["env_kwargs"], "scenarios": {"flat-turns@train": 1.0}}
    env = families_env(**kwargs)
    env.reset(seed=2000)
    total, done = 0.0, False
    while not done:
        _, reward, term, trunc, _ = env.step(np.zeros(4, dtype=np.float32))
        total += reward
        done = term or trunc
    env.close()

    obj = bl.objective_of(path)
    episode = load_scenario("flat-turns@train").episode(2000)
    wrapper = ScenarioWrapper(ProtoExplorerEnv(**episode.env_kwargs()))
    base = make_controller(kwargs["residual_base"])
    m = run_episode(wrapper, base, episode, reward_weights=obj.reward_weights)
    assert m["return"] == pytest.approx(total, rel=1e-9)
    assert total > 0.5 * episode.duration / 0.1  # a tracking episode, not an empty one
