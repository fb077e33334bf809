"""Gymnasium environments (the only layer that imports gymnasium)."""

from rover_env.envs.registration import ENV_IDS, SOIL_ENV_ID, register_envs

__all__ = ["ENV_IDS", "SOIL_ENV_ID", "register_envs"]
