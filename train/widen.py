"""Copy a residual PPO agent with a wider residual, acting the same (rover_env.training.widen).

python train/widen.py agents/mobility-ppo-rr-ft-patch --scale 1.0 --out agents/mobility-ppo-rr-wide
"""

import argparse
import sys

from rover_env.config import ConfigError
from rover_env.training.widen import widen_residual


def main() -> int:
    ap = argparse.ArgumentParser(prog="train/widen.py", description=__doc__)
    ap.add_argument("agent", help="agent or run folder (model, statistics, config.yaml)")
    ap.add_argument("--scale", type=float, required=True, help="new action_residual, in (0, 2]")
    ap.add_argument("--out", required=True, help="new agent folder (must not exist)")
    ap.add_argument("--noise-factor", type=float, default=1.0,
                    help="exploration noise of the copy x this (1: unchanged)")  # fmt: skip
    args = ap.parse_args()
    try:
        print(widen_residual(args.agent, args.scale, args.out, args.noise_factor))
    except (ConfigError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
