"""Fast path of the per-substep tire layer: a MuJoCo engine plugin written in C.

``RoverSim(backend="plugin")`` and :class:`rover_env.sim.batch.BatchRoverSim` use it; the
numpy :class:`~rover_env.sim.tire_layer.TireLayer` stays the reference, and the plugin
(``tire_plugin.c``) repeats its arithmetic operation by operation. On this machine its
per-wheel outputs and generalized forces are bit-identical to the numpy layer's on random
states; trajectories differ at the 1e-16 level only because MuJoCo sums ``qfrc_passive``
(where a passive plugin adds) and ``qfrc_applied`` (where the numpy layer writes) in a
different order. numpy's ``expm1`` may use SVML on AVX-512 machines and differ from libm's
by an ulp; the tests' 1e-12 tolerances leave room for that.

Why it can run with no Python per substep (verified against MuJoCo 4.0.0):

* A passive plugin's ``compute`` runs in ``mj_passive``, called by ``mj_fwdVelocity`` after
  ``mj_comVel`` (so ``xpos``, ``xaxis``, ``subtree_com``, ``cdof`` and ``cvel`` are current)
  and before ``mj_fwdActuation`` reads ``ctrl``. The plugin therefore integrates the dcmotor
  position setpoints there and writes them to ``ctrl[pos]``; the actuators use them in the
  same ``mj_forward``. ``tests/test_fast.py::test_setpoints_are_written_before_actuation``
  checks this ordering on the installed MuJoCo.
* ``compute`` is a pure function of the state: it reads the *committed* tire deflections
  and setpoints from ``plugin_state``, writes its results to a *pending* block, and the
  plugin's ``advance`` (called from ``mj_advance`` after integration) commits them. Extra
  ``mj_forward`` calls (rendering, resets, ``Batch.forward``) leave the state alone, as
  they do with the numpy layer, which only runs inside ``RoverSim.step``.
* In this backend the setpoints are plugin state: write them with
  :meth:`PluginView.set_setpoints`; ``ctrl[pos]`` is overwritten on every ``mj_forward``.
  The speed targets stay in ``ctrl[vel]``; a command effect's per-substep targets are
  queued in the state instead (:meth:`PluginView.queue_commands`), and the plugin writes
  each to ``ctrl[vel]`` in its substep, so one ``mj_step`` call runs them all.
* Everything per rover lives in ``plugin_state`` (layout in ``tire_plugin.c`` and
  :class:`StateLayout`), so copies of MjData, ``mj_getState``/``mj_setState`` and
  ``mujoco.batch`` rows carry it; the plugin's ``plugin_data`` is only its parsed
  configuration plus scratch memory.

The library is compiled on first use (:mod:`rover_env.sim.fast.build`); the ground is a
``<numeric>`` block the plugin reads every substep, so it can change at run time
(:mod:`rover_env.sim.fast.plugin`).
"""

from rover_env.sim.fast.build import (
    MUJOCO_VERSION,
    PLUGIN_NAME,
    FastBackendError,
    cache_dir,
    compile_plugin,
    load_plugin,
)
from rover_env.sim.fast.plugin import (
    INSTANCE,
    TERRAIN_NUMERIC,
    PluginView,
    StateLayout,
    TruthArrays,
    inject_plugin,
    terrain_block,
)

__all__ = [
    "INSTANCE",
    "MUJOCO_VERSION",
    "PLUGIN_NAME",
    "TERRAIN_NUMERIC",
    "FastBackendError",
    "PluginView",
    "StateLayout",
    "TruthArrays",
    "cache_dir",
    "compile_plugin",
    "inject_plugin",
    "load_plugin",
    "terrain_block",
]
