"""The independent simulator: MuJoCo for the rigid chain, everything at the ground and in the
drives from this package, stepped with a ``mj_step1`` / forces / ``mj_step2`` split.

- Physics step 2 ms, MuJoCo's ``implicitfast`` integrator (joint springs/dampers implicit); the
  wheel forces of :mod:`tire` / :mod:`soil` enter through ``xfrc_applied`` at each wheel's hub
  (the contact force moved there with its moment), the motor torques through ``qfrc_applied``.
- Contact: the ground is the plane z = 0 (a slope tilts gravity). Each wheel's lowest rim point
  is found in the wheel plane; compression ``delta`` is its depth below the plane, the contact
  frame is x = axle x normal, y = normal x x.
- Carrier velocity at the contact point: the hub's velocity plus the segment's (not the wheel's)
  angular velocity crossed with the lever to the ground point.
- Speed loops at 250 Hz (every second step); the motor current every step.
- The rover is put down at its static height and settles for one second with zero targets
  before the log's t = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

import rover_env.independent.motor as motor
import rover_env.independent.soil as soil
import rover_env.independent.tire as tire
from rover_env.independent.effects import Effects
from rover_env.independent.model import (
    DRIVEN,
    JOINTS,
    WHEELS,
    RoverParams,
    build_mjcf,
    gravity_vector,
)

Array = NDArray[np.float64]

DT = 0.002
CONTROL_EVERY = 2  # 250 Hz
SETTLE_S = 1.0
RR_SMOOTH = 0.01  # m/s of rim speed over which the rolling-resistance moment builds up


def _cross(a: Array, b: Array) -> Array:
    """Row-wise cross product of (W, 3) arrays (np.cross's overhead dominates at six rows)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


@dataclass
class Truth:
    """True signals at the log's sample times."""

    t: Array
    phi: Array  # (N, 6) wheel angles since t = 0
    theta: Array  # (N, 5)
    pose: Array  # (N, 3) segment 3 in its frame at t = 0
    slip: Array  # (N, 6) SPEC's S per wheel (tire state)
    omega: Array  # (N, 6) wheel rates
    sink: Array  # (N, 6) tire compression (flat) or sinkage below the undisturbed surface (soil)


def _static_height(p: RoverParams, eff: Effects) -> float:
    load = p.total_mass() * 9.81 / 6
    d = float(np.mean(p.wheel_radius))
    if eff.soil is not None:
        s = soil.preset(eff.soil, eff.k_phi_factor)
        return d - soil.static_sinkage(s, d, p.wheel_width, load)
    return d - load / p.c_z


def simulate(
    p: RoverParams, eff: Effects, t: Array, cmd: Array, *, settle: float = SETTLE_S
) -> Truth:
    """Drive the rover with targets ``cmd`` (N, 4), held from ``t[k]`` to ``t[k + 1]``."""
    grav = gravity_vector(eff.slope_deg, eff.slope_heading_deg)
    z0 = _static_height(p, eff)
    xml = build_mjcf(p, timestep=DT, gravity=grav, z0=z0, rotor_armature=motor.reflected_inertia())
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)

    wid = np.array([m.body(f"w{w}").id for w in WHEELS])
    w_qadr = np.array([m.jnt_qposadr[m.joint(f"phi_{w}").id] for w in WHEELS])
    w_dadr = np.array([m.jnt_dofadr[m.joint(f"phi_{w}").id] for w in WHEELS])
    j_qadr = np.array([m.jnt_qposadr[m.joint(j).id] for j in JOINTS])
    drv_dadr = w_dadr[: len(DRIVEN)]
    drv_qadr = w_qadr[: len(DRIVEN)]
    seg3 = m.body("seg3").id
    root = m.body("seg1").id

    radius = np.array(p.wheel_radius, dtype=float)
    nrm = np.array([0.0, 0.0, 1.0])
    drives = motor.Drives.make(p.k_t, p.kp, p.ki, eff.current_limit_scale)
    on_soil = eff.soil is not None
    soil_p = None
    if on_soil:
        assert eff.soil is not None
        base = soil.preset(eff.soil, eff.k_phi_factor)
        soil_p = soil.replace(base, c=base.c * eff.friction_scale)
    ux = np.zeros(6)
    uy = np.zeros(6)
    dig = np.zeros(6)
    lagged = np.zeros(4)
    dt_c = DT * CONTROL_EVERY
    lag_a = 1.0 - math.exp(-dt_c / eff.lag_tau) if eff.lag_tau > 0 else 1.0
    mujoco.mj_forward(m, d)
    drives.reset_counts(d.qpos[drv_qadr])

    n = t.shape[0]
    ts = float(t[1] - t[0])
    sample_every = round(ts / DT)
    if abs(sample_every * DT - ts) > 1e-9:
        raise ValueError(f"sample period {ts} is not a multiple of the {DT} s physics step")
    n_settle = round(settle / DT)
    total = n_settle + (n - 1) * sample_every
    out_phi = np.zeros((n, 6))
    out_theta = np.zeros((n, 5))
    out_pose = np.zeros((n, 3))
    out_slip = np.zeros((n, 6))
    out_omega = np.zeros((n, 6))
    out_sink = np.zeros((n, 6))
    sink_now = np.zeros(6)
    phi0 = np.zeros(6)
    p30 = np.zeros(3)
    r30 = np.eye(3)
    yaw_prev = 0.0
    yaw_turns = 0.0
    s_travel = np.zeros(6)
    fz_prev = np.zeros(6)

    def record(k: int) -> None:
        nonlocal yaw_prev, yaw_turns
        out_phi[k] = d.qpos[w_qadr] - phi0
        out_theta[k] = d.qpos[j_qadr]
        rel = r30.T @ (d.xpos[seg3] - p30)
        fwd = r30.T @ d.xmat[seg3].reshape(3, 3)[:, 0]
        yaw = math.atan2(fwd[1], fwd[0])
        if yaw - yaw_prev > math.pi:
            yaw_turns -= 2 * math.pi
        elif yaw - yaw_prev < -math.pi:
            yaw_turns += 2 * math.pi
        yaw_prev = yaw
        out_pose[k] = (rel[0], rel[1], yaw + yaw_turns)
        out_slip[k] = s_travel
        out_omega[k] = d.qvel[w_dadr]
        out_sink[k] = sink_now

    for step in range(total + 1):
        k_log = (step - n_settle) // sample_every if step >= n_settle else -1
        if step == n_settle:
            phi0 = d.qpos[w_qadr].copy()
            p30 = d.xpos[seg3].copy()
            r30 = d.xmat[seg3].reshape(3, 3).copy()
        if step >= n_settle and (step - n_settle) % sample_every == 0:
            record(k_log)
            if k_log == n - 1:
                break
        if step % CONTROL_EVERY == 0:
            now = (step - n_settle) * DT
            td = now - eff.delay
            idx = math.floor(td / ts + 1e-9) if td >= 0 else -1
            raw = cmd[min(idx, n - 1)] if idx >= 0 else np.zeros(4)
            lagged = lagged + lag_a * (raw - lagged)
            drives.control(lagged, d.qpos[drv_qadr], dt_c)

        mujoco.mj_step1(m, d)
        # ---- wheel-ground forces
        hub = d.xpos[wid]
        axis = d.xmat[wid].reshape(6, 3, 3)[:, :, 1]
        down = -(nrm[None, :] - (axis @ nrm)[:, None] * axis)
        down /= np.linalg.norm(down, axis=1, keepdims=True)
        rim = hub + radius[:, None] * down
        xc = _cross(axis, np.broadcast_to(nrm, axis.shape))
        xc /= np.linalg.norm(xc, axis=1, keepdims=True)
        yc = _cross(np.broadcast_to(nrm, xc.shape), xc)
        spin = d.qvel[w_dadr]
        cv = d.cvel[wid]
        ang_w = cv[:, :3]
        ang_c = ang_w - spin[:, None] * axis
        lin_hub = cv[:, 3:] + _cross(ang_w, hub - d.subtree_com[root][None, :])
        delta = -rim[:, 2] if not on_soil else (-dig) - rim[:, 2]
        sink_now = -rim[:, 2]
        ground = hub + (radius - np.clip(delta, 0.0, None))[:, None] * down
        v_c = lin_hub + _cross(ang_c, ground - hub)
        vx = np.einsum("ij,ij->i", v_c, xc)
        vy = np.einsum("ij,ij->i", v_c, yc)
        vn = v_c @ nrm
        # a deflected tire rolls on d - delta/3; a rigid wheel in soil on d (SOIL.md's v_w = r w)
        r_e = (radius if on_soil else tire.rolling_radius(radius, delta)) * eff.radius_scale
        vw = r_e * spin
        ux, uy = tire.step_states(ux, uy, vx, vy, vw, DT)
        travel = np.where(vx + vw >= 0.0, 1.0, -1.0)
        torque_axle = np.zeros(6)
        if not on_soil:
            fz = tire.normal_force(delta, -vn, p.c_z, p.d_z)
            ld = 1.0 - eff.friction_fall * np.tanh(fz / eff.friction_range)
            mux = p.mu_x * eff.friction_scale * ld
            muy = p.mu_y * eff.friction_scale * ld
            fx, fy, s_travel = tire.gim_forces(ux, uy, travel, fz, mux, muy, p.c_s, p.c_alpha)
        else:
            assert soil_p is not None
            s_travel = np.clip(travel * ux / tire.SIGMA, -1.0, 1.0)
            s_wong = -s_travel
            tan_b = uy / tire.SIGMA
            ld = 1.0 - eff.friction_fall * np.tanh(fz_prev / eff.friction_range)
            fxs, fy, fzs, tq = soil.wheel_forces(
                soil_p, radius, p.wheel_width, delta, s_wong, tan_b, eff.friction_scale * ld
            )
            fz = np.where(delta > 0, np.maximum(fzs - soil.C_SOIL * vn, 0.0), 0.0)
            fx = travel * fxs
            torque_axle = -travel * tq
            ground = hub
            dig = np.maximum(
                dig
                + DT
                * (
                    soil.DIG * np.maximum(s_wong - soil.S_DIG, 0.0) * np.abs(vw)
                    - np.abs(vx) * dig / soil.L_DIG
                ),
                0.0,
            )
        if eff.c_rr > 0.0:
            lever = radius - np.clip(delta, 0.0, 0.5 * radius)
            torque_axle = torque_axle - eff.c_rr * fz * lever * np.tanh(vw / RR_SMOOTH)
        fz_prev = fz
        force = fx[:, None] * xc + fy[:, None] * yc + fz[:, None] * nrm[None, :]
        torque = _cross(ground - hub, force) + torque_axle[:, None] * axis
        d.xfrc_applied[wid, :3] = force
        d.xfrc_applied[wid, 3:] = torque
        d.qfrc_applied[:] = 0.0
        d.qfrc_applied[drv_dadr] = drives.wheel_torque(d.qvel[drv_dadr])
        mujoco.mj_step2(m, d)
    return Truth(
        t=t.copy(),
        phi=out_phi,
        theta=out_theta,
        pose=out_pose,
        slip=out_slip,
        omega=out_omega,
        sink=out_sink,
    )
