"""Many rovers stepped together by ``mujoco.batch`` on a thread pool, tire plugin inside.

Python physics callbacks are refused inside ``mujoco.batch``, so this needs the plugin
backend: the tire layer and the speed-loop setpoints run in C within each ``mj_step``, and
every per-rover quantity (tire deflections, setpoints, last per-wheel outputs) lives in the
simulation's ``plugin_state`` row. Results equal N separate ``RoverSim(backend="plugin")``
runs stepped the same way, at any thread count.

Per-simulation ground: :meth:`BatchRoverSim.set_models` runs each rover on a model of its
own (``mujoco.batch.Batch.set_models``), for instance copies of a template simulator's model
after :meth:`RoverSim.set_terrain`, which carry the heightfield, the obstacles and the
plugin's terrain block together. :meth:`BatchRoverSim.load` copies a single simulator's
whole state (plugin state included) into rows, so resets can be done by a ``RoverSim``.

:class:`rover_env.sim.readers.RoverIndex` reads what an environment needs from its bound
arrays (and from one ``RoverSim.data``) with the same arithmetic.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import mujoco.batch
import numpy as np
from numpy.typing import ArrayLike, NDArray

from rover_env import tire
from rover_env.config import DRIVEN_WHEELS, RoverConfig, TerrainConfig
from rover_env.rut import check_overflow
from rover_env.sim.fast import PluginView
from rover_env.sim.simulator import RoverSim, SimulationError, WheelTruth

Array = NDArray[np.float64]

_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION


class BatchRoverSim:
    """``n`` rovers, stepped on ``nthread`` threads (0: all CPUs).

    Args:
        n: number of rovers.
        rover: rover configuration, a shipped name or a YAML path.
        terrain: terrain configuration, a shipped name or a YAML path.
        nthread: threads of the batch, the caller's included.
        persistent: keep one MjData per rover (see ``mujoco.batch.Batch``).
        template: a ``RoverSim(backend="plugin")`` to build from instead of ``rover`` and
            ``terrain``; it settles start poses (:meth:`reset`) and its model is the batch's.
        derived: extra MjData fields to bind (``xpos``, ``cvel``, ...), available as
            :meth:`field`; derived fields must be bound before the calls that fill them.
    """

    def __init__(
        self,
        n: int,
        rover: RoverConfig | str | Path = "proto_explorer",
        terrain: TerrainConfig | str | Path = "flat",
        nthread: int = 0,
        persistent: bool = False,
        template: RoverSim | None = None,
        derived: tuple[str, ...] = (),
    ) -> None:
        if n < 1:
            raise ValueError(f"n must be >= 1, got {n}")
        if template is not None and template.backend != "plugin":
            raise ValueError("BatchRoverSim needs a template with backend='plugin'")
        # One single-rover simulator builds the model and settles each start pose.
        self.template = RoverSim(rover, terrain, backend="plugin") if template is None else template
        self.cfg = self.template.cfg
        self.model = self.template.model
        self.dt = self.template.dt
        self.n = n
        self.batch = mujoco.batch.Batch(self.model, n, nthread, persistent)
        if self.batch.nstate != mujoco.mj_stateSize(self.model, _INTEGRATION):
            raise RuntimeError("mujoco.batch rows are not mjSTATE_INTEGRATION states")
        self._plugin = PluginView(self.model)
        self._ctrl_vel = self.template.index.ctrl_vel
        self.qpos = self.batch.bind("qpos")
        """(n, nq) live view of the state rows."""
        self.qvel = self.batch.bind("qvel")
        self.ctrl = self.batch.bind("ctrl")
        self.plugin_state = self.batch.bind("plugin_state")
        self.time_view = self.batch.bind("time")
        """(n,) live view of the rows' simulation times (:attr:`time` is a copy)."""
        self.sensordata = self.batch.bind("sensordata")
        """(n, nsensordata), read-only: refreshed by each call, one substep behind as with mj_step."""
        self._fields = {name: self.batch.bind(name) for name in derived}
        self.speed_targets = np.zeros((n, len(DRIVEN_WHEELS)))
        self.reset()

    def field(self, name: str) -> Array:
        """A bound derived field (given in ``derived``): live ``(n, ...)``, read-only."""
        return self._fields[name]

    def set_models(self, models: list[mujoco.MjModel] | None) -> None:
        """Run rover ``i`` on ``models[i]`` (same sizes as the batch's model), or all on the
        batch's model (None). Call again after editing one of them (``RoverSim.set_terrain``
        on the model's simulator)."""
        self.batch.set_models(models)

    def load(self, ids: ArrayLike, sim: RoverSim, forward: bool = False) -> None:
        """Copy ``sim``'s whole state (time, plugin state, speed targets) into rows ``ids``.

        With ``forward`` the rows' derived fields are recomputed (``mj_forward``); else they
        keep the values of the rows' last call until their next one.
        """
        sel = np.asarray(ids, dtype=np.int64).reshape(-1)
        state = np.empty(self.batch.nstate)
        mujoco.mj_getState(sim.model, sim.data, state, _INTEGRATION)
        self.batch.state[sel] = state
        self.speed_targets[sel] = sim.speed_targets
        if forward:
            self.batch.forward(sel)

    @property
    def time(self) -> Array:
        return self.time_view.copy()

    def reset(
        self,
        ids: ArrayLike | None = None,
        x: ArrayLike = 0.0,
        y: ArrayLike = 0.0,
        yaw: ArrayLike = 0.0,
        settle: float = 0.5,
    ) -> None:
        """Put rovers ``ids`` (default all) at rest at (x, y, yaw), as ``RoverSim.reset`` does.

        x, y, yaw are scalars or one value per reset rover; each distinct pose is settled
        once by the single-rover template and its whole state copied into the rows.
        """
        sel = np.arange(self.n) if ids is None else np.asarray(ids, dtype=np.int64).reshape(-1)
        poses = np.broadcast_to(
            np.stack(np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, yaw))), -1),
            (len(sel), 3),
        )
        settled: dict[tuple[float, float, float], Array] = {}
        sim = self.template
        for row, pose in zip(sel, poses, strict=True):
            key = (float(pose[0]), float(pose[1]), float(pose[2]))
            if key not in settled:
                sim.reset(x=key[0], y=key[1], yaw=key[2], settle=settle)
                state = np.empty(self.batch.nstate)
                mujoco.mj_getState(self.model, sim.data, state, _INTEGRATION)
                settled[key] = state
            self.batch.state[row] = settled[key]
        self.speed_targets[sel] = 0.0
        # Derived fields (sensordata) describe the new state, as after RoverSim.reset.
        self.batch.forward(sel)

    def set_speed_targets(self, targets: ArrayLike) -> None:
        """Speed targets (rad/s) of the driven wheels, shape (n, 4) or (4,) for all rovers."""
        t = np.broadcast_to(np.asarray(targets, dtype=float), self.speed_targets.shape)
        if not np.all(np.isfinite(t)):
            raise ValueError("speed targets must be finite")
        lim = self.cfg.motor.max_wheel_speed
        self.speed_targets[:] = np.clip(t, -lim, lim)
        self.ctrl[:, self._ctrl_vel] = self.speed_targets

    def step(self, nstep: int = 1, ids: ArrayLike | None = None) -> None:
        """Advance rovers ``ids`` (default all) ``nstep`` physics substeps."""
        self.ctrl[:, self._ctrl_vel] = self.speed_targets
        if ids is None:
            self.batch.step(nstep=nstep)
            sel: NDArray[np.int64] | slice = slice(None)
        else:
            sel = np.asarray(ids, dtype=np.int64).reshape(-1)
            if sel.size == 0:
                return
            self.batch.step(sel, nstep=nstep)
        rows = np.arange(self.n)[sel]
        warned = rows[self.batch.warning[sel, :, 0].any(axis=1)]
        if warned.size:
            names = [
                mujoco.mjtWarning(int(i)).name
                for i in np.flatnonzero(self.batch.warning[warned[0], :, 0])
            ]
            raise SimulationError(
                f"MuJoCo warning(s) in rover(s) {warned.tolist()}: {', '.join(names)}"
            )
        q, v = self.qpos[sel], self.qvel[sel]
        bad = ~(np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1))
        if bad.any():
            raise SimulationError(f"non-finite state in rover(s) {rows[bad].tolist()}")
        pv = self._plugin
        if pv.layout.rut_state:  # one number per rover: the writes a full rut pool refused
            col = pv.slice.start + pv.layout.rut.start + 1
            check_overflow(float(np.max(self.batch.plugin_state[sel, col])))

    def wheel_truth(self) -> WheelTruth:
        """Per-wheel truth of the last substep, arrays with a leading rover axis (n, 6, ...)."""
        pv = self._plugin
        if (pv.nstep(self.plugin_state) <= 0).any():
            raise RuntimeError("wheel_truth() needs at least one physics substep")
        ts = pv.truth(self.plugin_state)
        eps = self.cfg.tire.v_eps
        S = tire.slip_ratio(ts.v_x, ts.v_w, eps)
        return WheelTruth(
            S=S,
            S_alpha=tire.lateral_slip(ts.v_x, ts.v_y, ts.v_w, S, eps),
            F_x=ts.F_x,
            F_y=ts.F_y,
            F_z=ts.F_z,
            delta=ts.delta,
            v_x=ts.v_x,
            v_y=ts.v_y,
            v_w=ts.v_w,
            contact_point=ts.point,
            patch=ts.patch,
            sinkage=ts.sinkage,
            soil=ts.soil,
        )

    def sensor(self, name: str) -> Array:
        """One sensor's readings for every rover, (n, dim), as of the last call."""
        return np.asarray(self.batch.sensor(name).data).copy()
