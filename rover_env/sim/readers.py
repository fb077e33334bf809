"""What an environment reads from a rover's MjData arrays, for one simulator or many.

:class:`RoverIndex` reads encoders, potentiometers, gyros, attitude, segment velocities,
driven-wheel slip, loads and sinkage from MjData arrays with any leading axes: one
``RoverSim.data`` or the ``(n, ...)`` arrays bound from a :class:`~rover_env.sim.batch.BatchRoverSim`,
with the same arithmetic, so one rover read either way gives the same bits.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rover_env import tire
from rover_env.config import DRIVEN_WHEELS, JOINTS, WHEELS
from rover_env.sim.fast import PluginView
from rover_env.sim.simulator import RoverSim

__all__ = ["RoverIndex"]

Array = NDArray[np.float64]


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
