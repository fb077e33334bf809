"""Evaluate a trained run: python train/evaluate.py RUN_DIR [--episodes N] [--final --question ID].

Validation seeds by default; ``--final --question ID`` is the agent's one run on the test
seeds, a look at a registered question, recorded in docs/benchmark/test_ledger.csv (a second
one is refused unless ``--force``).
"""

import sys

from rover_env.training.cli import evaluate_main

if __name__ == "__main__":
    sys.exit(evaluate_main())
