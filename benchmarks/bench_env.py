"""Environment throughput against raw physics and Gymnasium's Ant-v5, measured in one run.

Run: python benchmarks/bench_env.py [--steps 200]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import rover_env
from rover_env.sim.simulator import RoverSim

gym.register_envs(rover_env)
ID = "rover_env/ProtoExplorer-v0"


def env_rate(env: gym.Env, steps: int) -> float:
    env.reset(seed=0)
    env.action_space.seed(0)
    t0 = time.perf_counter()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(env.action_space.sample())
        if np.any(term) or np.any(trunc):
            env.reset()
    return steps / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=int, default=200)
    args = ap.parse_args()

    sim = RoverSim()
    sim.set_speed_targets([2.0, 3.0, 2.0, 3.0])
    n = 2000
    t0 = time.perf_counter()
    sim.step(n)
    phys = n / (time.perf_counter() - t0)  # substeps/s with the tire layer

    env = gym.make(ID)
    single = env_rate(env, args.steps)
    ctrl_dt = env.unwrapped.control_dt
    env.close()

    vec = gym.make_vec(ID, num_envs=2, vectorization_mode="async")
    vec_rate = env_rate(vec, args.steps // 2) * 2
    vec.close()

    ant = gym.make("Ant-v5")
    ant_rate = env_rate(ant, 2000)
    ant_dt = ant.unwrapped.dt
    ant.close()

    phys_sim_s = phys * sim.dt
    env_sim_s = single * ctrl_dt
    print(f"physics with tire layer : {phys:9.0f} substeps/s = {phys_sim_s:7.2f} sim s / wall s")
    print(f"single env              : {single:9.1f} steps/s    = {env_sim_s:7.2f} sim s / wall s")
    print(f"env overhead over physics: {100 * (1 - env_sim_s / phys_sim_s):6.1f} %")
    print(
        f"async vector env (2)    : {vec_rate:9.1f} steps/s    = {vec_rate * ctrl_dt:7.2f} sim s / wall s"
        f"  (x{vec_rate / single:.2f} single)"
    )
    print(
        f"Gymnasium Ant-v5        : {ant_rate:9.1f} steps/s    = {ant_rate * ant_dt:7.2f} sim s / wall s"
    )
    print(f"rover env / Ant-v5 (sim s per wall s): {env_sim_s / (ant_rate * ant_dt):.4f}")


if __name__ == "__main__":
    main()
