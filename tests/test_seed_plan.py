"""Every entry point keeps a seed inside its split (issue 17): a validation seed plays a
validation episode, and the episodes of different splits never meet."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import rover_env
from rover_env import seeds as seed_plan
from rover_env.benchmark.mixture import ScenarioMixEnv
from rover_env.benchmark.run import ScenarioWrapper
from rover_env.benchmark.scenarios import load_scenario
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.seeds import (
    HELD_OUT,
    SPLITS,
    check_split,
    draw_seed,
    refuse_final_only,
    split_of,
)

gym.register_envs(rover_env)
MIX = "rover_env/ProtoExplorerScenarioMix-v0"
# A few seeds of every split, from both ends of each block.
SPLIT_SEEDS = {name: [r.start, r.start + 1, r.stop - 1] for name, r in SPLITS.items()}
USABLE = {name: s for name, s in SPLIT_SEEDS.items() if name != "spent"}


def test_split_of_and_checks() -> None:
    for name, r in SPLITS.items():
        assert {split_of(s) for s in (r.start, r.stop - 1)} == {name}
    assert split_of(0) == split_of(1999) == "training"  # outside every block: not held out
    assert check_split([2000, 2099], "validation", "here") == [2000, 2099]
    with pytest.raises(ValueError, match=r"here: seeds \[4000\] are not validation seeds"):
        check_split([2000, 4000], "validation", "here")
    rng = np.random.default_rng(0)
    assert all(split_of(draw_seed("test", rng)) == "test" for _ in range(50))


def test_spent_block_takes_no_new_use() -> None:
    """The old test block 3000-3999 was looked at by the final runs before issue 46."""
    assert split_of(3000) == split_of(3999) == "spent" and split_of(4000) == "test"
    assert "spent" in HELD_OUT
    for use in (
        lambda: draw_seed("spent", np.random.default_rng(0)),
        lambda: seed_plan.seeds("spent", 3),
        lambda: check_split([3000], "spent", "here"),
        lambda: refuse_final_only([3034], "here", final=True),
    ):
        with pytest.raises(ValueError, match=r"spent seeds 3000\.\.3999"):
            use()
    with pytest.raises(ValueError, match="played only by a final run"):
        refuse_final_only([4000], "here")
    refuse_final_only([4000, 2000, 100_000], "here", final=True)  # a final run may


def _mix_episodes(env: gym.Env[Any, Any], seed: int, follow_ups: int) -> list[Any]:
    """(scenario, jitter seed, episode) of a seeded reset and the unseeded resets after it."""
    out = []
    for k in range(follow_ups + 1):
        _, info = env.reset(seed=seed if k == 0 else None)
        assert info["seed_split"] == split_of(seed)
        out.append((info["scenario"], int(info["episode_seed"]), env.unwrapped._active.episode))
    return out


def test_scenario_mix_plays_each_seed_in_its_split() -> None:
    env = gym.make(MIX, scenarios=["split-mu", "ice-patch"])
    mix = env.unwrapped
    assert isinstance(mix, ScenarioMixEnv)
    played: dict[str, set[tuple[str, int]]] = {}
    for split, seed_list in USABLE.items():
        eps: set[tuple[str, int]] = set()
        for s in seed_list:
            # Test seeds are played seed by seed: no unseeded follow-up (next test).
            episodes = _mix_episodes(env, s, follow_ups=0 if split == "test" else 2)
            for scen, ep_seed, active in episodes:
                assert split_of(ep_seed) == split, (split, s, ep_seed)
                assert active.seed == ep_seed and active.scenario == scen
            if split != "training":
                # A held-out seed plays the benchmark's own episode of that seed.
                scen, ep_seed, active = episodes[0]
                assert ep_seed == s
                bench = load_scenario(scen).episode(s)
                assert active.start == bench.start and active.terrain == bench.terrain
            eps |= {(scen, ep_seed) for scen, ep_seed, _ in episodes}
        played[split] = eps
    names = list(played)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            assert not played[a] & played[b], f"{a} and {b} share episodes"
    env.close()


def test_scenario_mix_never_drifts_into_test_or_spent_seeds() -> None:
    """Issue 46: unseeded resets after a test seed went on drawing test seeds (3090, 3034)."""
    env = gym.make(MIX, scenarios=["split-mu", "ice-patch"])
    _, info = env.reset(seed=SPLITS["test"].start)
    assert info["episode_seed"] == SPLITS["test"].start  # a final run's own seed plays
    with pytest.raises(ValueError, match="unseeded reset after a test seed"):
        env.reset()
    with pytest.raises(ValueError, match="spent seeds"):
        env.reset(seed=3090)
    _, info = env.reset(seed=SPLITS["validation"].start)  # a seeded reset leaves the test block
    for _ in range(5):
        _, info = env.reset()
        assert split_of(info["episode_seed"]) == "validation"
    _, info = env.reset(seed=100_000)
    for _ in range(20):
        _, info = env.reset()
        assert split_of(info["episode_seed"]) == "training"
    env.close()


def test_scenario_mix_training_draws_are_unchanged() -> None:
    """Training seeds draw (scenario, jitter seed) exactly as the shipped agents saw them."""
    env = gym.make(MIX, scenarios=["split-mu", "ice-patch", "stuck-wheel"])
    mix = env.unwrapped
    assert isinstance(mix, ScenarioMixEnv)
    for s in (100_000, 100_001, 7):
        _, info = env.reset(seed=s)
        rng = np.random.default_rng(s)  # gymnasium seeds np_random with PCG64(seed)
        i = int(rng.choice(3, p=mix.p))
        block = SPLITS["training"]
        assert info["scenario"] == mix.names[i]
        assert info["episode_seed"] == int(rng.integers(block.start, block.stop))
    env.close()


def test_plain_env_episodes_of_different_splits_differ() -> None:
    """The env's episode (start heading, command stream) is its seed's; none is shared."""
    env = gym.make("rover_env/ProtoExplorer-v0", sensor_noise="none")
    prints: dict[str, set[tuple[float, ...]]] = {}
    for split, seeds in SPLIT_SEEDS.items():
        prints[split] = set()
        for s in seeds:
            _, info = env.reset(seed=s)
            fp = (*np.round(info["command"], 12), round(float(env.unwrapped.sim.data.qpos[3]), 12))
            _, info2 = env.reset(seed=s)
            assert tuple(np.round(info2["command"], 12)) == fp[:2]  # same seed, same episode
            prints[split].add(fp)
    names = list(prints)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            assert not prints[a] & prints[b]
    env.close()


def test_scenario_wrapper_refuses_a_seed_other_than_its_episode() -> None:
    ep = load_scenario("ice-patch").episode(SPLITS["validation"].start, duration=0.3)
    w = ScenarioWrapper(ProtoExplorerEnv(terrain=ep.terrain))
    w.set_episode(ep)
    w.reset(seed=ep.seed)  # its own seed is fine
    with pytest.raises(ValueError, match="set_episode\\(\\) chooses the seed"):
        w.reset(seed=SPLITS["test"].start)
    w.close()


def test_vector_env_seed_block_stays_in_its_split() -> None:
    venv = gym.make_vec(
        "rover_env/ProtoExplorer-v0", num_envs=2, vectorization_mode="vector_entry_point"
    )
    venv.reset(seed=SPLITS["validation"].start)
    with pytest.raises(ValueError, match="not validation seeds"):
        venv.reset(seed=SPLITS["validation"].stop - 1)  # rover 1 would play seed 2100
    venv.close()


def test_training_envs_keep_their_split(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    from rover_env.training.config import AlgoConfig
    from rover_env.training.envs import SeedSchedule, make_env, make_vec_env

    cfg = AlgoConfig()
    env = make_env(MIX, cfg, [SPLITS["validation"].start], split="validation")
    _, info = env.reset()
    assert info["seed_split"] == "validation"
    assert info["episode_seed"] == SPLITS["validation"].start
    _, info = env.reset()  # past the list: the env's own stream, still validation
    assert split_of(info["episode_seed"]) == "validation"
    with pytest.raises(ValueError, match="not validation seeds"):
        env.reset(seed=SPLITS["training"].start)
    env.close()
    with pytest.raises(ValueError, match="not validation seeds"):
        SeedSchedule(gym.make("rover_env/ProtoExplorer-v0"), [SPLITS["test"].start], "validation")
    with pytest.raises(ValueError, match="not training seeds"):
        make_vec_env(MIX, cfg, 1, [[SPLITS["validation"].start]], None, "train")


def test_benchmark_runs_the_seeds_of_its_split(tmp_path: Path) -> None:
    import csv

    from rover_env.benchmark.cli import run_benchmark

    files = run_benchmark(
        ["open-loop"],
        ["ice-patch"],
        2,
        tmp_path,
        split="validation",
        duration=0.2,
        progress=False,
        plots=False,
    )
    with files["episodes"].open() as fh:
        seeds = [int(r["seed"]) for r in csv.DictReader(fh)]
    assert seeds == [SPLITS["validation"].start, SPLITS["validation"].start + 1]
