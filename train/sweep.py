"""A training sweep: one train/ppo.py run per seed (and algorithm), locally or on Ray.

python train/sweep.py --config configs/ppo.yaml --env-id rover_env/ProtoExplorer-v0 --seeds 0-9 --out runs/sweep
python train/sweep.py --config configs/ppo.yaml --env-id rover_env/ProtoExplorer-v0 --seeds 0-3 --executor ray --ray-address HOST:6379 --out /shared/runs/sweep
python train/sweep.py --config ... --seeds 0-9 --out runs/sweep --resume   # finish a stopped sweep
"""

import sys

from rover_env.training.cli import sweep_main

if __name__ == "__main__":
    sys.exit(sweep_main())
