"""Moved to :mod:`rover_env.policies.ppo` (issue 17); re-exported for old imports."""

from rover_env.policies.ppo import PPOController, resolve_model_path

__all__ = ["PPOController", "resolve_model_path"]
