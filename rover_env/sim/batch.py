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

:class:`RoverIndex` reads what an environment needs (encoders, potentiometers, gyros,
segment velocities, driven-wheel slip) from MjData arrays with any leading axes: one
``RoverSim.data`` or the ``(n, ...)`` arrays bound from the batch, with the same arithmetic.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import mujoco.batch
import numpy as np
from numpy.typing import ArrayLike, NDArray

from rover_env import tire
from rover_env.config import DRIVEN_WHEELS, JOINTS, WHEELS, RoverConfig, TerrainConfig
from rover_env.rut import check_overflow
from rover_env.sim.fast import PluginView
from rover_env.sim.simulator import RoverSim, SimulationError, WheelTruth

Array = NDArray[np.float64]

_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION


class RoverIndex:
    """Where a compiled rover model keeps what is read from it; reads arrays of any leading shape.

    Every reader takes MjData fields as arrays whose last axes are MjData's (``data.sensordata``
    of one ``RoverSim``, or ``(n, nsensordata)`` bound from a batch) and repeats the
    simulator's arithmetic operation by operation, so one rover read either way gives the
    same bits.
    """

    def __init__(self, sim: RoverSim) -> None:
        m = sim.model
        ix = sim.index
        self.seg_body = ix.seg_body.copy()
        self.seg_root = ix.seg_root.copy()
        self.driven_dof = ix.driven_dof.copy()
        s = ix.sensor
        self.phi = np.array([s[f"phi_{w}"].start for w in WHEELS])
        self.theta = np.array([s[j].start for j in JOINTS])
        self.gyro = np.concatenate(
            [np.arange(s[f"imu_seg{i}_gyro"].start, s[f"imu_seg{i}_gyro"].stop) for i in (1, 2, 3)]
        )
        self.n_driven = len(DRIVEN_WHEELS)
        self.v_eps = sim.cfg.tire.v_eps
        self.plugin = PluginView(m) if sim.backend == "plugin" else None
        self.max_tilt_cos = float(np.cos(np.radians(75.0)))

    def phi_theta(self, sensordata: Array) -> tuple[Array, Array]:
        """Wheel angles (..., 6) and joint angles (..., 5), as ``RoverSim.sensors()``."""
        return sensordata[..., self.phi], sensordata[..., self.theta]

    def gyro_rates(self, sensordata: Array) -> Array:
        """IMU angular rates (..., 3, 3) [segment, xyz]."""
        g = sensordata[..., self.gyro]
        return g.reshape(*g.shape[:-1], 3, 3)

    def gravity(self, xmat: Array) -> Array:
        """World -z in each segment's axes (..., 3, 3): the IMUs' attitude."""
        rows = xmat[..., self.seg_body, 6:9]
        return -rows

    def segment_velocity(
        self, cvel: Array, xipos: Array, ximat: Array, subtree_com: Array, seg: int = 1
    ) -> tuple[Array, Array]:
        """Forward speed and yaw rate of segment ``seg`` in its own axes (…), as
        ``RoverSim.segment_truth()`` (``mj_objectVelocity`` with ``flg_local``; same operations)."""
        b = int(self.seg_body[seg])
        cv = cvel[..., b, :]
        w0, w1, w2 = cv[..., 0], cv[..., 1], cv[..., 2]
        com = subtree_com[..., int(self.seg_root[seg]), :]
        p = xipos[..., b, :]
        d0, d1, d2 = p[..., 0] - com[..., 0], p[..., 1] - com[..., 1], p[..., 2] - com[..., 2]
        # mju_transformSpatial: lin - dif x ang, then rotated into the body's axes.
        t0 = cv[..., 3] - (d1 * w2 - d2 * w1)
        t1 = cv[..., 4] - (d2 * w0 - d0 * w2)
        t2 = cv[..., 5] - (d0 * w1 - d1 * w0)
        r = ximat[..., b, :]
        forward = r[..., 0] * t0 + r[..., 3] * t1 + r[..., 6] * t2
        yaw_rate = r[..., 2] * w0 + r[..., 5] * w1 + r[..., 8] * w2
        return forward, yaw_rate

    def flipped(self, xmat: Array) -> NDArray[np.bool_]:
        """``RoverSim.flipped()`` (75 deg) over the leading axes."""
        return np.asarray(np.any(xmat[..., self.seg_body, 8] < self.max_tilt_cos, axis=-1))

    def _truth_part(self, plugin_state: Array, i: int, width: int = 1) -> Array:
        pv = self.plugin
        assert pv is not None, "needs the plugin backend"
        nw = pv.layout.nw
        start = pv.slice.start + pv.layout.truth + i * nw
        return plugin_state[..., start : start + width * nw]

    def driven_slip(self, plugin_state: Array) -> Array:
        """True slip ratio S of the driven wheels (..., 4) from the last committed substep."""
        nd = self.n_driven
        v_x = self._truth_part(plugin_state, 0)[..., :nd]
        v_w = self._truth_part(plugin_state, 2)[..., :nd]
        return tire.slip_ratio(v_x, v_w, self.v_eps)

    def wheel_sinkage(self, plugin_state: Array) -> Array:
        """Sinkage into loose soil (..., 6) of every wheel, 0 on hard ground (a copy)."""
        return self._truth_part(plugin_state, 14).copy()

    def wheel_load(self, plugin_state: Array) -> tuple[Array, Array]:
        """Normal force (..., 6) and contact point (..., 6, 3) of every wheel (copies)."""
        f_z = self._truth_part(plugin_state, 5).copy()
        pt = self._truth_part(plugin_state, 7, 3).copy()
        return f_z, pt.reshape(*pt.shape[:-1], -1, 3)


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
