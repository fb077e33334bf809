"""The scenario-mix training env and the residual action of its agents."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import rover_env
from rover_env.benchmark.mixture import ScenarioMixEnv
from rover_env.config import RoverConfig
from rover_env.control.open_loop import OpenLoop
from rover_env.envs.proto_explorer import OBS_NAMES
from rover_env.policies.residual import residual_action
from rover_env.seeds import SPLITS

I_CMD = OBS_NAMES.index("command_speed")


def _obs(v: float, w: float) -> np.ndarray:
    o = np.zeros(len(OBS_NAMES), dtype=np.float32)
    o[I_CMD : I_CMD + 2] = (v, w)
    return o


@pytest.mark.parametrize(("v", "w"), [(0.15, 0.0), (0.1, 0.2), (-0.12, -0.3)])
def test_zero_residual_is_the_open_loop_controller(v: float, w: float) -> None:
    cfg = RoverConfig()
    ol = OpenLoop(cfg)
    expected = np.clip(ol.feedforward(v, w), -4, 4) / cfg.motor.max_wheel_speed
    got = residual_action(np.zeros(4), _obs(v, w), cfg, 0.5)
    np.testing.assert_allclose(got, expected, rtol=1e-6)
    # A full positive residual adds half the maximum wheel speed, clipped at the limit.
    up = residual_action(np.ones(4), _obs(v, w), cfg, 0.5)
    np.testing.assert_allclose(up, np.clip(expected + 0.5, -1, 1), rtol=1e-6)


def test_residual_rejects_bad_actions() -> None:
    with pytest.raises(ValueError, match="4 entries"):
        residual_action(np.zeros(2), _obs(0.1, 0), RoverConfig(), 0.5)
    with pytest.raises(ValueError, match="non-finite"):
        residual_action([0, np.nan, 0, 0], _obs(0.1, 0), RoverConfig(), 0.5)


def test_mix_draws_training_seeds_reproducibly() -> None:
    gym.register_envs(rover_env)
    env = gym.make(
        "rover_env/ProtoExplorerScenarioMix-v0",
        scenarios=["split-mu", "ice-patch"],
        action_residual=0.5,
    )
    mix = env.unwrapped
    assert isinstance(mix, ScenarioMixEnv)
    runs = []
    for _ in range(2):
        obs, info = env.reset(seed=7)
        ep = mix._active.episode
        assert ep is not None and ep.seed in SPLITS["training"]
        assert info["scenario"] in ("split-mu", "ice-patch")
        traj = [obs]
        for _ in range(5):
            obs, *_ = env.step(np.zeros(4, dtype=np.float32))
            traj.append(obs)
        runs.append((info["scenario"], ep.seed, np.array(traj)))
    assert runs[0][:2] == runs[1][:2]
    np.testing.assert_array_equal(runs[0][2], runs[1][2])
    env.close()
    with pytest.raises(ValueError, match="terrain comes from each scenario"):
        ScenarioMixEnv(terrain="flat")


def _drive(ctrl: Any, step: Any, scenario: str, steps: int = 30) -> tuple[np.ndarray, Any]:
    """(env actions, env) of ``step(env, obs)`` over a 3 s tuning episode, ``ctrl`` reset first."""
    from rover_env.benchmark.run import ScenarioWrapper
    from rover_env.benchmark.scenarios import load_scenario
    from rover_env.envs.proto_explorer import ProtoExplorerEnv

    episode = load_scenario(scenario).episode(SPLITS["tuning"].start, duration=3.0)
    w = ScenarioWrapper(ProtoExplorerEnv(terrain=episode.terrain))
    w.set_episode(episode)
    obs, _ = w.reset()
    ctrl.reset(w.base)
    acts = []
    for _ in range(steps):
        a = step(w.base, obs)
        acts.append(a)
        obs, *_ = w.step(a)
    return np.array(acts), w.base


def test_zero_residual_on_slip_pi_drives_exactly_like_slip_pi() -> None:
    from rover_env.policies.residual import Residual
    from rover_env.policies.specs import make_controller

    pi, res = make_controller("slip-pi"), Residual("slip-pi", 0.5)
    plain, _ = _drive(pi, pi.action, "stuck-wheel")
    zero, _ = _drive(res, lambda env, obs: res(np.zeros(4), env, obs), "stuck-wheel")
    np.testing.assert_allclose(zero, plain, atol=1e-7)
    assert np.ptp(plain) > 0.01  # the PI acted (the wheel meets the box)
    with pytest.raises(ValueError, match="classical controller"):
        Residual("ppo:x", 0.5)


def test_residual_ramp_grows_the_policys_authority_from_zero() -> None:
    """With ``residual_ramp`` T a full residual adds nothing at t = 0, its share t / T of the
    scale before T and the whole scale after: the soft-start base cannot be undone early."""
    from rover_env.policies.residual import Residual

    base = Residual("open-loop@gain=2.2@ramp=2", 0.5)
    ramped = Residual("open-loop@gain=2.2@ramp=2", 0.5, ramp=2.0)
    plain, env = _drive(base, lambda env, obs: base(np.zeros(4), env, obs), "flat-turns")
    full, _ = _drive(ramped, lambda env, obs: ramped(-np.ones(4), env, obs), "flat-turns")
    t = np.arange(len(plain)) * env.control_dt  # the estimator's time at each action
    share = np.minimum(t / 2.0, 1.0)[:, None]
    np.testing.assert_allclose(full, np.clip(plain - 0.5 * share, -1, 1), atol=1e-6)
    assert full[0].tolist() == plain[0].tolist()  # no authority at the start
    assert np.all(full[-1] < plain[-1] - 0.49)  # the whole residual after 2 s (3 s drive)
    assert ramped.authority(1.0) == pytest.approx(0.25) and ramped.authority(5.0) == 0.5
    for bad in (-1.0, float("nan"), 61.0):
        with pytest.raises(ValueError, match="residual_ramp"):
            Residual("open-loop", 0.5, ramp=bad)


def test_zero_schedule_is_slip_pi_and_the_schedule_changes_its_gains() -> None:
    from rover_env.policies.residual import Schedule
    from rover_env.policies.specs import make_controller

    pi = make_controller("slip-pi")
    plain, _ = _drive(pi, pi.action, "ice-patch")
    zero_s, low_s = Schedule("slip-pi", [2.0, 0.5]), Schedule("slip-pi", [2.0, 0.5])
    zero, _ = _drive(zero_s, lambda env, obs: zero_s(np.zeros(2), env, obs), "ice-patch")
    low_db = np.array([-1.0, 1.0])
    low, env_low = _drive(low_s, lambda env, obs: low_s(low_db, env, obs), "ice-patch")
    pi_low, cfg0 = low_s._pi, low_s._cfg0
    assert pi_low is not None and cfg0 is not None
    assert pi_low.cfg.deadband == cfg0.deadband / 4  # two octaves down
    assert pi_low.cfg.ki == cfg0.ki * 2**0.5
    low_s.reset(env_low)
    assert pi_low.cfg is cfg0  # a reset restores the configured PI
    np.testing.assert_array_equal(zero, plain)
    assert np.abs(low - plain).max() > 1e-4  # a scheduled PI acts differently
    with pytest.raises(ValueError, match="slip-pi base"):
        Schedule("open-loop", [1.0, 1.0])
    with pytest.raises(ValueError, match="deadband_octaves"):
        Schedule("slip-pi", [1.0])
    env = ScenarioMixEnv(
        scenarios=["ice-patch"], action_schedule=[2.0, 0.5], residual_base="slip-pi"
    )
    assert env.action_space.shape == (2,)
    env.reset(seed=0)
    _, r, *_ = env.step(np.zeros(2, dtype=np.float32))
    assert np.isfinite(r)
    env.close()


def test_schedule_knobs_map_each_action_to_its_setting() -> None:
    from rover_env.policies.residual import Schedule, schedule_knobs

    assert schedule_knobs([2.0, 0.5]) == {"deadband": 2.0, "gain": 0.5}  # the first agents' form
    s = Schedule("slip-pi", {"axle_fight": 2.0, "retry_interval": 1.0, "stuck_retry": 1.0})
    env = ScenarioMixEnv(scenarios=["stuck-wheel"])
    s.reset(env._active.base)
    c0 = s._cfg0
    assert c0 is not None and s.n_actions == 3
    assert s.gains([0.0, 0.0, 0.0]) == c0  # a zero action is the configured PI
    c = s.gains([-1.0, 0.5, 1.0])
    assert c.axle_fight_scale == c0.axle_fight_scale / 4
    assert c.retry_interval == pytest.approx(c0.retry_interval * 2**0.5)
    assert c.stuck_retry_scale == c0.stuck_retry_scale * 2
    assert (c.deadband, c.kp, c.ki) == (c0.deadband, c0.kp, c0.ki)  # the other settings stay
    assert s.gains([-5.0, 9.0, 0.0]) == s.gains([-1.0, 1.0, 0.0])  # clipped to [-1, 1]
    with pytest.raises(ValueError, match=r"3 finite entries \(axle_fight, retry_interval, stuck"):
        s.gains([0.0])
    with pytest.raises(ValueError, match="knobs \\['speed'\\] unknown"):
        schedule_knobs({"speed": 1.0})
    with pytest.raises(ValueError, match=r"action_schedule\.gain must be octaves"):
        schedule_knobs({"gain": 4.0})
    mix = ScenarioMixEnv(
        scenarios=["ice-patch"],
        action_schedule={"axle_fight": 2.0, "retry_interval": 1.0, "gain": 0.5},
        residual_base="slip-pi",
    )
    assert mix.action_space.shape == (3,)
    env.close()
    mix.close()


def _is_residual(ctrl: Any) -> bool:
    from rover_env.policies.residual import Residual

    return isinstance(ctrl.residual, Residual) and ctrl.residual.scale == 0.5


def _is_wheel_residual(ctrl: Any) -> bool:
    from rover_env.policies.residual import Residual

    r = ctrl.residual
    return isinstance(r, Residual) and r.scale == 0.5 and r.base.name == "open-loop"


def _is_schedule(ctrl: Any) -> bool:
    from rover_env.policies.residual import Schedule

    return isinstance(ctrl.residual, Schedule) and ctrl.residual.knobs == {
        "deadband": 2.0,
        "gain": 0.5,
    }


def _is_axle_schedule(ctrl: Any) -> bool:
    from rover_env.policies.residual import Schedule

    return isinstance(ctrl.residual, Schedule) and ctrl.residual.knobs == {"stuck_retry": 1.0}


def _untrained_agent(folder: Any, env_kwargs: dict[str, Any]) -> Any:
    """An agent folder as a run leaves it (model, observation statistics, config.yaml) with an
    untrained PPO policy on the mix env with ``env_kwargs``: SB3 starts the action layer at
    gain 0.01, so it drives as its zero action (the base) does, which is enough to see the
    action mapping read from the config."""
    import yaml
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    venv = VecNormalize(DummyVecEnv([lambda: ScenarioMixEnv(**env_kwargs)]))
    PPO("MlpPolicy", venv, n_steps=64, batch_size=64, seed=0).save(str(folder / "model.zip"))
    venv.save(str(folder / "vecnormalize.pkl"))
    venv.close()
    mix = "rover_env/ProtoExplorerScenarioMix-v0"
    (folder / "config.yaml").write_text(yaml.safe_dump({mix: {"env_kwargs": env_kwargs}}))
    return folder


@pytest.mark.parametrize(
    ("env_kwargs", "scenario", "mapping"),
    [
        # a residual on the slip PI
        ({"action_residual": 0.5, "residual_base": "slip-pi"}, "split-mu", _is_residual),
        # a gain schedule of the slip PI
        ({"action_schedule": [2.0, 0.5], "residual_base": "slip-pi"}, "ice-patch", _is_schedule),
        # the wheels, no slip PI
        ({"action_residual": 0.5, "residual_base": "open-loop"}, "flat-turns", _is_wheel_residual),
    ],
)
def test_agent_action_mapping_is_read_from_its_config(
    tmp_path: Any, env_kwargs: dict[str, Any], scenario: str, mapping: Any
) -> None:
    """An agent's action mapping (residual on a base, or a schedule of the PI's knobs) comes
    from its config.yaml, and the ``ppo:`` controller drives a short benchmark episode."""
    pytest.importorskip("stable_baselines3")
    from rover_env.benchmark.run import Job, run_jobs
    from rover_env.policies.ppo import PPOController

    agent = _untrained_agent(tmp_path, {"scenarios": [scenario], **env_kwargs})
    ctrl = PPOController(agent)
    assert mapping(ctrl)
    assert ctrl.action_layout == "wheels" and ctrl.normalizer is not None
    (row,) = run_jobs([Job(f"ppo:{agent}", scenario, SPLITS["validation"].start, duration=2.0)])
    assert np.isfinite(row["mean_abs_slip"]) and row["distance_made_good"] > 0.1


@pytest.mark.parametrize(
    ("name", "scenario", "mapping"),
    [
        ("axle-schedule", "stuck-wheel", _is_axle_schedule),  # its stuck-wheel retries
    ],
)
def test_shipped_agent_loads_and_drives(name: str, scenario: str, mapping: Any) -> None:
    """A shipped agent, its action mapping read from its config, drives a short episode."""
    pytest.importorskip("stable_baselines3")
    from pathlib import Path

    from rover_env.benchmark.run import Job, run_jobs
    from rover_env.policies.ppo import PPOController

    agent = Path(__file__).resolve().parent.parent / "agents" / name
    if not agent.is_dir():
        pytest.skip("no shipped agent in this checkout")
    ctrl = PPOController(agent)
    assert mapping(ctrl)
    assert ctrl.action_layout == "wheels" and ctrl.normalizer is not None
    (row,) = run_jobs([Job(f"ppo:{agent}", scenario, SPLITS["validation"].start, duration=2.0)])
    assert np.isfinite(row["mean_abs_slip"]) and row["distance_made_good"] > 0.1
