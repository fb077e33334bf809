"""Optuna hyperparameter search on validation seeds, with a budget; resumable.

python train/search.py --algo sac --config configs/agents_soil --env-id rover_env/ProtoExplorerScenarioMix-v0 \
    --trials 20 --timesteps-per-trial 30000 --budget-minutes 240 --storage sqlite:///runs/search/sac/study.db --out runs/search/sac
Writes OUT/trials.csv and OUT/best.yaml (usable as --config); rerun the same command to resume.
"""

import sys

from rover_env.training.cli import search_main

if __name__ == "__main__":
    sys.exit(search_main())
