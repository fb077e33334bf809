"""PPO training (stable-baselines3): with the benchmark's policy loader, the only part that imports torch.

``train(env_id, config_path, seed, out_dir, resume=False, total_timesteps=None)`` writes a
run dir (layout in ``rover_env.training.ppo``); ``train/ppo.py`` and ``train/evaluate.py``
are its command lines.
"""

from __future__ import annotations

from rover_env.training.config import PPOConfig, load_config
from rover_env.training.ppo import TrainResult, train

__all__ = ["PPOConfig", "TrainResult", "load_config", "train"]
