"""Gymnasium environments (the only layer that imports gymnasium)."""

from rover_env.envs.registration import ENV_IDS, SOIL_ENV_ID, V1_ENV_IDS, register_envs

__all__ = ["ENV_IDS", "SOIL_ENV_ID", "V1_ENV_IDS", "register_envs"]
