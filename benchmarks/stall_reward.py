"""The training (mobility) reward a controller earns after T seconds, with its targets as they
are, halved and stopped: what stopping in a stall pays (issue 18, stop 36).

python benchmarks/stall_reward.py slip-pi:slip_pi_soil 1052 7

Soft-patch, one tuning or validation seed; the reward weights of a training config
(``--config``, default configs/agents/soil-families-ppo.yaml, the loose-soil agent's recipe;
the mobility reward of stop 36 was configs/agents_mobility/ppo_rr_wide_e04.yaml, in git
history).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from rover_env.benchmark.run import ScenarioWrapper
from rover_env.config import load_yaml
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.policies.specs import make_controller
from rover_env.seeds import split_of
from rover_env.tasks.scenarios import load_scenario

CONFIG = Path(__file__).resolve().parent.parent / "configs/agents/soil-families-ppo.yaml"


def reward_weights(config: Path) -> dict[str, Any]:
    """``env_kwargs.reward_weights`` of a one-entry training config (rl-zoo layout)."""
    data = load_yaml(config)
    ((_, entry),) = data.items()
    return dict(entry["env_kwargs"]["reward_weights"])


def mean_terms(
    spec: str, seed: int, t_switch: float, scale: float, weights: dict[str, Any]
) -> dict[str, float]:
    """Mean reward and reward terms a step from ``t_switch`` s on, targets x ``scale`` then."""
    ctrl = make_controller(spec)
    episode = load_scenario("soft-patch").episode(seed)
    w = ScenarioWrapper(ProtoExplorerEnv(terrain=episode.terrain, reward_weights=weights))
    w.set_episode(episode)
    obs, _ = w.reset()
    ctrl.reset(w.base)
    k = 0
    terms: dict[str, list[float]] = {"reward": []}
    while True:
        a = np.asarray(ctrl.action(w.base, obs), dtype=np.float32)
        late = k * w.base.control_dt >= t_switch
        if late:
            a = a * np.float32(scale)
        obs, r, term, trunc, info = w.step(a)
        k += 1
        if late:
            terms["reward"].append(float(r))
            for key, v in info.items():
                if key.startswith("reward_"):
                    terms.setdefault(key[7:], []).append(float(v))
        if term or trunc:
            return {key: float(np.mean(v)) for key, v in terms.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("controller", help="controller spec, as in rover-env benchmark")
    ap.add_argument("seed", type=int, help="soft-patch episode seed (tuning or validation)")
    ap.add_argument("t", type=float, help="seconds after which the targets are scaled")
    ap.add_argument("--config", type=Path, default=CONFIG, help="training config (its reward)")
    args = ap.parse_args()
    if split_of(args.seed) in ("test", "spent"):
        print(f"error: seed {args.seed} is a test or spent seed; probe tuning or validation seeds",
              file=sys.stderr)  # fmt: skip
        return 2
    weights = reward_weights(args.config)
    for scale in (1.0, 0.5, 0.0):
        m = mean_terms(args.controller, args.seed, args.t, scale, weights)
        rest = " ".join(f"{k} {v:+.3f}" for k, v in m.items() if k != "reward")
        print(f"targets x {scale:g}: reward {m['reward']:+.3f} a step; {rest}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
