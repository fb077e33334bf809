"""rover_env: simulator, Gymnasium environment and calibration toolkit for the Proto-Explorer.

Importing the package registers ``rover_env/ProtoExplorer-v0`` and
``rover_env/ProtoExplorerRough-v0`` with Gymnasium (Gymnasium 1.x has no plugin auto-loading);
``gym.make("rover_env:rover_env/ProtoExplorer-v0")`` imports it for you.

On Linux without a display, ``MUJOCO_GL`` defaults to ``egl`` (headless rendering) unless the
user set it; MuJoCo reads it when first imported, which is why this happens here.
"""

import os as _os
import sys as _sys

if _sys.platform.startswith("linux") and not _os.environ.get("DISPLAY"):
    _os.environ.setdefault("MUJOCO_GL", "egl")

from rover_env.envs.registration import register_envs

__version__ = "0.1.0"
__all__ = ["register_envs"]

register_envs()
