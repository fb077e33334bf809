"""What a family's world costs at reset: episode draw plus ``reset`` of the env (ground set on
the compiled simulator) against the fixed scenario's, measured in the same run.

    python benchmarks/bench_family_reset.py [--resets 20] [--scenarios flat-turns,sand-slope,soft-patch]
"""

from __future__ import annotations

import argparse
import time


def _per_reset(key: str, n: int) -> tuple[float, float]:
    from rover_env.benchmark.run import ScenarioWrapper
    from rover_env.envs.proto_explorer import ProtoExplorerEnv
    from rover_env.tasks.scenarios import load_scenario

    cfg = load_scenario(key)
    first = cfg.episode(1000)
    t0 = time.perf_counter()
    env = ScenarioWrapper(ProtoExplorerEnv(**first.env_kwargs()))
    build = time.perf_counter() - t0
    t0 = time.perf_counter()
    for s in range(1000, 1000 + n):
        env.set_episode(cfg.episode(s))
        env.reset()
    env.close()
    return build, (time.perf_counter() - t0) / n


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--resets", type=int, default=20)
    p.add_argument("--scenarios", default="flat-turns,sand-slope,soft-patch")
    args = p.parse_args()
    print("| scenario | build fixed [s] | reset fixed [ms] | reset family [ms] | ratio |")
    print("|---|---|---|---|---|")
    for n in args.scenarios.split(","):
        b0, r0 = _per_reset(n, args.resets)
        _, r1 = _per_reset(f"{n}@train", args.resets)
        print(f"| {n} | {b0:.2f} | {1e3 * r0:.1f} | {1e3 * r1:.1f} | {r1 / r0:.2f} |", flush=True)


if __name__ == "__main__":
    main()
