"""PPO training: config validation, run dir, resume after a kill, command lines (CPU, < 2 min)."""

from __future__ import annotations

import csv
import os
import pickle
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")

from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import DummyVecEnv

from rover_env.config import ConfigError
from rover_env.envs.registration import ENV_IDS, V1_ENV_IDS
from rover_env.training import load_config, train
from rover_env.training.callbacks import checkpoint_paths, latest_checkpoint

ENV = "rover_env/ProtoExplorer-v0"
REPO = Path(__file__).resolve().parent.parent
# Tiny but complete: 2 envs, 64-step rollouts, an evaluation and a checkpoint every rollout,
# 20-step episodes so that episodes finish and the learning curve has points.
SMALL: dict[str, Any] = {
    "n_timesteps": 256,
    "n_envs": 2,
    "vec_env": "dummy",
    "learning_rate": "lin_3e-4",
    "n_steps": 32,
    "batch_size": 32,
    "n_epochs": 2,
    "policy_kwargs": {"net_arch": [16, 16], "activation": "tanh"},
    "max_episode_steps": 20,
    "eval_freq": 64,
    "n_eval_episodes": 1,
    "checkpoint_freq": 64,
}


def _config(tmp_path: Path, **over: Any) -> Path:
    path = tmp_path / "ppo_test.yaml"
    path.write_text(yaml.safe_dump({ENV: {**SMALL, **over}}))
    return path


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


# --------------------------------------------------------------------------- configuration


def test_shipped_config_has_both_env_ids() -> None:
    for env_id in (*ENV_IDS, *V1_ENV_IDS):
        cfg = load_config(REPO / "configs" / "ppo.yaml", env_id)
        assert cfg["learning_rate"].linear and cfg["learning_rate"].start == pytest.approx(3e-4)
        assert cfg["batch_size"] <= cfg.rollout_size
    assert load_config("ppo", ENV) == load_config(REPO / "configs" / "ppo.yaml", ENV)


@pytest.mark.parametrize("name", ["ppo.yaml", "gsde.yaml"])
def test_resolved_config_round_trips(tmp_path: Path, name: str) -> None:
    env = ENV if name == "ppo.yaml" else "rover_env/ProtoExplorerScenarioMix-v0"
    src = REPO / "configs" / name
    if name == "gsde.yaml":  # a gSDE variant: its schedules and SDE settings resolve too
        src = tmp_path / name
        src.write_text(
            f"base: {REPO / 'configs' / 'ppo.yaml'}\n{env}:\n"
            "  use_sde: true\n  sde_sample_freq: 4\n  policy_kwargs: {log_std_init: -3.0}\n"
        )
    cfg = load_config(src, env)
    path = tmp_path / "resolved.yaml"
    path.write_text(yaml.safe_dump({env: cfg.to_dict()}))
    assert load_config(path, env) == cfg
    assert cfg["use_sde"] == (name == "gsde.yaml")


@pytest.mark.parametrize(
    ("over", "match"),
    [
        ({"n_step": 32}, r"unknown key\(s\) n_step"),
        ({"policy_kwargs": {"activaton": "relu"}}, r"policy_kwargs: unknown key\(s\) activaton"),
        ({"normalize": {"norm_obs": True, "clip": 5}}, r"normalize: unknown key\(s\) clip"),
        ({"learning_rate": "lin_fast"}, r"learning_rate: expected a number"),
        ({"vec_env": "threads"}, r"vec_env: expected one of subproc, dummy"),
        ({"gamma": 1.5}, r"gamma: must be in \(0, 1\]"),
        ({"batch_size": 128}, r"batch_size: 128 exceeds n_steps \* n_envs = 64"),
        ({"policy_kwargs": {"activation": "sigmoid"}}, r"activation: expected one of"),
        ({"use_sde": "yes"}, r"use_sde: expected true or false"),
        ({"sde_sample_freq": -2}, r"sde_sample_freq: must be >= -1"),
        # names and types come from SB3's PPO signature, not from a list kept here
        ({"buffer_size": 1000}, r"unknown key\(s\) buffer_size; allowed: .*normalize_advantage"),
        ({"normalize_advantage": "no"}, r"normalize_advantage: expected true or false"),
        ({"stats_window_size": 2.5}, r"stats_window_size: expected an integer"),
        ({"device": "cuda"}, r"unknown key\(s\) device"),
    ],
)
def test_config_errors_name_key_and_file(tmp_path: Path, over: dict[str, Any], match: str) -> None:
    path = _config(tmp_path, **over)
    with pytest.raises(ConfigError, match=match) as exc:
        load_config(path, ENV)
    assert str(path) in str(exc.value) and ENV in str(exc.value)


def test_any_sb3_argument_is_taken_and_passed_on(tmp_path: Path) -> None:
    """An SB3 argument no config had used before is valid and reaches the model."""
    from rover_env.training.algos import build_model
    from rover_env.training.signature import parameters

    cfg = load_config(_config(tmp_path, normalize_advantage=False, clip_range_vf=0.3), ENV)
    assert cfg["normalize_advantage"] is False and cfg["clip_range_vf"].start == 0.3
    assert set(cfg.hyperparams) == set(parameters("ppo"))  # every other one at SB3's default
    assert cfg["stats_window_size"] == parameters("ppo")["stats_window_size"].default
    venv = DummyVecEnv([lambda: gym.make(ENV, max_episode_steps=8)])
    model = build_model(cfg, venv)
    assert model.normalize_advantage is False and model.clip_range_vf(1.0) == 0.3
    venv.close()


def test_missing_env_id_and_file(tmp_path: Path) -> None:
    path = _config(tmp_path)
    with pytest.raises(ConfigError, match="no entry for env id 'Nope-v0'"):
        load_config(path, "Nope-v0")
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "missing.yaml", ENV)


def test_bad_env_kwargs_fail_before_training(tmp_path: Path) -> None:
    path = _config(tmp_path, env_kwargs={"no_such_option": 1})
    with pytest.raises(ConfigError, match=r"env_kwargs.*no_such_option"):
        train(ENV, path, 0, tmp_path / "run", progress=False)
    assert not (tmp_path / "run").exists()


# --------------------------------------------------------------------------- resume


class _KillAfter(BaseCallback):
    """Stops training at the first step past ``step``: a run killed just after a checkpoint."""

    def __init__(self, step: int) -> None:
        super().__init__()
        self.step = step

    def _on_step(self) -> bool:
        return self.num_timesteps <= self.step


def _obs_count(path: Path) -> float:
    with path.open("rb") as fh:
        return float(pickle.load(fh).obs_rms.count)


def _lr_by_step(run: Path) -> dict[float, float]:
    return {
        float(r["time/total_timesteps"]): float(r["train/learning_rate"])
        for r in _rows(run / "progress.csv")
        if r.get("train/learning_rate")
    }


def test_resume_continues_counts_schedule_and_statistics(tmp_path: Path) -> None:
    cfg = _config(tmp_path)
    straight = train(ENV, cfg, 0, tmp_path / "straight", progress=False)
    assert straight.num_timesteps == 256

    split = tmp_path / "split"
    killed = train(ENV, cfg, 0, split, progress=False, callbacks=[_KillAfter(128)])
    assert killed.num_timesteps == 130 and latest_checkpoint(split / "checkpoints") == 128
    _, vn_128, state_128 = checkpoint_paths(split / "checkpoints", 128)
    count_128 = _obs_count(vn_128)
    with state_128.open("rb") as fh:
        best_128 = pickle.load(fh)["eval"]["best_mean_reward"]
    assert np.isfinite(best_128)
    twin = tmp_path / "twin"
    shutil.copytree(split, twin)

    resumed = train(None, None, None, split, resume=True, progress=False)
    assert resumed.resumed_from == 128
    assert resumed.num_timesteps == straight.num_timesteps == 256
    # VecNormalize kept counting: 128 more steps plus the 2 reset observations of the resume.
    assert _obs_count(split / "vecnormalize.pkl") == count_128 + 128 + 2
    assert (
        _obs_count(split / "vecnormalize.pkl")
        == _obs_count(tmp_path / "straight" / "vecnormalize.pkl") + 2
    )
    assert resumed.best_mean_reward >= best_128
    # The evaluation grid, the learning-rate schedule and the logs continue where they stopped.
    ev = np.load(split / "evaluations.npz")
    np.testing.assert_array_equal(
        ev["timesteps"], np.load(tmp_path / "straight" / "evaluations.npz")["timesteps"]
    )
    lr_split, lr_straight = _lr_by_step(split), _lr_by_step(tmp_path / "straight")
    assert 256 in lr_split and 128 in lr_split  # logged before the kill and after the resume
    assert all(lr_split[k] == pytest.approx(lr_straight[k]) for k in lr_split)
    steps = [int(r["timesteps"]) for r in _rows(split / "episodes.csv")]
    assert steps == sorted(steps) and steps[-1] <= 256
    # Random state carries over: resuming the same checkpoint twice gives the same weights.
    train(None, None, None, twin, resume=True, progress=False)
    a = PPO.load(split / "model.zip", device="cpu").policy.state_dict()
    b = PPO.load(twin / "model.zip", device="cpu").policy.state_dict()
    for k in a:
        np.testing.assert_array_equal(a[k].numpy(), b[k].numpy())


def test_resume_refuses_a_mismatch(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"no config\.yaml"):
        train(None, None, None, tmp_path, resume=True)
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yaml").write_text(yaml.safe_dump({ENV: SMALL}))
    (run / "command.txt").write_text(yaml.safe_dump([{"seed": 3}]))
    with pytest.raises(ConfigError, match="uses seed 3"):
        train(ENV, None, 4, run, resume=True)
    with pytest.raises(ConfigError, match="no complete checkpoint"):
        train(ENV, None, 3, run, resume=True)
    with pytest.raises(ConfigError, match="already holds a training run"):
        train(ENV, _config(tmp_path), 3, run)


# --------------------------------------------------------------------------- command lines


# Scripts under train/ must import this checkout's rover_env, not an installed one.
_ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *args], cwd=REPO, env=_ENV, capture_output=True, text=True, timeout=120
    )


def test_cli_train_kill_resume_evaluate(tmp_path: Path) -> None:
    cfg = _config(tmp_path, vec_env="subproc")
    run = tmp_path / "run"
    cmd = [sys.executable, "train/ppo.py", "--env-id", ENV, "--config", str(cfg), "--seed", "1"]
    proc = subprocess.Popen(
        [*cmd, "--out", str(run), "--total-timesteps", "100000", "--no-progress"],
        cwd=REPO,
        env=_ENV,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 90
        while (latest_checkpoint(run / "checkpoints") or 0) < 128:
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() < deadline, "no checkpoint within 90 s"
            time.sleep(0.2)
    finally:
        proc.kill()
        proc.wait()

    out = _run("train/ppo.py", "--resume", str(run), "--total-timesteps", "256", "--no-progress")
    assert out.returncode == 0, out.stderr
    assert "resumed at step" in out.stdout and ": 256 steps" in out.stdout
    for name in (
        "config.yaml",
        "command.txt",
        "model.zip",
        "vecnormalize.pkl",
        "best_model.zip",
        "best_vecnormalize.pkl",
        "progress.csv",
        "episodes.csv",
        "evaluations.csv",
        "evaluations.npz",
        "learning_curve.png",
        "monitor/train_0.monitor.csv",
        "checkpoints/ppo_256_steps.zip",
    ):
        assert (run / name).is_file(), name
    assert any((run / "tb").iterdir())
    commands = yaml.safe_load((run / "command.txt").read_text())
    assert [c["seed"] for c in commands] == [1, 1] and commands[1]["resumed_from_step"] >= 128
    assert all(c["env_id"] == ENV and c["rover_env_version"] for c in commands)
    assert load_config(run / "config.yaml", ENV).n_timesteps == 256

    bad = _run(
        "train/ppo.py", "--env-id", ENV, "--config", str(cfg), "--seed", "1", "--out", str(run)
    )
    assert bad.returncode == 2 and "already holds a training run" in bad.stderr

    # Loading in a fresh interpreter: the benchmark runs the saved agent as ppo:RUN_DIR.
    ev = _run(
        "train/evaluate.py",
        str(run),
        "--episodes",
        "1",
        "--scenarios",
        "flat-turns",
        "--duration",
        "1.5",
        "--which",
        "final",
        "--out",
        str(tmp_path / "ev"),
        "--quiet",
    )
    assert ev.returncode == 0, ev.stderr
    assert f"ppo:{run / 'model.zip'}" in ev.stdout and "flat-turns" in ev.stdout
    assert (tmp_path / "ev" / "benchmark.md").is_file()
    assert "validation split" in ev.stdout

    # The test seeds once: a second final run of the same agent is refused.
    (tmp_path / "q.yaml").write_text(
        "questions:\n  - {id: q, text: agent vs open loop, baseline: open-loop, "
        "scenarios: [flat-turns], controllers: ['ppo:*'], max_looks: 2}\n"
    )
    final = ["--which", "final", "--quiet", "--final", "--ledger", str(tmp_path / "ledger.csv")]
    final += ["--question", "q", "--questions", str(tmp_path / "q.yaml")]
    short = ["--episodes", "1", "--scenarios", "flat-turns", "--duration", "0.5"]
    ev = _run("train/evaluate.py", str(run), *short, *final, "--out", str(tmp_path / "f"))
    assert ev.returncode == 0, ev.stderr
    assert "test split" in ev.stdout and "Look 1 of 2 at question `q`" in ev.stdout
    with (tmp_path / "ledger.csv").open() as fh:
        base, row = list(csv.DictReader(fh))  # the question's baseline is recorded too
    assert (base["agent"], base["role"]) == ("open-loop", "baseline")
    assert row["agent"] == f"ppo:{run / 'model.zip'}" and row["role"] == "agent"
    ev = _run("train/evaluate.py", str(run), *short, *final, "--out", str(tmp_path / "f2"))
    assert ev.returncode == 3 and "already had its final test run" in ev.stderr


def test_best_model_is_paired_with_the_statistics_it_was_selected_with(tmp_path: Path) -> None:
    from rover_env.policies.ppo import resolve_model_path

    for name in ("best_model.zip", "model.zip", "vecnormalize.pkl", "best_vecnormalize.pkl"):
        (tmp_path / name).write_bytes(b"")
    assert resolve_model_path(tmp_path) == (
        tmp_path / "best_model.zip",
        tmp_path / "best_vecnormalize.pkl",
    )
    assert resolve_model_path(tmp_path / "model.zip") == (
        tmp_path / "model.zip",
        tmp_path / "vecnormalize.pkl",
    )
    (tmp_path / "best_vecnormalize.pkl").unlink()
    assert resolve_model_path(tmp_path)[1] == tmp_path / "vecnormalize.pkl"


class _FirstWeights(BaseCallback):
    """The policy's weights and observation count when learning starts."""

    def __init__(self) -> None:
        super().__init__()
        self.weights: dict[str, Any] = {}
        self.obs_count = 0.0

    def _on_training_start(self) -> None:
        self.weights = {k: v.clone() for k, v in self.model.policy.state_dict().items()}
        vn = self.model.get_vec_normalize_env()
        assert vn is not None
        self.obs_count = float(vn.obs_rms.count)

    def _on_step(self) -> bool:
        return True


def test_init_from_starts_a_new_run_from_a_trained_agent(tmp_path: Path) -> None:
    """``--init-from`` (rl-zoo's --trained-agent): the new run's first weights and statistics
    are the agent's, not a fresh network's; a network of another shape is refused, named."""
    cfg = _config(tmp_path, n_timesteps=64, eval_freq=0)
    src = train(ENV, cfg, 0, tmp_path / "src", progress=False)
    agent = PPO.load(str(src.run_dir / "model.zip"), device="cpu")
    with (src.run_dir / "vecnormalize.pkl").open("rb") as fh:
        stats = pickle.load(fh)
    seen, fresh = _FirstWeights(), _FirstWeights()
    train(ENV, cfg, 1, tmp_path / "tuned", progress=False, callbacks=[seen], init_from=src.run_dir)
    train(ENV, cfg, 1, tmp_path / "fresh", progress=False, callbacks=[fresh])
    for k, v in agent.policy.state_dict().items():
        assert np.array_equal(seen.weights[k].numpy(), v.numpy()), k
    assert any(
        not np.array_equal(fresh.weights[k].numpy(), v.numpy())
        for k, v in agent.policy.state_dict().items()
    )
    # The statistics carry on from the agent's (plus the first reset of the 2 envs).
    assert seen.obs_count == pytest.approx(float(stats.obs_rms.count) + 2)
    assert fresh.obs_count < 3
    cmd = yaml.safe_load((tmp_path / "tuned" / "command.txt").read_text())
    assert str(src.run_dir) in str(cmd)
    wide = _config(tmp_path, n_timesteps=64, eval_freq=0, policy_kwargs={"net_arch": [8]})
    with pytest.raises(ConfigError, match="init_from"):
        train(ENV, wide, 1, tmp_path / "wide", progress=False, init_from=src.run_dir)
