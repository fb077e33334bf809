"""Gymnasium registration (Gymnasium 1.x has no plugin auto-loading: ``import rover_env`` does it)."""

from __future__ import annotations

import gymnasium as gym

ENV_IDS = ("rover_env/ProtoExplorer-v0", "rover_env/ProtoExplorerRough-v0")
V1_ENV_IDS = ("rover_env/ProtoExplorer-v1", "rover_env/ProtoExplorerRough-v1")
"""The same tasks at the 2 ms physics step (issue 49, docs/timestep.md): every physical check
holds there with its 1 ms tolerance and a step costs half the substeps. A new version because
trajectories differ (by ~1e-4); v0 keeps 1 ms for the agents and figures made on it."""
V1_TIMESTEP = 0.002
MIX_ENV_ID = "rover_env/ProtoExplorerScenarioMix-v0"
SOIL_ENV_ID = "rover_env/ProtoExplorerSoil-v1"
"""Random tracking commands on loose soil (``configs/terrain/sand.yaml``). Not in ENV_IDS,
the ids configs/ppo.yaml carries training settings for."""
FAMILY_ENV_ID = "rover_env/ProtoExplorerFamilies-v0"
"""The scenario families' training distributions, one world drawn per episode (issue 46)."""
MAX_EPISODE_STEPS = 300
"""30 s at the default 10 Hz control frequency."""
VECTOR_ENTRY_POINT = "rover_env.envs.vector:ProtoExplorerVectorEnv"


def register_envs() -> None:
    """Register the rover environments once per process."""
    if ENV_IDS[0] in gym.registry:
        return
    # vector_entry_point: gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")
    # steps N rovers together on mujoco.batch (rover_env.envs.vector).
    gym.register(
        id=ENV_IDS[0],
        entry_point="rover_env.envs.proto_explorer:ProtoExplorerEnv",
        vector_entry_point=VECTOR_ENTRY_POINT,
        max_episode_steps=MAX_EPISODE_STEPS,
    )
    gym.register(
        id=ENV_IDS[1],
        entry_point="rover_env.envs.proto_explorer:ProtoExplorerEnv",
        vector_entry_point=VECTOR_ENTRY_POINT,
        max_episode_steps=MAX_EPISODE_STEPS,
        kwargs={"terrain": "rough", "randomize_terrain": True},
    )
    for v0, v1 in zip(ENV_IDS, V1_ENV_IDS, strict=True):
        kwargs = dict(gym.spec(v0).kwargs)
        gym.register(
            id=v1,
            entry_point="rover_env.envs.proto_explorer:ProtoExplorerEnv",
            vector_entry_point=VECTOR_ENTRY_POINT,
            max_episode_steps=MAX_EPISODE_STEPS,
            kwargs={**kwargs, "timestep": V1_TIMESTEP},
        )
    gym.register(
        id=SOIL_ENV_ID,
        entry_point="rover_env.envs.proto_explorer:ProtoExplorerEnv",
        vector_entry_point=VECTOR_ENTRY_POINT,
        max_episode_steps=MAX_EPISODE_STEPS,
        kwargs={"terrain": "sand"},
    )
    # The benchmark's scenarios as a training ground (one drawn per episode). It lives with
    # the benchmark, above this layer, so it is named by string and imported only on make.
    gym.register(
        id=MIX_ENV_ID,
        entry_point="rover_env.benchmark.mixture:ScenarioMixEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
    )
    gym.register(
        id=FAMILY_ENV_ID,
        entry_point="rover_env.benchmark.mixture:families_env",
        max_episode_steps=MAX_EPISODE_STEPS,
    )
