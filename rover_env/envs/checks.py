"""Long environment checks for `rover-env validate` (not part of the default test run)."""

from __future__ import annotations

import math
import time

import gymnasium as gym
import numpy as np
from tqdm import tqdm


def random_steps(
    env_id: str = "rover_env/ProtoExplorerRough-v0", steps: int = 10_000, seed: int = 0
) -> dict[str, float]:
    """Random actions for ``steps`` steps: any NaN or MuJoCo warning raises."""
    env = gym.make(env_id)
    env.action_space.seed(seed)
    obs, _ = env.reset(seed=seed)
    episodes = flips = exits = 0
    t0 = time.perf_counter()
    for _ in tqdm(range(steps), desc=f"{env_id} random actions", unit="step", leave=False):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        if not (np.all(np.isfinite(obs)) and math.isfinite(float(reward))):
            raise FloatingPointError(f"non-finite observation or reward at episode {episodes}")
        flips += int(info["flipped"])
        exits += int(info["out_of_arena"])
        if terminated or truncated:
            episodes += 1
            obs, _ = env.reset()
    env.close()
    return {
        "steps": steps,
        "episodes": episodes,
        "flips": flips,
        "exits": exits,
        "wall_s": time.perf_counter() - t0,
    }
