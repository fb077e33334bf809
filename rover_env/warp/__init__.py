"""GPU path: the rover on MuJoCo Warp with the tire layer as Warp kernels (docs/gpu.md).

Needs the ``gpu`` extra (``pip install -e ".[gpu]"``: mujoco-warp, which brings warp-lang).
:mod:`rover_env.warp.sim` is the simulation; :mod:`rover_env.warp.env` (torch),
:mod:`rover_env.warp.ppo` and :mod:`rover_env.warp.bench` build on it.
"""
