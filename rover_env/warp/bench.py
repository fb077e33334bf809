"""Throughput of the Warp rover beside raw MuJoCo Warp on the same model.

``run([1024, 4096])`` returns one row per world count and kind: ``warp-env`` (the torch env
with the tire layer, random actions), ``warp-ppo`` (a short PPO run on that env, rollout and
update together), each with ``raw_steps_per_s``: bare ``mujoco_warp.step`` on the same MJCF
(no tire layer, so the wheels carry nothing: the chassis rests on the ground) measured in the
same process. Steps are physics substeps of one world (a ``WarpRoverEnv.step`` is
``control_dt / timestep`` of them), so the columns compare directly.

``python -m rover_env.warp.bench [N ...]`` prints the table (default 1024 4096 16384 on a
GPU, 16 on CPU).
"""

from __future__ import annotations

import sys
import time

import mujoco_warp as mjw
import torch
import warp as wp

from rover_env.config import load_rover, load_terrain
from rover_env.warp.env import ACT_DIM, WarpRoverEnv
from rover_env.warp.ppo import PPOConfig, train
from rover_env.warp.sim import warp_model


def default_device() -> str:
    return "cuda:0" if wp.is_cuda_available() else "cpu"


def raw_steps_per_s(n: int, device: str, steps: int = 100) -> float:
    """Bare ``mujoco_warp.step`` of the rover's model, captured as the env's substeps are."""
    mjm = warp_model(load_rover("proto_explorer"), load_terrain("flat"))
    with wp.ScopedDevice(device):
        m = mjw.put_model(mjm)
        d = mjw.make_data(mjm, nworld=n)
        mjw.step(m, d)  # compile
        with wp.ScopedCapture() as cap:  # a CUDA graph, or Warp's CPU launch stream
            for _ in range(steps):
                mjw.step(m, d)
        wp.synchronize()
        t0 = time.perf_counter()
        wp.capture_launch(cap.graph)
        wp.synchronize()
        return n * steps / (time.perf_counter() - t0)


def env_steps_per_s(env: WarpRoverEnv, iterations: int = 10) -> float:
    """Substeps per second of ``env.step`` with random actions (after a warm-up step)."""
    gen = torch.Generator(device=env.device).manual_seed(0)
    env.reset()
    env.step(torch.zeros(env.n, ACT_DIM, device=env.device))  # compile and capture
    wp.synchronize()
    t0 = time.perf_counter()
    for _ in range(iterations):
        a = torch.rand(env.n, ACT_DIM, generator=gen, device=env.device) * 2 - 1
        env.step(a)
    wp.synchronize()
    return env.n * env.substeps * iterations / (time.perf_counter() - t0)


def run(n_worlds: list[int], device: str | None = None, ppo_iterations: int = 3) -> list[dict]:
    """One ``warp-env`` and one ``warp-ppo`` row per world count (module docstring)."""
    dev = device or default_device()
    rows = []
    for n in n_worlds:
        raw = raw_steps_per_s(n, dev)
        env = WarpRoverEnv(n, device=dev)
        rows.append(
            {
                "name": "warp-env",
                "n": n,
                "steps_per_s": env_steps_per_s(env),
                "raw_steps_per_s": raw,
                "substeps": env.substeps,
            }
        )
        _, log = train(env, ppo_iterations, PPOConfig(steps_per_env=8))
        ppo = log[-1]["steps_per_s"] * env.substeps  # env steps -> substeps
        rows.append(
            {
                "name": "warp-ppo",
                "n": n,
                "steps_per_s": ppo,
                "raw_steps_per_s": raw,
                "substeps": env.substeps,
            }
        )
    return rows


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    dev = default_device()
    ns = [int(a) for a in args] or ([1024, 4096, 16384] if dev != "cpu" else [16])
    print(f"device {wp.get_device(dev).name}")
    print(f"{'name':<10} {'n':>7} {'steps/s':>12} {'raw MJWarp':>12} {'ratio':>6}")
    for r in run(ns, dev):
        ratio = r["steps_per_s"] / r["raw_steps_per_s"]
        print(
            f"{r['name']:<10} {r['n']:>7} {r['steps_per_s']:>12.0f} {r['raw_steps_per_s']:>12.0f}"
            f" {ratio:>6.2f}"
        )


if __name__ == "__main__":
    main()
