"""The training profiler's accounting, and the shipped PPO recipe's batched collection (issue 49)."""

from __future__ import annotations

import shutil
import tempfile
from typing import Any

import pytest

pytest.importorskip("stable_baselines3")

from rover_env.training import load_algo_config, profiling
from rover_env.training.config import AlgoConfig, parse_algo_config

ENV = "rover_env/ProtoExplorer-v0"
needs_cc = pytest.mark.skipif(
    not any(shutil.which(c) for c in ("gcc", "cc")),
    reason="the batched env needs the compiled tire plugin (a C compiler)",
)


def test_timers_count_exclusive_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """A stage's time is its own, less that of the timed calls inside it; rows add up."""
    clock = [0.0]
    monkeypatch.setattr(profiling.time, "perf_counter", lambda: clock[0])
    timers = profiling.Timers()

    def physics() -> None:
        clock[0] += 3.0

    inner = timers.wrap("physics", physics)

    def env() -> None:
        clock[0] += 1.0
        inner()
        inner()
        clock[0] += 0.5

    outer = timers.wrap("env Python (episodes)", env)
    timers.wrap("other", lambda: (outer(), clock.__setitem__(0, clock[0] + 2.0)))()
    assert timers.seconds["physics"] == 6.0 and timers.calls["physics"] == 2
    assert timers.seconds["env Python (episodes)"] == 1.5
    assert timers.seconds["other"] == 2.0
    assert sum(timers.seconds.values()) == clock[0] == timers.outer_s == 9.5
    with pytest.raises(ValueError, match="unknown stage"):
        timers.wrap("nonsense", physics)


def _tiny(algo: str, **over: Any) -> AlgoConfig:
    base: dict[str, Any] = {
        "n_envs": 2,
        "vec_env": "batch",
        "policy_kwargs": {"net_arch": [16, 16]},
        "max_episode_steps": 6,
        "batch_size": 8,
    }
    if algo == "ppo":
        base.update(n_steps=8, n_epochs=1)
    else:
        base.update(learning_starts=4, buffer_size=100)
    return parse_algo_config(algo, {**base, **over}, "test")


@needs_cc
@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_profile_attributes_the_run_to_its_stages(
    algo: str, tmp_path: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    p = profiling.profile_training(ENV, _tiny(algo), 16, warmup=8 if algo == "sac" else 0)
    assert not list(tmp_path.glob("SB3-*"))  # no logger folder left in the temp dir
    assert p.steps == 16
    for stage in ("physics", "env Python (episodes)", "adapter + VecMonitor", "VecNormalize"):
        assert p.seconds[stage] > 0, stage
    for stage in ("policy inference", "rollout/replay buffer", "gradient update"):
        assert p.seconds[stage] > 0, stage
    assert p.seconds["env workers (subprocess)"] == 0.0
    # Every timed call ran inside learn()'s timer, so the exclusive rows add up to its time
    # (a call timed outside it, or counted twice, would break this). The wall clock read
    # around learn() adds only the timer's start-up, unless the scheduler preempts between
    # the two clocks (a loaded machine), so it is checked one way only.
    assert sum(p.seconds.values()) == pytest.approx(p.timed_s, rel=1e-9)
    assert 0.5 * p.wall_s < p.timed_s <= p.wall_s
    lines = profiling.table([p])
    assert lines[0].startswith("| ms per env step") and any("physics" in x for x in lines)


@pytest.mark.parametrize(
    "env_id", ["rover_env/ProtoExplorer-v0", "rover_env/ProtoExplorerRough-v0"]
)
def test_shipped_ppo_collects_on_the_batched_env_with_the_old_update_grid(env_id: str) -> None:
    """The batched recipe keeps the 1024 env steps per update of 2 envs x 512 steps (so the
    updates per env step, and with them the learning curve per step, stay the same)."""
    cfg = load_algo_config("ppo", "ppo", env_id)
    assert cfg.vec_env == "batch" and cfg.n_envs > 2
    assert cfg.rollout_size == 1024 and cfg["n_epochs"] == 10
    mix = load_algo_config("ppo", "ppo", "rover_env/ProtoExplorerScenarioMix-v0")
    assert mix.vec_env == "subproc"  # no batched env for the scenario mix


@needs_cc
def test_profile_command_line(tmp_path: Any, capsys: pytest.CaptureFixture[str]) -> None:
    import yaml

    cfg = tmp_path / "ppo_tiny.yaml"
    entry = {"n_envs": 2, "vec_env": "batch", "n_steps": 8, "batch_size": 8, "n_epochs": 1}
    cfg.write_text(yaml.safe_dump({ENV: {**entry, "max_episode_steps": 6}}))
    assert profiling.profile_main(["--config", str(cfg), "--steps", "16"]) == 0
    printed = capsys.readouterr().out
    assert "| physics |" in printed and "| gradient update |" in printed
    assert profiling.profile_main(["--config", str(tmp_path / "none.yaml")]) == 2
    assert "not found" in capsys.readouterr().out
