"""The batched vector env (issue 5) against single envs, and the SB3 same-step adapter."""

from __future__ import annotations

import dataclasses
import os
import shutil
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from _compare import same

import rover_env
from rover_env.config import TerrainConfig, load_rover, load_terrain
from rover_env.envs.proto_explorer import OBS_NAMES
from rover_env.envs.vector import ProtoExplorerVectorEnv
from rover_env.estimation.batch import BatchSlipEstimator
from rover_env.estimation.estimator import SlipEstimator
from rover_env.sim.readers import RoverIndex
from rover_env.sim.simulator import RoverSim

pytestmark = pytest.mark.skipif(
    not any(shutil.which(c) for c in (os.environ.get("CC") or "gcc", "cc")),
    reason="the vector env needs the compiled tire plugin and no C compiler (gcc) is installed",
)

gym.register_envs(rover_env)
ID, ROUGH = "rover_env/ProtoExplorer-v0", "rover_env/ProtoExplorerRough-v0"
TINY = TerrainConfig(size=(1.6, 1.6))  # the rover leaves this arena within a few steps
# The rough variant's randomiser on a smaller, coarser arena: the same code, cheaper resets.
SMALL_ROUGH = dataclasses.replace(load_terrain("rough"), size=(8.0, 8.0), resolution=0.1)


def _pair(env_id: str, n: int, **kwargs: Any) -> tuple[gym.vector.VectorEnv, gym.vector.VectorEnv]:
    batched = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    sync = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync", backend="plugin", **kwargs)
    return batched, sync


@pytest.mark.parametrize(
    ("env_id", "n", "steps", "kwargs"),
    [
        (ID, 3, 10, {"max_episode_steps": 4}),
        (ID, 3, 12, {"terrain": TINY, "action_layout": "sides", "slip_source": "estimate"}),
        (ROUGH, 2, 5, {"max_episode_steps": 3, "terrain": SMALL_ROUGH}),
    ],
    ids=["flat-timelimit", "terminations-sides", "rough"],
)
def test_vector_env_equals_single_envs(env_id: str, n: int, steps: int, kwargs: Any) -> None:
    batched, sync = _pair(env_id, n, **kwargs)
    assert isinstance(batched.unwrapped, ProtoExplorerVectorEnv)
    assert batched.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP
    assert batched.observation_space == sync.observation_space
    assert batched.action_space == sync.action_space
    same(batched.reset(seed=7), sync.reset(seed=7), "reset")
    rng = np.random.default_rng(0)
    ends = 0
    for k in range(steps):
        a = rng.uniform(-1, 1, batched.action_space.shape).astype(np.float32)
        out = batched.step(a)
        same(out, sync.step(a), f"step {k}")
        ends += int(np.sum(out[2] | out[3]))
    assert ends >= n, "no episode ended: autoreset untested"
    # Partial resets, with a seed for one rover and options for all of them.
    mask = np.zeros(n, dtype=bool)
    mask[0] = True
    seeds = [11] + [None] * (n - 1)
    opts = {"reset_mask": mask, "yaw": 0.3}
    same(batched.reset(seed=seeds, options=dict(opts)), sync.reset(seed=seeds, options=dict(opts)))
    a = rng.uniform(-1, 1, batched.action_space.shape).astype(np.float32)
    same(batched.step(a), sync.step(a), "after partial reset")
    batched.close()
    sync.close()


def test_vector_env_refuses_the_numpy_backend() -> None:
    with pytest.raises(ValueError, match="plugin"):
        ProtoExplorerVectorEnv(2, backend="numpy")  # type: ignore[arg-type]


def test_readers_repeat_the_simulator() -> None:
    """RoverIndex's numpy reads equal the simulator's own on one rover and on stacked rows."""
    sim = RoverSim(terrain="rough", backend="plugin")
    ix = RoverIndex(sim)
    m, d = sim.model, sim.data
    rng = np.random.default_rng(3)
    rows = []
    for _ in range(20):
        sim.set_speed_targets(rng.uniform(-4, 4, 4))
        sim.step(37)
        vel = np.zeros(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, int(ix.seg_body[1]), vel, 1)
        seg = sim.segment_truth()
        assert (vel[3], vel[2]) == (seg.forward_speed[1], seg.yaw_rate[1])
        got = ix.segment_velocity(d.cvel, d.xipos, d.ximat, d.subtree_com)
        assert got == (vel[3], vel[2])
        np.testing.assert_array_equal(ix.driven_slip(d.plugin_state), sim.wheel_truth().S[:4])
        s = sim.sensors()
        phi, theta = ix.phi_theta(d.sensordata)
        np.testing.assert_array_equal(phi, s.phi)
        np.testing.assert_array_equal(theta, s.theta)
        np.testing.assert_array_equal(ix.gyro_rates(d.sensordata), s.imu_gyro)
        assert ix.flipped(d.xmat) == sim.flipped()
        rows.append((d.cvel.copy(), d.xipos.copy(), d.ximat.copy(), d.subtree_com.copy(), vel[2:4]))
    stacked = [np.stack([r[k] for r in rows]) for k in range(5)]
    speed, yaw = ix.segment_velocity(*stacked[:4])
    np.testing.assert_array_equal(speed, stacked[4][:, 1])
    np.testing.assert_array_equal(yaw, stacked[4][:, 0])


def test_batch_estimator_equals_streaming_estimator() -> None:
    """Rovers at different points of their windows (resets, gaps) estimate as SlipEstimator."""
    cfg = load_rover("proto_explorer")
    n = 4
    batch = BatchSlipEstimator(cfg, n)
    singles = [SlipEstimator(cfg) for _ in range(n)]
    rng = np.random.default_rng(1)
    t = np.zeros(n)
    angles = np.zeros((n, 11))
    for k in range(90):
        ids = [i for i in range(n) if rng.random() < 0.8]
        for i in ids:
            if rng.random() < 0.03:
                singles[i].reset()
                batch.reset([i])
                t[i] = 0.0
        t[ids] += rng.choice([0.02, 0.02, 0.05, 0.7], len(ids))
        angles[ids] += rng.normal([0.08] * 6 + [0.0] * 5, 0.02, (len(ids), 11))
        batch.push(ids, t[ids], angles[ids, :6], angles[ids, 6:])
        want = [singles[i].update(t[i], angles[i, :6], angles[i, 6:]) for i in ids]
        if ids and k % 3 == 0:
            for a, b in zip(batch.estimate(ids), want, strict=True):
                same(vars(a), vars(b), f"sample {k}")


# --------------------------------------------------------------------------- SB3 adapter
class _Columns(gym.vector.VectorWrapper):
    """The vector env with Gymnasium's API only (no step_rows/reset_rows): the adapter's
    general path, through info columns."""

    def get_attr(self, name: str) -> tuple[Any, ...]:
        return self.env.get_attr(name)  # type: ignore[no-any-return]

    def set_attr(self, name: str, values: Any) -> None:
        self.env.set_attr(name, values)


@pytest.mark.parametrize("path", ["rows", "columns"])
def test_sb3_adapter_resets_in_the_same_step_like_dummy_vec_env(path: str) -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from rover_env.training.envs import SeedSchedule
    from rover_env.training.vec_adapter import GymnasiumVecEnv

    n, limit = 3, 4
    seeds = [[100 + i, 200 + i] for i in range(n)]
    kwargs: dict[str, Any] = {"terrain": TINY, "max_episode_steps": limit}
    venv = gym.make_vec(ID, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    if path == "columns":
        venv = _Columns(venv)
    adapted = GymnasiumVecEnv(venv, seeds)
    assert hasattr(adapted.venv, "step_rows") == (path == "rows")
    reference = DummyVecEnv(
        [
            lambda i=i: SeedSchedule(gym.make(ID, backend="plugin", **kwargs), seeds[i])
            for i in range(n)
        ]
    )
    # The single envs again, stepped by hand: the truth about each episode's last step.
    singles = [gym.make(ID, backend="plugin", **kwargs) for _ in range(n)]
    episode = [0] * n
    last = [s.reset(seed=seeds[i][0])[0] for i, s in enumerate(singles)]

    obs = adapted.reset()
    np.testing.assert_array_equal(obs, reference.reset())
    np.testing.assert_array_equal(obs, np.stack(last))
    rng = np.random.default_rng(4)
    ends = {"terminated": 0, "truncated": 0}
    for k in range(12):
        a = rng.uniform(-1, 1, (n, 4)).astype(np.float32)
        obs, rew, done, infos = adapted.step(a)
        obs_r, rew_r, done_r, infos_r = reference.step(a)
        np.testing.assert_array_equal(obs, obs_r, err_msg=f"step {k}")
        np.testing.assert_array_equal(rew, rew_r)
        np.testing.assert_array_equal(done, done_r)
        for i in range(n):
            o, r, term, trunc, _ = singles[i].step(a[i])
            assert np.float32(r) == rew[i]
            assert done[i] == (term or trunc)
            assert set(infos[i]) == set(infos_r[i]) - {"episode"}
            for key, value in infos_r[i].items():
                if key != "episode":
                    same(np.asarray(infos[i][key]), np.asarray(value), key)
            if done[i]:
                # The step that ends an episode returns the next one's first observation ...
                np.testing.assert_array_equal(infos[i]["terminal_observation"], o)
                assert infos[i]["TimeLimit.truncated"] == (trunc and not term)
                ends["truncated" if trunc and not term else "terminated"] += 1
                episode[i] += 1
                nxt = seeds[i][episode[i]] if episode[i] < len(seeds[i]) else None
                o, reset_info = singles[i].reset(seed=nxt)
                np.testing.assert_array_equal(obs[i], o)
                assert set(adapted.reset_infos[i]) == set(reset_info)
            else:
                assert "terminal_observation" not in infos[i]
                np.testing.assert_array_equal(obs[i], o)
    assert ends["terminated"] > 0 and ends["truncated"] > 0, ends
    # SeedSchedule's methods through env_method (checkpoints, evaluation rewind).
    state = adapted.env_method("rng_state", indices=[1])[0]
    assert state["next"] == min(episode[1] + 1, 2)
    adapted.env_method("rewind")
    assert adapted.env_method("rng_state", indices=[1])[0]["next"] == 0
    adapted.env_method("set_rng_state", state, indices=[1])
    assert (
        adapted.get_attr("np_random", indices=[1])[0].bit_generator.state == state["bit_generator"]
    )
    adapted.close()
    reference.close()


def _copied(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: np.array(v) for k, v in r.items()} for r in rows]


def test_rows_are_the_info_columns_split_and_stay_put() -> None:
    """``step_rows``/``reset_rows`` give per rover what ``step``/``reset`` give as columns;
    nothing in them is a view of a buffer a later step or reset rewrites (the adapter hands
    them to SB3 without DummyVecEnv's deepcopy)."""
    from rover_env.training.vec_adapter import split_infos

    n = 3
    kwargs: dict[str, Any] = {"terrain": TINY, "max_episode_steps": 3}
    rows_env = ProtoExplorerVectorEnv(n, **kwargs)
    cols_env = ProtoExplorerVectorEnv(n, **kwargs)
    obs_r, rows = rows_env.reset_rows(seed=[1, 2, 3])
    obs_c, cols = cols_env.reset(seed=[1, 2, 3])
    np.testing.assert_array_equal(obs_r, obs_c)
    assert not np.array_equal(rows[0]["position"], rows[2]["position"])
    for i, split in enumerate(split_infos(cols, n)):
        same(rows[i], split, f"reset rover {i}")
    handed, copies = [rows], [_copied(rows)]
    rng = np.random.default_rng(2)
    for k in range(5):  # through a time limit: rows of autoreset rovers hold the reset's info
        a = rng.uniform(-1, 1, (n, 4)).astype(np.float32)
        *out_r, rows = rows_env.step_rows(a)
        *out_c, cols = cols_env.step(a)
        same(out_r, out_c, f"step {k}")
        for i, split in enumerate(split_infos(cols, n)):
            same(rows[i], split, f"step {k} rover {i}")
        handed.append(rows)
        copies.append(_copied(rows))
    rows_env.reset_rows(seed=[4, 5, 6])
    # What was handed out earlier is unchanged by later steps and resets (no shared buffers).
    for k, (got, copy) in enumerate(zip(handed, copies, strict=True)):
        for i in range(n):
            same({key: np.asarray(v) for key, v in got[i].items()}, copy[i], f"{k} rover {i}")
    mask = np.array([False, True, False])
    _, rows = rows_env.reset_rows(options={"reset_mask": mask})
    assert rows[0] == {} and rows[2] == {} and "position" in rows[1]
    rows_env.close()
    cols_env.close()


def test_obs_layout() -> None:
    env = ProtoExplorerVectorEnv(2, max_episode_steps=5)
    obs, info = env.reset(seed=0)
    assert obs.shape == (2, len(OBS_NAMES)) and obs.dtype == np.float32
    assert info["_command"].all() and info["command"].shape == (2, 2)
    with pytest.raises(RuntimeError, match="reset"):
        ProtoExplorerVectorEnv(1).step(np.zeros((1, 4), dtype=np.float32))


def test_training_batch_vec_env(tmp_path: Any) -> None:
    """``vec_env: batch`` in a PPO config: all rovers in one vector env, episodes monitored."""
    pytest.importorskip("stable_baselines3")
    from rover_env.training.config import AlgoConfig
    from rover_env.training.envs import make_vec_env

    cfg = AlgoConfig(vec_env="batch", max_episode_steps=3, env_kwargs={"sensor_noise": "none"})
    venv = make_vec_env(ID, cfg, 2, [[5], [6]], tmp_path, "train")
    obs = venv.reset()
    assert obs.shape == (2, len(OBS_NAMES))
    single = gym.make(ID, backend="plugin", sensor_noise="none", max_episode_steps=3)
    np.testing.assert_array_equal(obs[1], single.reset(seed=6)[0])
    episodes = []
    for _ in range(4):
        *_, infos = venv.step(np.zeros((2, 4), dtype=np.float32))
        episodes += [info["episode"] for info in infos if "episode" in info]
    assert len(episodes) == 2 and all(e["l"] == 3 for e in episodes)
    venv.close()
    assert (tmp_path / "train_batch.monitor.csv").is_file()
    with pytest.raises(ValueError, match="eval env 1: seeds \\[3000\\] are not validation seeds"):
        make_vec_env(ID, cfg, 2, [[2000], [3000]], None, "eval", split="validation")
