"""SAC and TD3 beside PPO, and the Optuna search: configs, replay-buffer resume, agents on the
benchmark, a 2-trial search that resumes (CPU, tiny step counts, seconds each)."""

from __future__ import annotations

import csv
import math
import os
import pickle
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")
pytest.importorskip("optuna")

import optuna

from rover_env.benchmark.ledger import agent_hash
from rover_env.benchmark.run import ScenarioWrapper, run_episode
from rover_env.config import ConfigError
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.envs.registration import ENV_IDS
from rover_env.policies.residual import Residual
from rover_env.policies.specs import make_controller, parse_specs
from rover_env.tasks.scenarios import load_scenario
from rover_env.training import load_algo_config, train
from rover_env.training.callbacks import latest_checkpoint, replay_buffer_path
from rover_env.training.config import parse_algo_config
from rover_env.training.evaluate import agent_spec
from rover_env.training.search import apply_params, search

ENV = "rover_env/ProtoExplorer-v0"
MIX = "rover_env/ProtoExplorerScenarioMix-v0"
REPO = Path(__file__).resolve().parent.parent
OFF: dict[str, Any] = {
    "n_timesteps": 128,
    "n_envs": 2,
    "vec_env": "dummy",
    "learning_starts": 32,
    "batch_size": 16,
    "buffer_size": 1000,
    "train_freq": 4,
    "gradient_steps": -1,
    "policy_kwargs": {"net_arch": [16, 16]},
    "max_episode_steps": 20,
    "eval_freq": 64,
    "n_eval_episodes": 1,
    "checkpoint_freq": 64,
}
PPO_SMALL: dict[str, Any] = {
    "n_timesteps": 256,
    "n_envs": 2,
    "vec_env": "dummy",
    "learning_rate": "lin_3e-4",
    "n_steps": 32,
    "batch_size": 32,
    "n_epochs": 1,
    "policy_kwargs": {"net_arch": [8, 8]},
    "max_episode_steps": 20,
    "eval_freq": 64,
    "n_eval_episodes": 1,
    "checkpoint_freq": 64,
}


def _write(tmp_path: Path, name: str, entry: dict[str, Any]) -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump({ENV: entry}))
    return path


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def residual_agent(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A PPO wheel residual (0.5 of the range on the soft-started open loop x 2.2) trained here
    for 256 steps, its output layer then scaled x 200: a few hundred steps leave the mean near
    0 (SB3 starts ``action_net`` at gain 0.01), and widening and ``spread`` must be seen where
    the mean lies beyond the action bounds too, as a trained agent's does on a stall."""
    from stable_baselines3 import PPO

    tmp = tmp_path_factory.mktemp("residual_agent")
    entry = {
        **PPO_SMALL,
        "n_steps": 64,
        "batch_size": 64,
        "policy_kwargs": {"net_arch": [16, 16]},
        "max_episode_steps": 30,
        "eval_freq": 10_000,
        "checkpoint_freq": 10_000,
        "env_kwargs": {
            "scenarios": {"soft-patch": 1.0},
            "action_residual": 0.5,
            "residual_base": "open-loop@gain=2.2@ramp=2",
            "residual_ramp": 2.0,
        },
    }
    cfg = tmp / "ppo.yaml"
    cfg.write_text(yaml.safe_dump({MIX: entry}))
    run = tmp / "run"
    train(MIX, cfg, 0, run, progress=False)
    agent = tmp / "agent"
    agent.mkdir()
    for name in ("config.yaml", "command.txt", "vecnormalize.pkl"):
        shutil.copy2(run / name, agent / name)
    model = PPO.load(str(run / "model.zip"), device="cpu")
    sd = model.policy.state_dict()
    sd["action_net.weight"] = sd["action_net.weight"] * 200.0
    sd["action_net.bias"] = sd["action_net.bias"] * 200.0
    model.policy.load_state_dict(sd)
    model.save(str(agent / "model.zip"))
    return agent


# --------------------------------------------------------------------------- configuration


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_shipped_off_policy_configs_load_and_round_trip(tmp_path: Path, algo: str) -> None:
    for env_id in (*ENV_IDS[:1], MIX):
        cfg = load_algo_config(algo, algo, env_id)
        assert cfg.algo == algo and cfg.off_policy
        path = tmp_path / f"{algo}.yaml"
        path.write_text(yaml.safe_dump({env_id: cfg.to_dict()}))
        assert load_algo_config(algo, path, env_id) == cfg
    td3 = load_algo_config("td3", "td3", ENV)
    assert td3.algo == "td3" and td3.action_noise is not None
    assert td3.action_noise.type == "normal" and td3.action_noise.sigma == pytest.approx(0.1)


def test_soil_agent_configs() -> None:
    """configs/agents_soil/{algo}.yaml: the three algorithms train on the same ground with the
    same action and reward (a fair comparison), the soil scenarios and turns, acting on the
    wheels through the open-loop base (no slip PI in the policy's loop)."""
    kws = []
    for algo in ("ppo", "sac", "td3"):
        for where in ("agents_soil", REPO / "configs" / "agents_soil"):
            kws.append(load_algo_config(algo, where, MIX).env_kwargs)
    for kw in kws:
        assert kw == kws[0]
        assert {"sand-slope", "soft-patch", "sand-turns", "flat-turns"} <= set(kw["scenarios"])
        assert kw["residual_base"] == "open-loop" and kw["action_residual"] > 0


def test_agent_config_rebuilds_the_shipped_axle_schedule_agent() -> None:
    """configs/agents/axle-schedule.yaml is self-contained (no ``base:``), has one env id
    (so ``train/ppo.py --config FILE --seed 0`` needs nothing else) and resolves to exactly
    the hyperparameters the shipped agent was trained with (its run's resolved config.yaml)."""
    from rover_env.config import read_yaml
    from rover_env.training.cli import only_env_id

    path = REPO / "configs" / "agents" / "axle-schedule.yaml"
    assert "base" not in read_yaml(path)
    assert only_env_id(str(path)) == MIX
    shipped = REPO / "agents" / "axle-schedule" / "config.yaml"
    assert load_algo_config("ppo", path, MIX) == load_algo_config("ppo", shipped, MIX)
    (cmd,) = yaml.safe_load((REPO / "agents" / "axle-schedule" / "command.txt").read_text())
    assert (cmd["seed"], cmd["total_timesteps"]) == (0, 200_000)


@pytest.mark.parametrize(
    ("algo", "over", "match"),
    [
        ("sac", {"policy_delay": 2}, r"unknown key\(s\) policy_delay"),
        ("td3", {"ent_coef": "auto"}, r"unknown key\(s\) ent_coef"),
        ("td3", {"policy_kwargs": {"log_std_init": -2}}, r"policy_kwargs: unknown key"),
        ("sac", {"ent_coef": "autox"}, r"\.ent_coef: expected a number"),
        ("td3", {"action_noise": {"type": "pink"}}, r"action_noise\.type: expected one of"),
        ("sac", {"gradient_steps": 0}, r"\.gradient_steps: must be -1"),
        ("td3", {"batch_size": 2000}, r"\.batch_size: 2000 exceeds buffer_size"),
        ("sac", {"tau": 1.5}, r"\.tau: must be in \(0, 1\]"),
    ],
)
def test_off_policy_config_errors_name_key_and_file(
    tmp_path: Path, algo: str, over: dict[str, Any], match: str
) -> None:
    path = _write(tmp_path, f"{algo}_bad.yaml", {**OFF, **over})
    with pytest.raises(ConfigError, match=match) as err:
        load_algo_config(algo, path, ENV)
    assert str(path) in str(err.value) and ENV in str(err.value)


def test_unknown_algorithm_and_learned_specs() -> None:
    with pytest.raises(ConfigError, match="unknown algorithm 'ddpg'"):
        parse_algo_config("ddpg", {})
    assert parse_specs("open-loop,sac:runs/a,td3:runs/b") == [
        "open-loop",
        "sac:runs/a",
        "td3:runs/b",
    ]
    for bad in ("sac", "td3:", "a2c:runs/x"):
        with pytest.raises(ValueError, match="unknown controller"):
            parse_specs(bad)
    with pytest.raises(ValueError, match="residual_base must be a classical"):
        Residual("sac:runs/a", 0.5)


# --------------------------------------------------------------------------- off-policy runs


def test_sac_checkpoint_keeps_the_replay_buffer_and_resume_continues_it(tmp_path: Path) -> None:
    cfg = _write(tmp_path, "sac.yaml", OFF)
    run = tmp_path / "sac_run"
    res = train(ENV, cfg, 3, run, progress=False, algo="sac")
    assert res.algo == "sac" and res.num_timesteps == 128
    ckpt = run / "checkpoints"
    assert latest_checkpoint(ckpt, "sac") == 128
    assert sorted(p.name for p in ckpt.glob("*replay_buffer*")) == [
        "sac_replay_buffer_128_steps.pkl"
    ]
    with replay_buffer_path(ckpt, 128, "sac").open("rb") as fh:
        before = pickle.load(fh)
    assert before.pos == 64  # 128 env steps over 2 envs
    assert yaml.safe_load((run / "command.txt").read_text())[0]["algo"] == "sac"

    with pytest.raises(ConfigError, match="the run trains sac"):
        train(None, None, None, run, resume=True, algo="td3", progress=False)
    res2 = train(None, None, None, run, resume=True, total_timesteps=192, progress=False)
    assert res2.resumed_from == 128 and res2.num_timesteps == 192 and res2.algo == "sac"
    assert not replay_buffer_path(ckpt, 128, "sac").exists()  # only the newest keeps one
    with replay_buffer_path(ckpt, 192, "sac").open("rb") as fh:
        after = pickle.load(fh)
    assert after.pos == 96
    np.testing.assert_array_equal(after.observations[:64], before.observations[:64])
    np.testing.assert_array_equal(after.actions[:64], before.actions[:64])
    assert np.any(after.observations[64:96] != 0)

    # a checkpoint whose buffer is gone cannot silently restart with an empty buffer
    replay_buffer_path(ckpt, 192, "sac").unlink()
    with pytest.raises(ConfigError, match="no replay buffer"):
        train(None, None, None, run, resume=True, total_timesteps=256, progress=False)


def test_td3_agent_runs_on_the_benchmark(tmp_path: Path) -> None:
    entry = {**OFF, "action_noise": {"type": "normal", "sigma": 0.2}, "n_timesteps": 64}
    cfg = _write(tmp_path, "td3.yaml", entry)
    run = tmp_path / "td3_run"
    train(ENV, cfg, 0, run, progress=False, algo="td3")
    spec = agent_spec(run)
    assert spec == f"td3:{run}"
    assert len(agent_hash(spec)) == 16 and agent_hash(spec) != agent_hash(f"sac:{run}")
    ctrl = make_controller(spec)
    assert ctrl.name == spec and ctrl.action_layout == "wheels"
    episode = load_scenario("flat-turns").episode(2000, 0.5)
    wrapper = ScenarioWrapper(ProtoExplorerEnv(terrain=episode.terrain))
    m = run_episode(wrapper, ctrl, episode)
    assert math.isfinite(m["mean_abs_slip"]) and math.isfinite(m["energy_per_metre"])
    with pytest.raises(ValueError, match=r"holds a td3 agent; use td3:"):
        make_controller(f"sac:{run}")


# --------------------------------------------------------------------------- search


def test_apply_params_nested_keys_arch_and_linear_schedule() -> None:
    base = {"learning_rate": "lin_3e-4", "n_steps": 32, "n_envs": 2, "batch_size": 256}
    out = apply_params(
        base,
        {"learning_rate": 1e-3, "policy_kwargs.net_arch": "32x16", "action_noise.sigma": 0.2},
    )
    assert out["learning_rate"] == "lin_0.001"
    assert out["policy_kwargs"]["net_arch"] == [32, 16]
    assert out["action_noise"] == {"sigma": 0.2}
    assert out["batch_size"] == 64  # capped at n_steps * n_envs
    assert base["learning_rate"] == "lin_3e-4"  # the base entry is not modified


SPACE = {
    "learning_rate": {"low": 1e-4, "high": 1e-3, "log": True},
    "n_epochs": {"choices": [1, 2]},
    "policy_kwargs.net_arch": {"choices": ["8x8", "16x16"]},
}


def test_search_two_trials_then_resumes_to_three(tmp_path: Path) -> None:
    cfg = _write(tmp_path, "ppo.yaml", PPO_SMALL)
    out = tmp_path / "search"
    res = search(
        "ppo", cfg, ENV, out, trials=2, timesteps_per_trial=128, evaluations=2, space=SPACE
    )
    assert res.n_complete == 2 and res.best_number is not None
    rows = _rows(out / "trials.csv")
    assert [r["number"] for r in rows] == ["0", "1"] and all(r["state"] == "COMPLETE" for r in rows)
    values = [float(r["value"]) for r in rows]
    assert res.best_value == max(values)
    # every trial: a run scored on validation evaluations, reported to the pruner
    study = optuna.load_study(study_name=f"ppo|{ENV}", storage=f"sqlite:///{out / 'study.db'}")
    for t in study.trials:
        assert sorted(t.intermediate_values) == [64, 128]
        evals = _rows(out / f"trial_{t.number:03d}" / "run" / "evaluations.csv")
        assert float(evals[-1]["mean_reward"]) == pytest.approx(t.value)
        assert not (out / f"trial_{t.number:03d}" / "run" / "checkpoints").exists()
    best = load_algo_config("ppo", out / "best.yaml", ENV)
    p = study.best_trial.params
    assert best["learning_rate"].linear and best["learning_rate"].start == pytest.approx(
        p["learning_rate"]
    )
    assert best["n_epochs"] == p["n_epochs"]
    assert best.policy_kwargs.net_arch == tuple(
        int(x) for x in p["policy_kwargs.net_arch"].split("x")
    )
    assert best.n_timesteps == 256 and best.eval_freq == 64  # the base file's, not the trial's

    # the command line resumes the stored study: one more trial, the first two untouched
    space = tmp_path / "space.yaml"
    space.write_text(yaml.safe_dump(SPACE))
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
    }
    cmd = [sys.executable, "train/search.py", "--algo", "ppo", "--config", str(cfg)]
    cmd += ["--env-id", ENV, "--trials", "3", "--timesteps-per-trial", "128"]
    cmd += ["--evaluations", "2", "--space", str(space), "--out", str(out)]
    cmd += ["--storage", f"sqlite:///{out / 'study.db'}", "--budget-minutes", "10"]
    proc = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "3 complete" in proc.stdout
    rows3 = _rows(out / "trials.csv")
    assert len(rows3) == 3 and rows3[:2] == rows


def test_search_fine_tunes_a_trained_agent_in_every_trial(tmp_path: Path) -> None:
    """``init_from``: each trial starts from the agent (its run records it); network keys
    cannot be searched then; a stored study refuses to resume from another agent."""
    cfg = _write(tmp_path, "ppo.yaml", PPO_SMALL)
    src = train(ENV, cfg, 0, tmp_path / "src", total_timesteps=64, progress=False)
    out = tmp_path / "search"
    space = {"learning_rate": SPACE["learning_rate"], "n_epochs": SPACE["n_epochs"]}
    kw: dict[str, Any] = {"trials": 1, "timesteps_per_trial": 64, "evaluations": 1}
    res = search("ppo", cfg, ENV, out, space=space, init_from=src.run_dir, **kw)
    assert res.n_complete == 1
    cmd = (out / "trial_000" / "run" / "command.txt").read_text()
    assert str(src.run_dir) in cmd
    with pytest.raises(ConfigError, match="net_arch"):
        search("ppo", cfg, ENV, tmp_path / "s2", space=SPACE, init_from=src.run_dir, **kw)
    assert not (tmp_path / "s2").exists()  # refused before any study folder or storage
    with pytest.raises(ConfigError, match="fine-tunes"):
        search("ppo", cfg, ENV, out, space=space, **{**kw, "trials": 2})


def test_search_space_errors(tmp_path: Path) -> None:
    cfg = _write(tmp_path, "ppo.yaml", PPO_SMALL)
    with pytest.raises(ConfigError, match="need low < high"):
        search(
            "ppo",
            cfg,
            ENV,
            tmp_path / "s",
            space={"ent_coef": {"low": 0.0, "high": 0.1, "log": True}},
        )
    with pytest.raises(ConfigError, match="choices must be a non-empty list"):
        search("ppo", cfg, ENV, tmp_path / "s", space={"n_epochs": {"choices": []}})
    with pytest.raises(ConfigError, match="no entry for env id"):
        search("ppo", cfg, MIX, tmp_path / "s", space=SPACE)
    shutil.rmtree(tmp_path / "s", ignore_errors=True)


def test_sweep_trains_each_algorithm_from_a_folder_of_configs(tmp_path: Path) -> None:
    from rover_env.training.sweep import sweep

    folder = tmp_path / "agents"
    folder.mkdir()
    for algo in ("sac", "td3"):
        (folder / f"{algo}.yaml").write_text(yaml.safe_dump({ENV: {**OFF, "n_timesteps": 64}}))
    rows = sweep(folder, [0], tmp_path / "sweep", algos=["sac", "td3"], progress=False)
    assert [(r["algo"], r["num_timesteps"]) for r in rows] == [("sac", 64), ("td3", 64)]
    for algo in ("sac", "td3"):
        cmd = yaml.safe_load((tmp_path / "sweep" / f"{algo}_s0" / "command.txt").read_text())[0]
        assert cmd["algo"] == algo and cmd["argv"].split()[1] == f"train/{algo}.py"
        assert cmd["config"] == str(folder.resolve() / f"{algo}.yaml")


def test_search_retries_a_trial_a_killed_search_left_running(tmp_path: Path) -> None:
    from rover_env.training.search import _suggest

    cfg = _write(tmp_path, "ppo.yaml", PPO_SMALL)
    out = tmp_path / "search"
    out.mkdir()
    storage = f"sqlite:///{out / 'study.db'}"
    study = optuna.create_study(storage=storage, study_name=f"ppo|{ENV}", direction="maximize")
    orphan = study.ask()  # as a search killed mid-trial leaves it: RUNNING
    params = {k: _suggest(orphan, k, s) for k, s in SPACE.items()}
    res = search("ppo", cfg, ENV, out, trials=1, timesteps_per_trial=64, evaluations=1, space=SPACE)
    trials = optuna.load_study(study_name=f"ppo|{ENV}", storage=storage).trials
    assert [t.state.name for t in trials] == ["FAIL", "COMPLETE"]
    assert trials[1].params == params and trials[1].user_attrs["retry_of"] == 0
    assert res.best_number == 1 and res.n_complete == 1


def test_widen_residual_keeps_the_agents_actions_and_noise(
    tmp_path: Path, residual_agent: Path
) -> None:
    """The widened copy acts as the agent wherever the agent's mean was inside its bounds,
    with the same exploration noise in rad/s; beyond them it reaches further."""
    from stable_baselines3 import PPO

    from rover_env.training.widen import widen_residual

    src = residual_agent
    out = widen_residual(src, 1.0, tmp_path / "wide")
    old = PPO.load(str(src / "model.zip"), device="cpu")
    new = PPO.load(str(out / "model.zip"), device="cpu")
    kw_old = load_algo_config("ppo", src / "config.yaml", MIX).env_kwargs
    kw_new = load_algo_config("ppo", out / "config.yaml", MIX).env_kwargs
    assert kw_old["action_residual"] == 0.5 and kw_new["action_residual"] == 1.0
    assert {**kw_new, "action_residual": 0.5} == kw_old
    obs = np.random.default_rng(0).normal(size=(256, old.observation_space.shape[0]))
    obs = obs.astype(np.float32)
    mean_old = old.policy.get_distribution(old.policy.obs_to_tensor(obs)[0]).distribution.mean
    mean_new = new.policy.get_distribution(new.policy.obs_to_tensor(obs)[0]).distribution.mean
    m_old, m_new = mean_old.detach().numpy(), mean_new.detach().numpy()
    inside = np.abs(m_old) < 1.0
    assert inside.mean() > 0.2 and (~inside).any()
    np.testing.assert_allclose(1.0 * m_new[inside], 0.5 * m_old[inside], rtol=1e-5, atol=1e-6)
    assert np.all(np.abs(m_new[~inside]) >= 0.5 - 1e-6)  # beyond the old clip: further
    std_old = old.policy.log_std.exp().detach().numpy()
    std_new = new.policy.log_std.exp().detach().numpy()
    np.testing.assert_allclose(1.0 * std_new, 0.5 * std_old, rtol=1e-6)
    noisy = widen_residual(src, 1.0, tmp_path / "noisy", noise_factor=4.0)
    m_noisy = PPO.load(str(noisy / "model.zip"), device="cpu")
    mean_noisy = m_noisy.policy.get_distribution(m_noisy.policy.obs_to_tensor(obs)[0])
    np.testing.assert_allclose(mean_noisy.distribution.mean.detach().numpy(), m_new, rtol=1e-6)
    std_noisy = m_noisy.policy.log_std.exp().detach().numpy()
    np.testing.assert_allclose(std_noisy, 4.0 * std_new, rtol=1e-5)
    with pytest.raises(ConfigError, match="noise_factor"):
        widen_residual(src, 1.0, tmp_path / "w0", noise_factor=0.0)
    with pytest.raises(ConfigError, match="already exists"):
        widen_residual(src, 1.0, out)
    with pytest.raises(ConfigError, match="new_scale"):
        widen_residual(src, 3.0, tmp_path / "w3")


def test_spread_is_the_mean_the_deterministic_action_clips(residual_agent: Path) -> None:
    """``spread`` reads the policy's own mean and noise: where the mean is inside [-1, 1] it is
    the deterministic action; beyond, the action is the bound (what a saturated policy does)."""
    ctrl = make_controller(f"ppo:{residual_agent}")
    n_obs = ctrl.model.observation_space.shape[0]
    obs = np.random.default_rng(1).normal(size=(64, n_obs)).astype(np.float32) * 20.0
    n_in = n_out = 0
    for o in obs:
        stats = ctrl.spread(o)
        assert stats is not None
        mean, std = stats
        o_n = np.asarray(ctrl.normalizer.normalize_obs(o), dtype=np.float32)
        act, _ = ctrl.model.predict(o_n, deterministic=True)
        np.testing.assert_allclose(np.clip(mean, -1, 1), act, rtol=1e-5, atol=1e-6)
        assert np.all(std > 0)
        n_in += int(np.sum(np.abs(mean) < 1))
        n_out += int(np.sum(np.abs(mean) > 1))
    assert n_in > 0 and n_out > 0  # both cases were exercised


def test_stall_clock_counts_slow_seconds_resets_and_caps() -> None:
    from rover_env.envs.proto_explorer import OBS_NAMES
    from rover_env.policies.memory import StallClock, stall_clock_from

    clock = StallClock(speed=0.02, cap=1.0)
    obs = np.zeros(len(OBS_NAMES), dtype=np.float32)
    i = OBS_NAMES.index("speed_estimate")
    ts = []
    for v in (0.1, 0.0, 0.01, -0.019, 0.03, 0.0):
        obs[i] = v
        ts.append(clock.update(obs, 0.25))
    assert ts == [0.0, 0.25, 0.5, 0.75, 0.0, 0.25]
    for _ in range(10):
        clock.update(obs, 0.25)
    assert clock.t == 1.0  # capped
    assert stall_clock_from(None) is None and stall_clock_from(False) is None
    assert stall_clock_from({"cap": 5}).cap == 5.0  # type: ignore[union-attr]
    with pytest.raises(ValueError, match=r"stall_clock: unknown key\(s\) \['sped'\]"):
        stall_clock_from({"sped": 0.1})
    with pytest.raises(ValueError, match="speed must be > 0"):
        stall_clock_from({"speed": 0})


def test_an_agent_given_the_stall_clock_acts_as_before_and_the_mix_env_feeds_it(
    tmp_path: Path, residual_agent: Path
) -> None:
    """The copy with the clock as a zero-weight extra input drives the benchmark exactly as the
    agent while the clock runs; the training env appends the same clock the controller
    computes."""
    from rover_env.benchmark.mixture import ScenarioMixEnv
    from rover_env.policies.memory import StallClock
    from rover_env.training.widen import add_stall_clock

    src = residual_agent
    # "slow" below 0.5 m/s, above the rover's pace: the clock runs from the start, so the
    # copy is seen acting as the agent with a nonzero input it must ignore
    out = add_stall_clock(src, tmp_path / "clock", {"speed": 0.5, "cap": 5.0})
    with pytest.raises(ConfigError, match="already set"):
        add_stall_clock(out, tmp_path / "again")
    a, b = make_controller(f"ppo:{src}"), make_controller(f"ppo:{out}")
    assert b.clock is not None and a.clock is None  # type: ignore[attr-defined]
    n_obs = a.model.observation_space.shape[0]  # type: ignore[attr-defined]
    assert b.model.observation_space.shape == (n_obs + 1,)  # type: ignore[attr-defined]
    episode = load_scenario("soft-patch").episode(1052)
    wrapper = ScenarioWrapper(ProtoExplorerEnv(terrain=episode.terrain))
    wrapper.set_episode(episode)
    obs, _ = wrapper.reset()
    a.reset(wrapper.base)
    b.reset(wrapper.base)
    clock_seen = []
    for _ in range(30):
        act_a, act_b = a.action(wrapper.base, obs), b.action(wrapper.base, obs)
        np.testing.assert_allclose(act_b, act_a, rtol=0, atol=1e-6)
        clock_seen.append(b.clock.t)  # type: ignore[attr-defined]
        obs, *_ = wrapper.step(act_a)
    assert max(clock_seen) > 1.0  # the new input was read while it ran, not only at 0

    env = ScenarioMixEnv(scenarios=["soft-patch"], stall_clock={"speed": 0.05, "cap": 3.0})
    assert env.observation_space.shape == (47,)
    o, _ = env.reset(seed=100000)
    mirror = StallClock(0.05, 3.0)
    assert o.shape == (47,) and o[-1] == 0.0
    seen = []
    for _ in range(30):
        o, *_ = env.step(np.zeros(4, dtype=np.float32))
        assert o[-1] == pytest.approx(mirror.update(o[:-1], 0.1))
        seen.append(float(o[-1]))
    assert max(seen) > 0  # the start from rest is slow


def test_the_agent_command_is_seeded_two_runs_give_the_same_weights(tmp_path: Path) -> None:
    """``train/ppo.py --config configs/agents/soil-families-ppo.yaml --seed S`` rebuilds an
    agent: two runs of one update with the same seed end with identical weights and
    observation statistics (issue 46: agents anyone can rebuild; the shipped run rebuilt to its
    51,200-step checkpoint was bit-identical)."""
    import torch
    from stable_baselines3 import PPO

    cfg = REPO / "configs" / "agents" / "soil-families-ppo.yaml"
    runs = {}
    for name, seed in (("a", 5), ("b", 5)):
        out = tmp_path / name
        train("rover_env/ProtoExplorerFamilies-v0", cfg, seed, out, total_timesteps=2048)
        model = PPO.load(out / "model.zip", device="cpu")
        weights = torch.cat([p.detach().flatten() for p in model.policy.parameters()])
        with open(out / "vecnormalize.pkl", "rb") as f:
            runs[name] = (weights, pickle.load(f).obs_rms.mean)
    assert torch.equal(runs["a"][0], runs["b"][0])
    assert np.array_equal(runs["a"][1], runs["b"][1])
    assert np.abs(runs["a"][1]).sum() > 0  # the statistics saw the 2048 steps of the run
