"""Train PPO on a rover env.

python train/ppo.py --env-id rover_env/ProtoExplorer-v0 --config configs/ppo.yaml --seed 0 --out runs/ppo_s0
python train/ppo.py --resume runs/ppo_s0          # continue a killed run from its last checkpoint
"""

import sys

from rover_env.training.cli import train_main

if __name__ == "__main__":
    sys.exit(train_main(algo="ppo"))
