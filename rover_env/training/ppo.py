"""Moved to :mod:`rover_env.training.run` (PPO, SAC, TD3); re-exported for old imports."""

from rover_env.training.run import RUN_FILES, TrainResult, train

__all__ = ["RUN_FILES", "TrainResult", "train"]
