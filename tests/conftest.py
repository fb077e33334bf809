"""Headless rendering: MuJoCo picks its OpenGL backend at import, so choose EGL first."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
