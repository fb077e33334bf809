"""The per-substep tire layer: contact geometry, slip kinematics and force application.

It is written against MuJoCo ids rather than the rover, so the single-wheel test rig and the
rover share one implementation. Forces go into ``qfrc_applied`` at the contact point, between
``mj_step1`` and ``mj_step2``; the layer owns ``qfrc_applied`` and overwrites it each substep.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np
from numpy.typing import NDArray

from rover_env import tire
from rover_env.effects import TireEffect
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
    ) -> None:
        self.model = model
        self.bodies = np.asarray(wheel_bodies)
        self.joints = np.asarray(wheel_joints)
        self.dofs = model.jnt_dofadr[self.joints]
        self.carriers = model.body_parentid[self.bodies]
        self.roots = model.body_rootid[self.carriers]
        self.radius = radius
        self.terrain = terrain
        self.params = params
        self.effects = list(effects)
        self.dt = float(model.opt.timestep)
        n = len(self.bodies)
        self.u_x = np.zeros(n)
        self.u_y = np.zeros(n)
        self.last: TireState | None = None

    def reset(self) -> None:
        self.u_x[:] = 0.0
        self.u_y[:] = 0.0
        self.last = None

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
        self.u_x, self.u_y, ux_dot, uy_dot = tire.transient_step(
            self.u_x, self.u_y, v_x, v_y, v_w, F_z, self.dt, tp, mu_x, mu_y
        )
        F_x, F_y = tire.transient_forces(self.u_x, self.u_y, ux_dot, uy_dot, F_z, tp, mu_x, mu_y)
        for e in self.effects:
            F_x, F_y = e.forces(F_x, F_y, F_z, mu_x, mu_y)
        force = F_x[:, None] * xc + F_y[:, None] * yc + F_z[:, None] * nrm
        data.qfrc_applied[:] = 0.0
        zero = np.zeros(3)
        for i in range(len(self.bodies)):
            mujoco.mj_applyFT(
                self.model,
                data,
                force[i],
                zero,
                c.point[i],
                int(self.bodies[i]),
                data.qfrc_applied,
            )
        self.last = TireState(v_x, v_y, v_w, F_x, F_y, F_z, c.delta, c.point, nrm, patch)
