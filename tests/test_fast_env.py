"""The env's compiled core (issue 5): C slip estimator and C sample loop against numpy."""

from __future__ import annotations

import os
import shutil
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from _compare import same

import rover_env
from rover_env.config import FrictionPatch, TerrainConfig, load_rover
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.estimation.batch import BatchSlipEstimator
from rover_env.estimation.fast import FastSlipEstimator
from rover_env.estimation.sensors import SensorConfig

pytestmark = pytest.mark.skipif(
    not any(shutil.which(c) for c in (os.environ.get("CC") or "gcc", "cc")),
    reason="the env's C core is compiled on first use and no C compiler (gcc) is installed",
)

gym.register_envs(rover_env)
ID = "rover_env/ProtoExplorer-v0"
TOL = 1e-12


def _drive(n: int, steps: int, dts: list[float], reset_p: float) -> list[tuple[Any, ...]]:
    """Pushes of random drives for n rovers: resets, gaps and irregular sampling."""
    rng = np.random.default_rng(1)
    t = np.zeros(n)
    angles = np.zeros((n, 11))
    out: list[tuple[Any, ...]] = []
    for _ in range(steps):
        ids = [i for i in range(n) if rng.random() < 0.8]
        resets = [i for i in ids if rng.random() < reset_p]
        t[resets] = 0.0
        t[ids] += rng.choice(dts, len(ids))
        angles[ids] += rng.normal([0.08] * 6 + [0.0] * 5, [0.02] * 6 + [0.01] * 5, (len(ids), 11))
        out.append((ids, resets, t[ids].copy(), angles[ids].copy()))
    return out


@pytest.mark.parametrize(
    ("dts", "reset_p"),
    [([0.02, 0.02, 0.05, 0.7], 0.03), ([0.001, 0.002], 0.001)],
    ids=["gaps", "dense"],
)
def test_fast_estimator_matches_numpy(dts: list[float], reset_p: float) -> None:
    """Rates, slip, chain motion, pose to 1e-12 and the same flags (dense: the ring grows)."""
    cfg = load_rover("proto_explorer")
    n = 3
    ref, fast = BatchSlipEstimator(cfg, n), FastSlipEstimator(cfg, n)
    compared = flagged = 0
    for ids, resets, t, y in _drive(n, 800, dts, reset_p):
        ref.reset(resets)
        fast.reset(resets)
        ref.push(ids, t, y[:, :6], y[:, 6:])
        fast.push(ids, t, y[:, :6], y[:, 6:])
        if not ids:
            continue
        for a, b in zip(fast.estimate(ids), ref.estimate(ids), strict=True):
            for name, want in vars(b).items():
                got = getattr(a, name)
                assert np.shape(got) == np.shape(want), name
                if name == "flags":
                    np.testing.assert_array_equal(got, want)
                    flagged += int(np.any(want))
                else:
                    scale = max(1.0, float(np.max(np.abs(want))))
                    np.testing.assert_allclose(got, want, rtol=0, atol=TOL * scale, err_msg=name)
            compared += 1
    assert compared > 1000 and 0 < flagged < compared


def test_fast_estimator_refuses_bad_samples() -> None:
    est = FastSlipEstimator(load_rover("proto_explorer"), 2)
    with pytest.raises(RuntimeError, match="at least one sample"):
        est.estimate([0])
    est.push([0], [1.0], np.zeros((1, 6)), np.zeros((1, 5)))
    with pytest.raises(ValueError, match=r"time must increase: 1\.0 then 1\.0"):
        est.push([0], [1.0], np.zeros((1, 6)), np.zeros((1, 5)))
    bad = np.zeros((1, 6))
    bad[0, 2] = np.nan
    with pytest.raises(ValueError, match="finite"):
        est.push([1], [0.5], bad, np.zeros((1, 5)))
    est.estimate([0])  # the good rover is untouched


def _rollout(fast: bool, kwargs: dict[str, Any], steps: int) -> list[Any]:
    env = gym.make(ID, backend="plugin", **kwargs)
    core = env.unwrapped
    assert isinstance(core, ProtoExplorerEnv) and core._fast is not None
    if not fast:
        core._fast = None  # the numpy sample loop, same compiled estimator
    rng = np.random.default_rng(0)
    out: list[Any] = [env.reset(seed=3)]
    for _ in range(steps):
        step = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        out.append(step)
        if step[2] or step[3]:
            out.append(env.reset())
    env.close()
    return out


PATCHY = TerrainConfig(
    patches=(FrictionPatch(name="sand", center=(0.3, 0.0), size=(2.0, 2.0), mu_x=0.3, mu_y=0.25),)
)


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"sensor_noise": SensorConfig(wheel_noise=0.003)},
        {"sensor_noise": "none", "terrain": PATCHY},
        {"action_layout": "sides", "slip_source": "estimate", "max_episode_steps": 12},
    ],
    ids=["default", "wheel-noise", "patch-no-noise", "sides-estimate-resets"],
)
def test_c_sample_loop_equals_numpy_loop(kwargs: dict[str, Any]) -> None:
    """Observations, rewards, flags and infos bit for bit, noise draws included."""
    same(_rollout(True, kwargs, 30), _rollout(False, kwargs, 30))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"max_episode_steps": 6},
        {"sensor_noise": SensorConfig(wheel_noise=0.003), "action_layout": "sides"},
    ],
    ids=["resets", "wheel-noise"],
)
def test_vector_c_sampler_equals_numpy_loop(kwargs: dict[str, Any]) -> None:
    """The vector env's C sample loop against its numpy loop, partial resets included."""
    runs = []
    for fast in (True, False):
        venv = gym.make_vec(ID, num_envs=3, vectorization_mode="vector_entry_point", **kwargs)
        core = venv.unwrapped
        assert core._sampler is not None  # type: ignore[attr-defined]
        if not fast:
            core._sampler = None  # type: ignore[attr-defined]
        rng = np.random.default_rng(4)
        out: list[Any] = [venv.reset(seed=9)]
        for _ in range(14):
            out.append(venv.step(rng.uniform(-1, 1, venv.action_space.shape).astype(np.float32)))
        venv.close()
        runs.append(out)
    same(runs[0], runs[1])
