"""Where the wall time of training goes, stage by stage (rover_env.training.profiling).

python train/profile_training.py --algo ppo --env-id rover_env/ProtoExplorer-v0 --steps 8192
python train/profile_training.py --algo sac --config configs/sac.yaml --steps 1000

Trains for --steps env steps without a run dir and prints ms per env step of each stage.
benchmarks/bench_throughput.py compares configurations in one run, beside raw MuJoCo.
"""

import sys

from rover_env.training.profiling import profile_main

if __name__ == "__main__":
    sys.exit(profile_main())
