"""Evaluate a trained run on the test seeds: python train/evaluate.py RUN_DIR [--episodes N]."""

import sys

from rover_env.training.cli import evaluate_main

if __name__ == "__main__":
    sys.exit(evaluate_main())
