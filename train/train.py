"""Train PPO, SAC or TD3 on a rover env: python train/train.py --algo sac --env-id ... --seed 0 --out DIR

The same as train/ppo.py, train/sac.py and train/td3.py with the algorithm as an option.
"""

import sys

from rover_env.training.cli import train_main

if __name__ == "__main__":
    sys.exit(train_main())
