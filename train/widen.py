"""Copy a residual PPO agent with a wider residual and/or the stall clock as a new input, acting
the same (rover_env.training.widen).

python train/widen.py runs/soil_ppo_s0 --scale 1.0 --out runs/soil_ppo_wide
python train/widen.py runs/soil_ppo_s0 --scale 1.0 --stall-clock --out runs/soil_ppo_clock
"""

import argparse
import sys
import tempfile
from pathlib import Path

from rover_env.config import ConfigError
from rover_env.training.widen import add_stall_clock, widen_residual


def main() -> int:
    ap = argparse.ArgumentParser(prog="train/widen.py", description=__doc__)
    ap.add_argument("agent", help="agent or run folder (model, statistics, config.yaml)")
    ap.add_argument("--scale", type=float, default=None, help="new action_residual, in (0, 2]")
    ap.add_argument("--out", required=True, help="new agent folder (must not exist)")
    ap.add_argument("--noise-factor", type=float, default=1.0,
                    help="exploration noise of the copy x this (1: unchanged)")  # fmt: skip
    ap.add_argument("--stall-clock", action="store_true",
                    help="add the stall clock as a 47th input of zero weight")  # fmt: skip
    args = ap.parse_args()
    if args.scale is None and not args.stall_clock:
        print("error: give --scale, --stall-clock or both", file=sys.stderr)
        return 2
    if args.scale is None and args.noise_factor != 1.0:
        print("error: --noise-factor rescales with --scale; give both", file=sys.stderr)
        return 2
    try:
        if not args.stall_clock:
            print(widen_residual(args.agent, args.scale, args.out, args.noise_factor))
            return 0
        with tempfile.TemporaryDirectory() as tmp:
            src = args.agent
            if args.scale is not None:
                src = widen_residual(args.agent, args.scale, Path(tmp) / "w", args.noise_factor)
            print(add_stall_clock(src, args.out))
    except (ConfigError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
