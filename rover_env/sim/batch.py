"""Many rovers stepped together by ``mujoco.batch`` on a thread pool, tire plugin inside.

Python physics callbacks are refused inside ``mujoco.batch``, so this needs the plugin
backend: the tire layer and the speed-loop setpoints run in C within each ``mj_step``, and
every per-rover quantity (tire deflections, setpoints, last per-wheel outputs) lives in the
simulation's ``plugin_state`` row. Results equal N separate ``RoverSim(backend="plugin")``
runs stepped the same way, at any thread count.

Per-simulation ground (``batch.expand("numeric_data")`` with
:func:`rover_env.sim.fast.terrain_block` rows) is possible but not wrapped here: the
heightfield and obstacles used for chassis contacts would have to follow.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import mujoco.batch
import numpy as np
from numpy.typing import ArrayLike, NDArray

from rover_env import tire
from rover_env.config import DRIVEN_WHEELS, RoverConfig, TerrainConfig
from rover_env.sim.fast import PluginView
from rover_env.sim.simulator import RoverSim, SimulationError, WheelTruth

Array = NDArray[np.float64]

_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION


class BatchRoverSim:
    """``n`` rovers on one terrain, stepped on ``nthread`` threads (0: all CPUs).

    Args:
        n: number of rovers.
        rover: rover configuration, a shipped name or a YAML path.
        terrain: terrain configuration, a shipped name or a YAML path.
        nthread: threads of the batch, the caller's included.
        persistent: keep one MjData per rover (see ``mujoco.batch.Batch``).
    """

    def __init__(
        self,
        n: int,
        rover: RoverConfig | str | Path = "proto_explorer",
        terrain: TerrainConfig | str | Path = "flat",
        nthread: int = 0,
        persistent: bool = False,
    ) -> None:
        if n < 1:
            raise ValueError(f"n must be >= 1, got {n}")
        # One single-rover simulator builds the model and settles each start pose.
        self.template = RoverSim(rover, terrain, backend="plugin")
        self.cfg = self.template.cfg
        self.model = self.template.model
        self.dt = self.template.dt
        self.n = n
        self.batch = mujoco.batch.Batch(self.model, n, nthread, persistent)
        if self.batch.nstate != mujoco.mj_stateSize(self.model, _INTEGRATION):
            raise RuntimeError("mujoco.batch rows are not mjSTATE_INTEGRATION states")
        self._plugin = PluginView(self.model)
        self._ctrl_vel = self.template._ctrl_vel
        self.qpos = self.batch.bind("qpos")
        """(n, nq) live view of the state rows."""
        self.qvel = self.batch.bind("qvel")
        self.ctrl = self.batch.bind("ctrl")
        self.plugin_state = self.batch.bind("plugin_state")
        self._time = self.batch.bind("time")
        self.sensordata = self.batch.bind("sensordata")
        """(n, nsensordata), read-only: refreshed by each call, one substep behind as with mj_step."""
        self.speed_targets = np.zeros((n, len(DRIVEN_WHEELS)))
        self.reset()

    @property
    def time(self) -> Array:
        return self._time.copy()

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

    def step(self, nstep: int = 1) -> None:
        """Advance every rover ``nstep`` physics substeps."""
        self.ctrl[:, self._ctrl_vel] = self.speed_targets
        self.batch.step(nstep=nstep)
        warned = np.flatnonzero(self.batch.warning[..., 0].any(axis=1))
        if warned.size:
            names = [
                mujoco.mjtWarning(int(i)).name
                for i in np.flatnonzero(self.batch.warning[warned[0], :, 0])
            ]
            raise SimulationError(
                f"MuJoCo warning(s) in rover(s) {warned.tolist()}: {', '.join(names)}"
            )
        bad = ~(np.isfinite(self.qpos).all(axis=1) & np.isfinite(self.qvel).all(axis=1))
        if bad.any():
            raise SimulationError(f"non-finite state in rover(s) {np.flatnonzero(bad).tolist()}")

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
        )

    def sensor(self, name: str) -> Array:
        """One sensor's readings for every rover, (n, dim), as of the last call."""
        return np.asarray(self.batch.sensor(name).data).copy()
