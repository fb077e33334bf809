"""The Gymnasium environment: API conformance, determinism, actions, slip term, rendering."""

from __future__ import annotations

import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import rover_env
from rover_env.config import FrictionPatch, TerrainConfig
from rover_env.envs.proto_explorer import OBS_NAMES, ProtoExplorerEnv
from rover_env.tasks import Task
from rover_env.tasks.reward import RewardWeights

gym.register_envs(rover_env)
ID = "rover_env/ProtoExplorer-v0"


def test_gymnasium_check_env() -> None:
    env = gym.make(ID)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_sb3_check_env() -> None:
    sb3_env_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(ID)
    sb3_env_checker.check_env(env, warn=True)
    env.close()


def test_registration_from_a_fresh_interpreter() -> None:
    code = (
        "import gymnasium as gym\n"
        "env = gym.make('rover_env:rover_env/ProtoExplorer-v0')\n"
        "print(env.spec.max_episode_steps, env.observation_space.shape)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["300", f"({len(OBS_NAMES)},)"]


def _rollout(seed: int, actions: np.ndarray) -> list:
    env = gym.make(ID)
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for a in actions:
        out.append(env.step(a))
    env.close()
    return out


def _same(a, b) -> None:
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            _same(a[k], b[k])
    elif isinstance(a, tuple | list):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _same(x, y)
    else:
        np.testing.assert_array_equal(a, b)


def test_same_seed_and_actions_are_bit_identical() -> None:
    actions = np.random.default_rng(0).uniform(-1, 1, (12, 4)).astype(np.float32)
    _same(_rollout(3, actions), _rollout(3, actions))
    first_obs_other_seed = _rollout(4, actions[:1])[0][0]
    assert not np.array_equal(first_obs_other_seed, _rollout(3, actions[:1])[0][0])


def test_non_finite_action_names_the_entry() -> None:
    env = gym.make(ID)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="2L=nan"):
        env.step(np.array([0.1, 0.1, np.nan, 0.1], dtype=np.float32))
    with pytest.raises(ValueError, match="right=inf"):
        gym.make(ID, action_layout="sides").unwrapped.step(np.array([0.0, np.inf]))


def test_out_of_range_actions_are_clipped() -> None:
    env = ProtoExplorerEnv()
    env.reset(seed=0)
    env.step(np.array([5.0, 5.0, -5.0, -5.0]))
    np.testing.assert_allclose(env.sim.speed_targets, [4.0, 4.0, -4.0, -4.0])


def test_higher_targets_turn_the_wheels_faster() -> None:
    rates = []
    for a in (0.2, 0.8):
        env = ProtoExplorerEnv(sensor_noise="none")
        env.reset(seed=0)
        for _ in range(10):
            obs, *_ = env.step(np.full(4, a, dtype=np.float32))
        rates.append(obs[:4])
    assert np.all(rates[1] > rates[0] + 1.0), rates


def test_slip_term_rises_on_a_low_friction_patch() -> None:
    ice = FrictionPatch(name="ice", center=(10.0, 0.25), size=(22.0, 0.2), mu_x=0.05, mu_y=0.06)
    slip = []
    for patches in ((), (ice,)):
        env = ProtoExplorerEnv(terrain=TerrainConfig(patches=patches), sensor_noise="none")
        env.reset(seed=0, options={"yaw": 0.0})
        terms = []
        for _ in range(30):
            _, _, _, _, info = env.step(np.array([0.9, 0.6, 0.9, 0.6], dtype=np.float32))
            terms.append(info["reward_slip"])
        assert (info["wheel_mu"][0, 0] == 0.05) == bool(patches)  # 1L is on the ice
        slip.append(np.mean(terms))
    assert slip[1] < slip[0] - 0.02, slip


def test_log_slip_penalty_is_linear_below_its_scale_and_logarithmic_above() -> None:
    w = RewardWeights(slip=2.0, slip_scale=0.01)
    assert w.slip_penalty(1e-5) == pytest.approx(1e-5, rel=1e-3)
    assert w.slip_penalty(1.0) == pytest.approx(0.01 * np.log(101.0))
    assert RewardWeights().slip_penalty(0.7) == 0.7  # default: linear
    with pytest.raises(ValueError, match="slip_scale"):
        RewardWeights(slip_scale=-1.0)
    env = ProtoExplorerEnv(reward_weights={"slip": 2.0, "slip_scale": 0.01}, sensor_noise="none")
    env.reset(seed=0)
    for _ in range(5):
        _, _, _, _, info = env.step(np.array([1.0, -1.0, 1.0, -1.0], dtype=np.float32))
    m = info["slip_true_mean_abs"]
    assert m > 0.01  # a spin on the spot: beyond the scale, where the two forms differ
    assert info["reward_slip"] == pytest.approx(-2.0 * 0.01 * np.log1p(m / 0.01))


def test_info_has_every_reward_term_and_privileged_truth_only_there() -> None:
    env = ProtoExplorerEnv()
    obs, _ = env.reset(seed=0)
    _, reward, _, _, info = env.step(env.action_space.sample())
    terms = [k for k in info if k.startswith("reward_")]
    assert sorted(terms) == ["reward_energy", "reward_slip", "reward_tracking"]
    assert reward == pytest.approx(sum(info[k] for k in terms))
    for key in ("slip_true", "slip_estimate", "tracking_error_speed", "tracking_error_yaw_rate"):
        assert key in info
    assert obs.shape == (len(OBS_NAMES),)
    assert not any("true" in n or "F_z" in n or "mu" in n for n in OBS_NAMES)


def test_mobility_reward_pays_for_the_path_along_the_command_and_charges_sinkage() -> None:
    """The mobility terms: progress is the step's path speed, signed by the command's
    direction; sinkage is the six wheels' mean in mm; the reward is the sum of the terms."""
    w = {"tracking": 0.0, "yaw_tracking": 1.0, "progress": 4.0, "sinkage": 0.02}
    env = ProtoExplorerEnv(terrain="sand", reward_weights=w, sensor_noise="none")
    env.set_task(_Fixed(0.15))
    for sign in (1.0, -1.0):
        env.reset(seed=0, options={"yaw": 0.0})
        for _ in range(15):
            _, reward, _, _, info = env.step(np.full(4, 0.6, dtype=np.float32))
        terms = sorted(k for k in info if k.startswith("reward_"))
        assert terms == [
            "reward_energy",
            "reward_progress",
            "reward_sinkage",
            "reward_slip",
            "reward_tracking",
        ]
        assert reward == pytest.approx(sum(info[k] for k in terms))
        assert info["wheel_sinkage"].mean() > 1e-3  # on sand the wheels sit in the soil
        assert info["reward_sinkage"] == pytest.approx(-0.02 * 1000 * info["wheel_sinkage"].mean())
        v = sign * info["distance"] / 0.1
        assert info["reward_progress"] == pytest.approx(4.0 * v)
        assert sign * info["reward_progress"] > 0.1  # forward: paid; against the command: charged
        env.set_task(_Fixed(-0.15))


class _Fixed(Task):
    """A constant command (speed m/s, no yaw rate), never renewed."""

    def __init__(self, v: float) -> None:
        self.v = v

    def command(self, rng: np.random.Generator, t: float) -> tuple[float, float, float]:
        return self.v, 0.0, float("inf")


def test_stall_energy_charges_the_power_not_turned_into_progress() -> None:
    """A rover held still pays its whole power; one at the commanded pace pays none; a
    command without speed is never charged."""
    w = {"tracking": 0.0, "progress": 4.0, "stall_energy": 0.05}
    env = ProtoExplorerEnv(terrain="sand", reward_weights=w, sensor_noise="none")
    charged = []
    for v, action in ((0.15, 0.6), (0.15, 0.0), (0.0, 0.6)):
        env.set_task(_Fixed(v))
        env.reset(seed=0, options={"yaw": 0.0})
        for _ in range(15):
            _, reward, _, _, info = env.step(np.full(4, action, dtype=np.float32))
        assert reward == pytest.approx(sum(info[k] for k in info if k.startswith("reward_")))
        p = info["distance"] / 0.1
        idle = min(max(1.0 - p / v, 0.0), 1.0) if v else 0.0
        power = info["energy"] / 0.1
        assert info["reward_stall_energy"] == pytest.approx(-0.05 * idle * power)
        charged.append((idle, info["reward_stall_energy"]))
    assert charged[0][0] < 0.9  # driving: most of the power moves the rover
    assert charged[2][1] == 0.0  # no commanded speed: nothing to stall against


def test_flip_terminates() -> None:
    env = ProtoExplorerEnv()
    env.reset(seed=0)
    env.sim.data.qpos[3:7] = [0.0, 1.0, 0.0, 0.0]
    _, _, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
    assert terminated and not truncated and info["flipped"]


def test_rough_variant_randomises_terrain_per_episode() -> None:
    env = gym.make("rover_env/ProtoExplorerRough-v0")
    env.reset(seed=1)
    t1 = env.unwrapped.sim.terrain_cfg
    env.reset()
    t2 = env.unwrapped.sim.terrain_cfg
    assert t1 != t2
    env.reset(seed=1)
    assert env.unwrapped.sim.terrain_cfg == t1
    for _ in range(5):
        env.step(env.action_space.sample())
    env.close()


def test_async_vector_env_runs() -> None:
    envs = gym.make_vec(ID, num_envs=2, vectorization_mode="async")
    obs, _ = envs.reset(seed=0)
    for _ in range(3):
        obs, _rew, _term, _trunc, _info = envs.step(envs.action_space.sample())
    assert obs.shape == (2, len(OBS_NAMES)) and np.all(np.isfinite(obs))
    envs.close()


def _has_gl() -> str | None:
    if os.environ.get("MUJOCO_GL") not in (None, "egl"):
        return None
    os.environ.setdefault("MUJOCO_GL", "egl")
    try:
        import mujoco

        r = mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 32, 32)
        r.close()
    except Exception as exc:  # any backend failure means: no OpenGL here
        return f"no OpenGL backend for MuJoCo rendering ({type(exc).__name__}: {exc})"
    return None


def test_rgb_array_render() -> None:
    reason = _has_gl()
    if reason:
        pytest.skip(reason)
    env = gym.make(ID, render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.std() > 1.0
    assert env.metadata["render_fps"] == 10
    env.close()


def test_record_command_writes_a_gif(tmp_path) -> None:
    reason = _has_gl()
    if reason:
        pytest.skip(reason)
    import imageio.v2 as imageio

    from rover_env.cli import main

    out = tmp_path / "ep.gif"
    assert main(["record", "--seconds", "0.5", "--out", str(out)]) == 0
    frames = imageio.mimread(out)
    assert len(frames) == 6  # the reset frame + 5 control steps at 10 Hz
    assert np.std(frames[-1]) > 1.0
    with pytest.raises(ValueError, match=r"\.gif or \.mp4"):
        main(["record", "--out", str(tmp_path / "ep.avi")])
