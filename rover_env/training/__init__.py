"""Training (stable-baselines3 PPO, SAC, TD3; Optuna search): with the benchmark's lazily
loaded policies, the only part that imports torch.

``train(env_id, config_path, seed, out_dir, resume=False, total_timesteps=None, algo="ppo")``
writes a run dir (layout in ``rover_env.training.run``); ``train/ppo.py``, ``train/sac.py``,
``train/td3.py`` (``train/train.py --algo``), ``train/search.py`` and ``train/evaluate.py``
are its command lines.
"""

from __future__ import annotations

from rover_env.training.config import (
    ALGOS,
    AlgoConfig,
    load_algo_config,
    load_config,
)
from rover_env.training.run import TrainResult, train

__all__ = [
    "ALGOS",
    "AlgoConfig",
    "TrainResult",
    "load_algo_config",
    "load_config",
    "train",
]
