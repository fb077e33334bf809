"""Train TD3 on a rover env (stable-baselines3; same run dir, resume and evaluation as PPO).

python train/td3.py --env-id rover_env/ProtoExplorerScenarioMix-v0 --config configs/agents_soil --seed 0 --out runs/td3_soil_s0
python train/td3.py --resume runs/td3_soil_s0     # continue from the newest checkpoint (replay buffer included)
"""

import sys

from rover_env.training.cli import train_main

if __name__ == "__main__":
    sys.exit(train_main(algo="td3"))
