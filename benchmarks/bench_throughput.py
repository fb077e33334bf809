"""Env steps per second of the envs and of training on them, each beside raw MuJoCo measured
in the same run (issue 49).

Run: python benchmarks/bench_throughput.py [--quick] [--n 32] [--steps 8192]
                                           [--skip-training] [--skip-gpu]

Prints markdown, all measured in this process:

1. CPU env: the single env (fast path) beside raw MuJoCo: the same compiled model stepped by
   ``mj_step`` with no tire layer (gravity off, as in bench_speed.py), 100 substeps of 1 ms
   counted as one env step;
2. batched CPU env: ``ProtoExplorerVectorEnv`` with ``--n`` rovers beside raw
   ``mujoco.batch`` with the same rovers and threads, no tire layer;
3. training on CPU: PPO with the shipped recipe before issue 49 (2 subprocess envs x 512
   steps), the batched env through Gymnasium's info columns (the adapter's general path), and
   the shipped configs/ppo.yaml (32 batched rovers x 32 steps), then before and shipped again
   in turn (the ratio is the median over rounds); SAC and TD3 as shipped and on
   the batched env (past ``learning_starts``); each profiled stage by stage
   (:mod:`rover_env.training.profiling`) and beside raw ``mujoco.batch`` measured right before
   and after it (the mean of the two);
4. GPU (only where ``mujoco_warp`` imports and a CUDA device exists): the Warp env at
   N = 1k, 4k, 16k beside raw MJWarp, from ``rover_env.warp.bench``.

The machine may be shared: every row also gives its steps per CPU-second of this process
(what the threads would do on idle cores) and the load average, and ratios to raw MuJoCo are
taken from rates measured next to each other, not minutes apart.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import mujoco
import mujoco.batch
import numpy as np

import rover_env
from rover_env.sim.simulator import RoverSim

gym.register_envs(rover_env)
ID = "rover_env/ProtoExplorer-v0"
ID_V1 = "rover_env/ProtoExplorer-v1"
"""The same task at the 2 ms physics step (docs/timestep.md): 50 substeps per env step."""
SUBSTEPS = 100
"""Physics substeps (1 ms) per env step (0.1 s)."""


@dataclasses.dataclass
class Rate:
    """Units per wall second and per CPU second of this process."""

    wall: float
    cpu: float


def timed(fn: Callable[[], int]) -> Rate:
    t0, c0 = time.perf_counter(), time.process_time()
    units = fn()
    dt, dc = time.perf_counter() - t0, time.process_time() - c0
    return Rate(units / dt, units / max(dc, 1e-9))


def raw_model() -> mujoco.MjModel:
    """The rover's compiled model, to be stepped with no tire layer and gravity off (it
    touches the ground only through the tire layer: pure engine cost)."""
    sim = RoverSim(backend="numpy")
    sim.set_speed_targets([2.0, 3.0, 2.0, 3.0])
    model = sim.model
    model.opt.gravity[:] = 0.0
    return model


class RawSingle:
    """Raw MuJoCo, one rover: env-step equivalents (100 substeps) per second."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model, self.data = model, mujoco.MjData(model)

    def __call__(self, steps: int) -> Rate:
        def run() -> int:
            mujoco.mj_step(self.model, self.data, SUBSTEPS * steps)
            return steps

        return timed(run)


class RawBatch:
    """Raw ``mujoco.batch``, ``n`` rovers: rover env-step equivalents per second
    (:meth:`beside`: the best of a few chunks, the reference measured next to a row)."""

    def __init__(self, model: mujoco.MjModel, n: int, nthread: int) -> None:
        self.n = n
        self.batch = mujoco.batch.Batch(model, n, nthread)

    def __call__(self, steps: int) -> Rate:
        def run() -> int:
            for _ in range(steps):
                self.batch.step(nstep=SUBSTEPS)
            return steps * self.n

        return timed(run)

    def beside(self) -> float:
        return best([self(max(2, 640 // self.n)) for _ in range(4)]).wall


def env_rate(env: Any, steps: int, n: int) -> Rate:
    """Env steps per second (summed over rovers) with random actions."""
    env.action_space.seed(0)

    def run() -> int:
        for _ in range(steps):
            out = env.step(env.action_space.sample())
            if n == 1 and (out[2] or out[3]):
                env.reset()
        return steps * n

    return timed(run)


def best(rates: list[Rate]) -> Rate:
    return Rate(max(r.wall for r in rates), max(r.cpu for r in rates))


def envs_section(out: Callable[[str], None], n: int, rounds: int, nthread: int) -> RawBatch:
    model = raw_model()
    raw1, rawn = RawSingle(model), RawBatch(model, n, nthread)
    single = gym.make(ID, backend="plugin")
    single.reset(seed=0)
    vec = gym.make_vec(ID, num_envs=n, vectorization_mode="vector_entry_point", nthread=nthread)
    vec.reset(seed=0)
    rows: dict[str, list[Rate]] = {k: [] for k in ("env", "raw", "vec", "rawn")}
    ratios: dict[str, list[float]] = {"env": [], "vec": []}
    for _ in range(rounds):  # interleaved: each rate beside its raw reference
        rows["env"].append(env_rate(single, 20, 1))
        rows["raw"].append(raw1(20))
        rows["vec"].append(env_rate(vec, max(2, 640 // n), n))
        rows["rawn"].append(rawn(max(2, 640 // n)))
        ratios["env"].append(rows["env"][-1].wall / rows["raw"][-1].wall)
        ratios["vec"].append(rows["vec"][-1].wall / rows["rawn"][-1].wall)
    single.close()
    vec.close()
    b = {k: best(v) for k, v in rows.items()}
    out("## Envs on CPU (env steps/s; raw MuJoCo: 100 substeps of the same model, no tire layer)")
    out("")
    out(
        "| | env steps/s | per CPU-s | raw MuJoCo steps/s | raw per CPU-s | / raw (median of rounds) |"
    )
    out("|---|---:|---:|---:|---:|---:|")
    out(
        f"| single env (fast path) | {b['env'].wall:,.0f} | {b['env'].cpu:,.0f} | "
        f"{b['raw'].wall:,.0f} | {b['raw'].cpu:,.0f} | {np.median(ratios['env']):.3f} |"
    )
    out(
        f"| batched env, N = {n}, {nthread or os.cpu_count()} threads | {b['vec'].wall:,.0f} | "
        f"{b['vec'].cpu:,.0f} | {b['rawn'].wall:,.0f} (mujoco.batch) | {b['rawn'].cpu:,.0f} | "
        f"{np.median(ratios['vec']):.3f} |"
    )
    out("")
    return rawn


def training_section(
    out: Callable[[str], None], rawn: RawBatch, steps: int, off_steps: int, n: int, rounds: int
) -> None:
    from rover_env.training.config import load_algo_config
    from rover_env.training.profiling import profile_training, table

    new = load_algo_config("ppo", "ppo", ID)
    old = dataclasses.replace(
        new,
        n_envs=2,
        vec_env="subproc",
        hyperparams={**new.hyperparams, "n_steps": 512},
    )
    runs: list[tuple[str, Any, dict[str, Any]]] = [
        ("PPO 2 subproc x 512 (before)", old, {}),
        (f"PPO batch {new.n_envs} x {new['n_steps']}, info columns", new, {"info_rows": False}),
        (f"PPO batch {new.n_envs} x {new['n_steps']} (shipped)", new, {}),
    ]
    for algo in ("sac", "td3"):
        cfg = load_algo_config(algo, algo, ID)
        starts = int(cfg["learning_starts"])
        kw = {"warmup": starts + 2 * cfg.n_envs}
        runs.append((f"{algo.upper()} 2 subproc (shipped)", cfg, kw))
        runs.append((f"{algo.upper()} batch 2", dataclasses.replace(cfg, vec_env="batch"), kw))
    profiles, raws = [], []
    ppo_rounds: list[tuple[Any, Any]] = []
    for k in range(rounds):  # PPO before and shipped in turn: ratios per round
        pair = []
        for label, cfg, kw in runs[:3] if k == 0 else [runs[0], runs[2]]:
            r0 = rawn.beside()
            p = profile_training(ID, cfg, steps, label, **kw)
            r1 = rawn.beside()
            if k == 0:
                profiles.append(p)
                raws.append(0.5 * (r0 + r1))
            if label != runs[1][0]:
                pair.append(p)
            print(f"  round {k}: {label}: {p.steps_per_s:,.1f} env steps/s", flush=True)
        ppo_rounds.append((pair[0], pair[1]))
    for label, cfg, kw in runs[3:]:
        r0 = rawn.beside()
        p = profile_training(ID, cfg, off_steps, label, **kw)
        r1 = rawn.beside()
        profiles.append(p)
        raws.append(0.5 * (r0 + r1))
        print(f"  {label}: {p.steps_per_s:,.1f} env steps/s", flush=True)
    v1 = load_algo_config("ppo", "ppo", ID_V1)
    label = f"PPO batch {v1.n_envs} x {v1['n_steps']}, {ID_V1.split('/')[1]} (2 ms)"
    r0 = rawn.beside()
    p_v1 = profile_training(ID_V1, v1, steps, label)
    r1 = rawn.beside()
    profiles.append(p_v1)
    raws.append(r0 + r1)  # raw at 50 substeps per env step: twice the 1 ms rate (mean of two)
    print(f"  {label}: {p_v1.steps_per_s:,.1f} env steps/s", flush=True)
    out("## Training on CPU: where each millisecond of an env step goes")
    out("")
    out(
        f"PPO {steps:,} env steps (first of {rounds} interleaved rounds), SAC/TD3 "
        f"{off_steps:,} (after their learning_starts, untimed), one seed, torch threads 1, "
        f"mujoco.batch on all CPUs; timers exclusive (rover_env.training.profiling). CPU-s: "
        f"this process and its env worker processes."
    )
    out("")
    for line in table(profiles):
        out(line)
    cells = " | ".join(f"{r:,.0f}" for r in raws)
    out(f"| raw mujoco.batch N = {n}, steps/s (best chunk before and after, mean) | {cells} |")
    cells = " | ".join(f"{p.steps_per_s / r:.3f}" for p, r in zip(profiles, raws, strict=True))
    out(f"| / raw | {cells} |")
    out("")
    wall = [b.steps_per_s / a.steps_per_s for a, b in ppo_rounds]
    cpu = [b.steps_per_cpu_s / a.steps_per_cpu_s for a, b in ppo_rounds]
    ppo1 = ppo_rounds[-1][1]
    out(
        f"PPO shipped / before, {rounds} interleaved rounds: {float(np.median(wall)):.2f} x env "
        f"steps/s (rounds {', '.join(f'{x:.2f}' for x in wall)}), "
        f"{float(np.median(cpu)):.2f} x env steps per CPU-second (process + env workers; "
        f"rounds {', '.join(f'{x:.2f}' for x in cpu)}). Shipped, last round: "
        f"{ppo1.steps_per_s:,.0f} env steps/s, {ppo1.steps_per_cpu_s:,.0f} per CPU-second."
    )
    out("")
    before = ppo_rounds[0][0]
    out(
        f"PPO on {ID_V1} (the same task at 2 ms; its raw reference is the same model at 50 "
        f"substeps per env step): {p_v1.steps_per_s:,.0f} env steps/s, "
        f"{p_v1.steps_per_cpu_s:,.0f} per CPU-second; {p_v1.steps_per_s / before.steps_per_s:.2f} "
        f"x the recipe before issue 49 (first round)."
    )
    out("")


def gpu_section(out: Callable[[str], None]) -> None:
    """The Warp env beside raw MJWarp, where mujoco_warp and a CUDA device exist."""
    try:
        import mujoco_warp  # noqa: F401
        import warp as wp

        wp.init()
        if not wp.is_cuda_available():
            raise RuntimeError("no CUDA device")
        from rover_env.warp import bench as warp_bench
    except Exception as exc:  # any failure to set up the GPU path skips the section
        out(f"GPU section skipped: {type(exc).__name__}: {exc}")
        out("")
        return
    rows = warp_bench.run(n_worlds=[1024, 4096, 16384])
    out("## GPU: Warp env beside raw MJWarp")
    out("")
    out("Substeps are physics steps of one world; an env step is `substeps` of them.")
    out("")
    out("| | N | env steps/s | substeps/s | raw MJWarp substeps/s | / raw |")
    out("|---|---:|---:|---:|---:|---:|")
    for r in rows:
        ratio = r["steps_per_s"] / r["raw_steps_per_s"] if r["raw_steps_per_s"] else float("nan")
        out(
            f"| {r['name']} | {r['n']:,} | {r['steps_per_s'] / r['substeps']:,.0f} | "
            f"{r['steps_per_s']:,.0f} | {r['raw_steps_per_s']:,.0f} | {ratio:.3f} |"
        )
    out("")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="short runs (~1-2 min; full ~10 min)")
    ap.add_argument("--n", type=int, default=32, help="rovers of the batched env rows")
    ap.add_argument("--steps", type=int, default=None, help="PPO env steps per profile")
    ap.add_argument("--skip-training", action="store_true")
    ap.add_argument("--skip-gpu", action="store_true")
    args = ap.parse_args()
    lines: list[str] = []

    def out(line: str = "") -> None:
        print(line, flush=True)
        lines.append(line)

    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    out("# Throughput (benchmarks/bench_throughput.py" + (" --quick)" if args.quick else ")"))
    out("")
    out(
        f"MuJoCo {mujoco.__version__}, Python {platform.python_version()}, {os.cpu_count()} "
        f"CPUs, load average at start {load0:.2f}."
    )
    out("")
    rawn = envs_section(out, args.n, 3 if args.quick else 8, 0)
    if not args.skip_training:
        steps = args.steps or (2048 if args.quick else 8192)
        training_section(
            out, rawn, steps, 256 if args.quick else 1024, args.n, 2 if args.quick else 3
        )
    if not args.skip_gpu:
        gpu_section(out)
    out(
        f"Total {time.perf_counter() - t0:.0f} s; load average at end {os.getloadavg()[0]:.2f} "
        f"({os.cpu_count()} CPUs)."
    )


if __name__ == "__main__":
    main()
