"""The physics timestep as a setting (issue 49, item 2; study: docs/timestep.md)."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import rover_env  # noqa: F401  (registers the env ids)
from rover_env.config import ConfigError, SimSpec, load_rover
from rover_env.envs.registration import ENV_IDS, V1_ENV_IDS
from rover_env.sim.rig import free_wheel_residual
from rover_env.sim.simulator import RoverSim


@pytest.mark.parametrize(("timestep", "substeps"), [(None, 20), (0.002, 10), (0.005, 4)])
def test_env_timestep_sets_the_substep_count_and_keeps_the_step(
    timestep: float | None, substeps: int
) -> None:
    env = gym.make("rover_env/ProtoExplorer-v0", timestep=timestep, backend="plugin")
    e = env.unwrapped
    assert e.sim.dt == pytest.approx(timestep or 0.001)
    assert e.substeps_per_sample == substeps  # 20 ms sensor samples (estimator_rate 50 Hz)
    assert e.substeps_per_sample * e.samples_per_step * e.sim.dt == pytest.approx(0.1)
    env.reset(seed=0)
    t0 = e.sim.time
    env.step(env.action_space.sample())
    assert e.sim.time - t0 == pytest.approx(0.1)
    env.close()


def test_env_timestep_is_validated() -> None:
    with pytest.raises(ValueError, match=r"timestep 0\.003 s must divide"):
        gym.make("rover_env/ProtoExplorer-v0", timestep=0.003)
    with pytest.raises(ConfigError, match=r"sim\.timestep above 5 ms"):
        gym.make("rover_env/ProtoExplorer-v0", timestep=0.01)
    with pytest.raises(ConfigError, match=r"sim\.timestep must be"):
        gym.make("rover_env/ProtoExplorer-v0", timestep=-0.001)
    with pytest.raises(ValueError, match="whole number of"):
        gym.make("rover_env/ProtoExplorer-v0", control_frequency=15.0)


def test_free_wheel_settles_at_2_ms_even_lightly_loaded() -> None:
    """The rear (unpowered) wheels' tire damping is explicit: at 5 N of load its bound is
    about 3.2 ms (docs/timestep.md); at 2 ms the wheel must settle to exactly rolling."""
    assert free_wheel_residual(5.0, dt=0.002) < 1e-3
    assert free_wheel_residual(27.0, dt=0.002) < 1e-3


def test_turning_drive_at_2_ms_ends_where_the_1_ms_drive_does() -> None:
    """validate's convergence drive (20 s, turning) at 2 ms vs 1 ms: within 1 % of the
    distance travelled (the validation's tolerance)."""
    ends = []
    for dt in (0.001, 0.002):
        cfg = dataclasses.replace(load_rover(), sim=SimSpec(timestep=dt))
        sim = RoverSim(cfg, backend="plugin")
        p0 = sim.segment_truth().pos[1, :2].copy()
        for k in range(200):
            sim.set_speed_targets([1.5, 3.0, 1.5, 3.0] if k >= 20 else [2.5] * 4)
            sim.step(round(0.1 / dt))
        ends.append(sim.segment_truth().pos[1, :2].copy())
    dist = float(np.linalg.norm(ends[0] - p0))
    assert dist > 1.0
    assert np.linalg.norm(ends[1] - ends[0]) < 0.01 * dist


@pytest.mark.parametrize("v0, v1", list(zip(ENV_IDS, V1_ENV_IDS, strict=True)))
def test_v1_ids_are_the_v0_tasks_at_2_ms(v0: str, v1: str) -> None:
    """v1 = v0's task and kwargs at the 2 ms step, single and batched; a step stays 0.1 s."""
    assert gym.spec(v1).kwargs == {**gym.spec(v0).kwargs, "timestep": 0.002}
    env = gym.make(v1)
    assert env.unwrapped.sim.dt == pytest.approx(0.002)
    env.reset(seed=0)
    t0 = env.unwrapped.sim.data.time
    env.step(np.zeros(4, dtype=np.float32))
    assert env.unwrapped.sim.data.time - t0 == pytest.approx(0.1)
    vec = gym.make_vec(v1, num_envs=2, vectorization_mode="vector_entry_point")
    assert vec.unwrapped.sim.dt == pytest.approx(0.002)
    assert gym.make(v0).unwrapped.sim.dt == pytest.approx(0.001)
