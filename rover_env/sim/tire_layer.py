"""The per-substep tire layer: contact geometry, slip kinematics and force application.

On hard ground a wheel gets the Gim–Nikravesh tire forces at its contact point; on loose
soil (:mod:`rover_env.soil`) the terramechanics stresses' resultant at its hub plus the
soil's resistive torque, with the rut map and per-wheel dug depth as state. It is written against MuJoCo ids rather than the rover, so the single-wheel test rig and the
rover share one implementation. Forces go into ``qfrc_applied`` at the contact point, between
``mj_step1`` and ``mj_step2``; the layer owns ``qfrc_applied`` and overwrites it each substep.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np
from numpy.typing import NDArray

from rover_env import soil, tire
from rover_env.effects import TireEffect
from rover_env.rut import RUT_WRITE_EVERY, RutGrid, across_unit
from rover_env.terrain import Terrain
from rover_env.tire import TireParams

Array = NDArray[np.float64]


class TireState(NamedTuple):
    """What the layer computed on its last substep, one entry per wheel."""

    v_x: Array
    v_y: Array
    v_w: Array
    F_x: Array
    F_y: Array
    F_z: Array
    delta: Array
    point: Array
    normal: Array
    patch: NDArray[np.int64]
    sinkage: Array
    """Sinkage below the soil surface the wheel stands on (m; 0 on hard ground)."""
    torque: Array
    """The soil's resistive torque T about the axle (N m; 0 on hard ground)."""
    soil: NDArray[np.int64]
    """0 on hard ground, k on the terrain's soil ``soils[k-1]``."""


def rut_writes(
    terrain: Terrain,
    point: Array,
    xc: Array,
    axis: Array,
    v_x: Array,
    delta: Array,
    sinkage: Array,
    on_soil: NDArray[np.bool_],
    radius: float,
    dt: float,
    memory: Array | None = None,
) -> list[tuple[float, float, float, float, float, float]]:
    """Ruts a substep leaves, as (x, y, across_x, across_y, depth, length): behind each
    moving wheel, on every :data:`~rover_env.rut.RUT_WRITE_EVERY`-th substep (the caller's).

    The depth is that of the wheel's lowest point below the terrain surface, written over
    the wheel's footprint (:meth:`~rover_env.rut.RutGrid.write_footprint`) a little behind
    its contact patch (where it has left the soil, and beyond its own footprint read), so a
    wheel never reads its own rut under it but the wheels behind it run in it. ``memory``
    (per wheel, its soil's :attr:`~rover_env.soil.SoilParams.memory`; None: 1) scales the
    depth; a soil without memory leaves no rut.
    """
    g = terrain.rut_grid
    out: list[tuple[float, float, float, float, float, float]] = []
    keep = np.ones(len(delta)) if memory is None else memory
    ax, ay = across_unit(axis)
    # Only a wheel clearly travelling (beyond the direction blend) leaves a rut: at start-up
    # creep the sign of v_x is noise, and a write "behind" could land ahead of the wheel.
    for i in np.flatnonzero(on_soil & (np.abs(v_x) > soil.V_BLEND) & (delta > 0.0) & (keep > 0.0)):
        h = min(float(sinkage[i]), radius)
        e = 1.0 - h / radius
        length = max(g.cell, 2.0 * abs(float(v_x[i])) * (RUT_WRITE_EVERY * dt))
        back = (radius * np.sqrt(max(0.0, 1.0 - e * e)) + 0.5 * length) + 1.5 * g.cell
        sgn = 1.0 if v_x[i] > 0 else -1.0
        qx = point[i, 0] - sgn * back * xc[i, 0]
        qy = point[i, 1] - sgn * back * xc[i, 1]
        depth = float(keep[i] * delta[i])
        out.append((float(qx), float(qy), float(ax[i]), float(ay[i]), depth, length))
    return out


class TireLayer:
    """Gim–Nikravesh tire forces (transient-slip form) for a set of wheels.

    Args:
        model: compiled model.
        wheel_bodies: body id of each wheel.
        wheel_joints: id of each wheel's hinge (its axis is the spin axis).
        radius: nominal (unloaded) wheel radius d.
        terrain: ground surface and friction map.
        params: tire parameters (Table 3 and the transient-form constants).
        effects: model extensions acting inside the layer (friction hooks, force
            post-processing; :class:`rover_env.effects.TireEffect`). None: the reference layer.
        width: wheel width b (m), for the soil stresses and the rut width.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        wheel_bodies: NDArray[np.int64],
        wheel_joints: NDArray[np.int64],
        radius: float,
        terrain: Terrain,
        params: TireParams,
        effects: Sequence[TireEffect] = (),
        width: float = 0.05,
    ) -> None:
        self.model = model
        self.bodies = np.asarray(wheel_bodies)
        self.joints = np.asarray(wheel_joints)
        self.dofs = model.jnt_dofadr[self.joints]
        self.carriers = model.body_parentid[self.bodies]
        self.roots = model.body_rootid[self.carriers]
        self.radius = radius
        self.terrain = terrain
        # Each soil's memory by soil index (0: hard ground, never written), looked up per substep.
        self._memory = np.array([0.0, *(sp.memory for sp in terrain.soils)])
        self.params = params
        self._lateral_split = bool(np.any(np.asarray(params.lateral_split) != 0.0))
        self.effects = list(effects)
        self.dt = float(model.opt.timestep)
        n = len(self.bodies)
        self.u_x = np.zeros(n)
        self.u_y = np.zeros(n)
        self.width = width
        self.dig = np.zeros(n)
        if terrain.has_soil:
            terrain.rut_grid.samples(width)  # a rut_cell too fine for this wheel: ConfigError
        self.rut = terrain.rut_grid.new_state()
        self.substeps = 0
        """Substeps applied since the reset (the plugin's committed count): ruts are written
        on every RUT_WRITE_EVERY-th."""
        self.last: TireState | None = None

    def reset(self) -> None:
        self.u_x[:] = 0.0
        self.u_y[:] = 0.0
        self.dig[:] = 0.0
        if self.rut.size != self.terrain.rut_grid.state_size:
            self.rut = self.terrain.rut_grid.new_state()
        RutGrid.clear(self.rut, self.terrain.rut_grid.index_size)
        self.substeps = 0
        self.last = None

    def clear_ground_memory(self) -> None:
        """Forget the ruts and dug holes (the soil becomes virgin again); tire states stay."""
        RutGrid.clear(self.rut, self.terrain.rut_grid.index_size)
        self.dig[:] = 0.0

    def apply(self, data: mujoco.MjData) -> None:
        """Compute and apply this substep's tire forces (call after mj_step1)."""
        tp = self.params
        centre = data.xpos[self.bodies]
        axis = data.xaxis[self.joints]
        c = self.terrain.wheel_contact(centre, axis, self.radius)
        nrm = c.normal
        xc = np.cross(axis, nrm)
        xc /= np.linalg.norm(xc, axis=1, keepdims=True)
        yc = np.cross(nrm, xc)
        # Velocity field of each wheel's carrier (its segment), at the contact point and hub.
        cv = data.cvel[self.carriers]
        w, v0 = cv[:, :3], cv[:, 3:]
        ref = data.subtree_com[self.roots]
        v_p = v0 + np.cross(w, c.point - ref)
        v_c = v0 + np.cross(w, centre - ref)
        v_x = np.sum(v_p * xc, axis=1)
        v_y = np.sum(v_p * yc, axis=1)
        # Rolling radius r_e = d - k_re * delta (TireParams; see assets/README.md). The
        # force still acts at the contact point, so the torque arm is the loaded radius.
        r_e = self.radius - tp.k_re * np.maximum(c.delta, 0.0)
        v_w = r_e * data.qvel[self.dofs]
        delta_dot = -np.sum(v_c * nrm, axis=1)
        F_z = tire.normal_force(c.delta, delta_dot, tp)
        mu_x, mu_y, patch = self.terrain.friction(c.point[:, 0], c.point[:, 1])
        for e in self.effects:  # model extensions (none in the reference layer)
            mu_x, mu_y = e.friction(mu_x, mu_y, F_z)
        ux0, uy0 = self.u_x, self.u_y  # the soil branch starts from these
        self.u_x, self.u_y, ux_dot, uy_dot = tire.transient_step(
            self.u_x, self.u_y, v_x, v_y, v_w, F_z, self.dt, tp, mu_x, mu_y
        )
        # eq. (11)'s split (TireParams.lateral_split): off by default, not computed then
        lat = tire.lateral_factor(v_x, v_w, tp) if self._lateral_split else 1.0
        F_x, F_y = tire.transient_forces(
            self.u_x, self.u_y, ux_dot, uy_dot, F_z, tp, mu_x, mu_y, lat_factor=lat
        )
        for e in self.effects:
            F_x, F_y = e.forces(F_x, F_y, F_z, mu_x, mu_y)
        n = len(self.bodies)
        sink = np.zeros(n)
        torque = np.zeros(n)
        where = np.zeros(n, dtype=np.int64)
        at = c.point
        if self.terrain.has_soil:
            where = self.terrain.soil_index(c.point[:, 0], c.point[:, 1])
            on = where > 0
            if on.any():
                at = np.where(on[:, None], centre, c.point)
                v_w = np.where(on, self.radius * data.qvel[self.dofs], v_w)
                g = self.terrain.rut_grid
                rut = g.footprint_depth(self.rut, c.point, axis, self.width)
                for k in np.unique(where[on]):
                    m = where == k
                    sp = self.terrain.soils[k - 1]
                    sgx = sp.sigma if sp.sigma > 0.0 else tp.sigma_x
                    sgy = sp.sigma if sp.sigma > 0.0 else tp.sigma_y
                    st = soil.soil_step(
                        ux0[m], uy0[m], self.dig[m], v_x[m], v_y[m], v_w[m],
                        c.delta[m], delta_dot[m], rut[m], self.dt, sgx, sgy,
                        self.radius, self.width, sp,
                    )  # fmt: skip
                    self.u_x[m], self.u_y[m], self.dig[m] = st.u_x, st.u_y, st.dig
                    F_x[m], F_y[m], F_z[m] = st.F_x, st.F_y, st.F_z
                    sink[m], torque[m] = st.sinkage, st.T
                memory = self._memory[where]
                if self.substeps % RUT_WRITE_EVERY == 0:
                    writes = rut_writes(
                        self.terrain, c.point, xc, axis, v_x, c.delta, sink, on,
                        self.radius, self.dt, memory,
                    )  # fmt: skip
                    for qx, qy, ax, ay, depth, length in writes:
                        g.write_footprint(self.rut, qx, qy, ax, ay, depth, self.width, length)
            self.dig[~on] = 0.0
        force = F_x[:, None] * xc + F_y[:, None] * yc + F_z[:, None] * nrm
        data.qfrc_applied[:] = 0.0
        zero = np.zeros(3)
        for i in range(n):
            mujoco.mj_applyFT(
                self.model,
                data,
                force[i],
                zero if where[i] == 0 else -torque[i] * axis[i],
                at[i],
                int(self.bodies[i]),
                data.qfrc_applied,
            )
        self.last = TireState(
            v_x, v_y, v_w, F_x, F_y, F_z, c.delta, c.point, nrm, patch, sink, torque, where
        )
        self.substeps += 1
