"""rover_env: simulator, Gymnasium environment and calibration toolkit for the Proto-Explorer.

Importing the package registers ``rover_env/ProtoExplorer-v0`` and
``rover_env/ProtoExplorerRough-v0`` with Gymnasium (Gymnasium 1.x has no plugin auto-loading);
``gym.make("rover_env:rover_env/ProtoExplorer-v0")`` imports it for you.
"""

from rover_env.envs.registration import register_envs

__version__ = "0.1.0"
__all__ = ["register_envs"]

register_envs()
