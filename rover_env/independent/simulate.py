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
- The effects that change the build (payload, toe) enter the MJCF through :class:`RoverParams`
  (:func:`built`); a dragging brake is a joint torque on that wheel's hinge (the reaction on
  its segment), next to the motors' in ``qfrc_applied``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

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
NRM = np.array([0.0, 0.0, 1.0])  # the ground's normal


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
    tan_alpha: Array  # (N, 6) tangent of each wheel's slip angle (tire state)
    current: Array  # (N, 4) the driven motors' armature current (A)


def built(p: RoverParams, eff: Effects) -> RoverParams:
    """The rover as built with the effects that change its hardware: a payload on segment 2
    (a fraction of the rover's own mass), the front wheels' toe."""
    return replace(
        p,
        payload_mass=p.payload_mass + eff.payload_fraction * p.total_mass(),
        toe_rad=p.toe_rad + math.radians(eff.toe_deg),
    )


def brake_torque(eff: Effects, omega: Array) -> Array:
    """(6,) the dragging brake's moment on each wheel hinge at wheel rates ``omega``."""
    out = np.zeros(6)
    if eff.brake_torque > 0.0:
        w = eff.brake_wheel
        out[w] = -eff.brake_torque * math.tanh(float(omega[w]) / motor.DRAG_W)
    return out


def _static_height(p: RoverParams, eff: Effects) -> float:
    load = p.total_mass() * 9.81 / 6
    d = float(np.mean(p.wheel_radius))
    if eff.soil is not None:
        s = soil.preset(eff.soil, eff.k_phi_factor)
        return d - soil.static_sinkage(s, d, p.wheel_width, load)
    return d - load / p.c_z


@dataclass(frozen=True)
class _Addr:
    """Where the wheels, joints and logged segment sit in MuJoCo's arrays."""

    wid: NDArray[np.int_]  # wheel bodies
    w_qadr: NDArray[np.int_]  # wheel angles in qpos
    w_dadr: NDArray[np.int_]  # wheel rates in qvel
    j_qadr: NDArray[np.int_]  # the five chain joints in qpos
    drv_qadr: NDArray[np.int_]  # the driven wheels' angles
    drv_dadr: NDArray[np.int_]  # the driven wheels' rates
    seg3: int
    root: int

    @classmethod
    def of(cls, m: mujoco.MjModel) -> _Addr:
        w_qadr = np.array([m.jnt_qposadr[m.joint(f"phi_{w}").id] for w in WHEELS])
        w_dadr = np.array([m.jnt_dofadr[m.joint(f"phi_{w}").id] for w in WHEELS])
        return cls(
            wid=np.array([m.body(f"w{w}").id for w in WHEELS]),
            w_qadr=w_qadr,
            w_dadr=w_dadr,
            j_qadr=np.array([m.jnt_qposadr[m.joint(j).id] for j in JOINTS]),
            drv_qadr=w_qadr[: len(DRIVEN)],
            drv_dadr=w_dadr[: len(DRIVEN)],
            seg3=m.body("seg3").id,
            root=m.body("seg1").id,
        )


class _Command:
    """The targets as the speed loops see them: ``delay`` late, then through the first-order
    lag (exact discretisation at the control rate)."""

    def __init__(self, eff: Effects, t: Array, cmd: Array) -> None:
        self.cmd = cmd
        self.delay = eff.delay
        self.ts = float(t[1] - t[0])
        dt_c = DT * CONTROL_EVERY
        self.lag_a = 1.0 - math.exp(-dt_c / eff.lag_tau) if eff.lag_tau > 0 else 1.0
        self.lagged = np.zeros(4)

    def at(self, now: float) -> Array:
        """The lagged target at log time ``now`` (one call per control period)."""
        n = self.cmd.shape[0]
        td = now - self.delay
        idx = math.floor(td / self.ts + 1e-9) if td >= 0 else -1
        raw = self.cmd[min(idx, n - 1)] if idx >= 0 else np.zeros(4)
        self.lagged = self.lagged + self.lag_a * (raw - self.lagged)
        return self.lagged


@dataclass
class _Contact:
    """Each wheel's contact frame and the carrier's velocity there (one row per wheel)."""

    hub: Array
    axis: Array  # wheel axle
    xc: Array  # contact frame x = axle x normal
    yc: Array  # contact frame y = normal x x
    ground: Array  # contact point
    delta: Array  # compression (flat) or depth below the dug surface (soil)
    depth: Array  # rim depth below z = 0
    vx: Array
    vy: Array
    vn: Array
    vw: Array  # rim speed on the effective rolling radius


class _Ground:
    """The wheels' ground forces, tire (flat ground) or soil, and the state they carry from
    step to step: the tire states, the soil dug by slip, the last normal loads."""

    def __init__(self, p: RoverParams, eff: Effects, addr: _Addr) -> None:
        self.p = p
        self.eff = eff
        self.addr = addr
        self.radius = np.array(p.wheel_radius, dtype=float)
        self.soil_p: soil.Soil | None = None
        if eff.soil is not None:
            base = soil.preset(eff.soil, eff.k_phi_factor)
            self.soil_p = soil.replace(base, c=base.c * eff.friction_scale)
        self.ux = np.zeros(6)
        self.uy = np.zeros(6)
        self.dig = np.zeros(6)
        self.fz_prev = np.zeros(6)
        self.s_travel = np.zeros(6)  # SPEC's S per wheel, as logged
        self.sink = np.zeros(6)  # rim depth below z = 0, as logged

    def contact(self, d: mujoco.MjData) -> _Contact:
        """Lowest rim point in the wheel plane, contact frame, carrier velocity at the ground."""
        a, radius, on_soil = self.addr, self.radius, self.soil_p is not None
        hub = d.xpos[a.wid]
        axis = d.xmat[a.wid].reshape(6, 3, 3)[:, :, 1]
        down = -(NRM[None, :] - (axis @ NRM)[:, None] * axis)
        down /= np.linalg.norm(down, axis=1, keepdims=True)
        rim = hub + radius[:, None] * down
        xc = _cross(axis, np.broadcast_to(NRM, axis.shape))
        xc /= np.linalg.norm(xc, axis=1, keepdims=True)
        yc = _cross(np.broadcast_to(NRM, xc.shape), xc)
        spin = d.qvel[a.w_dadr]
        cv = d.cvel[a.wid]
        ang_w = cv[:, :3]
        ang_c = ang_w - spin[:, None] * axis
        lin_hub = cv[:, 3:] + _cross(ang_w, hub - d.subtree_com[a.root][None, :])
        delta = -rim[:, 2] if not on_soil else (-self.dig) - rim[:, 2]
        ground = hub + (radius - np.clip(delta, 0.0, None))[:, None] * down
        v_c = lin_hub + _cross(ang_c, ground - hub)
        vx = np.einsum("ij,ij->i", v_c, xc)
        vy = np.einsum("ij,ij->i", v_c, yc)
        vn = v_c @ NRM
        # a deflected tire rolls on d - delta/3; a rigid wheel in soil on d (SOIL.md's v_w = r w)
        r_e = (radius if on_soil else tire.rolling_radius(radius, delta)) * self.eff.radius_scale
        vw = r_e * spin
        return _Contact(hub, axis, xc, yc, ground, delta, -rim[:, 2], vx, vy, vn, vw)

    def _tire(self, c: _Contact, travel: Array) -> tuple[Array, Array, Array]:
        """fx, fy, fz of the tire on flat ground (sets the logged slip)."""
        p, eff = self.p, self.eff
        fz = tire.normal_force(c.delta, -c.vn, p.c_z, p.d_z)
        ld = 1.0 - eff.friction_fall * np.tanh(fz / eff.friction_range)
        mux = p.mu_x * eff.friction_scale * ld
        muy = p.mu_y * eff.friction_scale * ld
        fx, fy, self.s_travel = tire.gim_forces(
            self.ux, self.uy, travel, fz, mux, muy, p.c_s, p.c_alpha
        )
        return fx, fy, fz

    def _soil(self, c: _Contact, travel: Array) -> tuple[Array, Array, Array, Array]:
        """fx, fy, fz and axle torque of the wheel in loose soil (sets the logged slip, digs)."""
        assert self.soil_p is not None
        eff = self.eff
        self.s_travel = np.clip(travel * self.ux / tire.SIGMA, -1.0, 1.0)
        s_wong = -self.s_travel
        tan_b = self.uy / tire.SIGMA
        ld = 1.0 - eff.friction_fall * np.tanh(self.fz_prev / eff.friction_range)
        fxs, fy, fzs, tq = soil.wheel_forces(
            self.soil_p,
            self.radius,
            self.p.wheel_width,
            c.delta,
            s_wong,
            tan_b,
            eff.friction_scale * ld,
        )
        fz = np.where(c.delta > 0, np.maximum(fzs - soil.C_SOIL * c.vn, 0.0), 0.0)
        fx = travel * fxs
        torque_axle = -travel * tq
        self.dig = np.maximum(
            self.dig
            + DT
            * (
                soil.DIG * np.maximum(s_wong - soil.S_DIG, 0.0) * np.abs(c.vw)
                - np.abs(c.vx) * self.dig / soil.L_DIG
            ),
            0.0,
        )
        return fx, fy, fz, torque_axle

    def apply(self, d: mujoco.MjData) -> None:
        """Step the ground state and put the wheel forces into ``xfrc_applied`` at the hubs."""
        c = self.contact(d)
        self.sink = c.depth
        self.ux, self.uy = tire.step_states(self.ux, self.uy, c.vx, c.vy, c.vw, DT)
        travel = np.where(c.vx + c.vw >= 0.0, 1.0, -1.0)
        ground = c.ground
        if self.soil_p is None:
            fx, fy, fz = self._tire(c, travel)
            torque_axle = np.zeros(6)
        else:
            fx, fy, fz, torque_axle = self._soil(c, travel)
            ground = c.hub
        if self.eff.c_rr > 0.0:
            lever = self.radius - np.clip(c.delta, 0.0, 0.5 * self.radius)
            torque_axle = torque_axle - self.eff.c_rr * fz * lever * np.tanh(c.vw / RR_SMOOTH)
        self.fz_prev = fz
        force = fx[:, None] * c.xc + fy[:, None] * c.yc + fz[:, None] * NRM[None, :]
        torque = _cross(ground - c.hub, force) + torque_axle[:, None] * c.axis
        d.xfrc_applied[self.addr.wid, :3] = force
        d.xfrc_applied[self.addr.wid, 3:] = torque


class _Log:
    """The true signals at the log's samples, relative to the rover's state at t = 0."""

    def __init__(self, n: int, addr: _Addr) -> None:
        self.addr = addr
        self.phi = np.zeros((n, 6))
        self.theta = np.zeros((n, 5))
        self.pose = np.zeros((n, 3))
        self.slip = np.zeros((n, 6))
        self.omega = np.zeros((n, 6))
        self.sink = np.zeros((n, 6))
        self.tan_alpha = np.zeros((n, 6))
        self.current = np.zeros((n, 4))
        self.phi0 = np.zeros(6)
        self.p30 = np.zeros(3)
        self.r30 = np.eye(3)
        self.yaw_prev = 0.0
        self.yaw_turns = 0.0

    def start(self, d: mujoco.MjData) -> None:
        """t = 0: wheel angles and segment 3's pose from here on."""
        a = self.addr
        self.phi0 = d.qpos[a.w_qadr].copy()
        self.p30 = d.xpos[a.seg3].copy()
        self.r30 = d.xmat[a.seg3].reshape(3, 3).copy()

    def record(self, k: int, d: mujoco.MjData, ground: _Ground, current: Array) -> None:
        a = self.addr
        self.current[k] = current
        self.phi[k] = d.qpos[a.w_qadr] - self.phi0
        self.theta[k] = d.qpos[a.j_qadr]
        rel = self.r30.T @ (d.xpos[a.seg3] - self.p30)
        fwd = self.r30.T @ d.xmat[a.seg3].reshape(3, 3)[:, 0]
        yaw = math.atan2(fwd[1], fwd[0])
        if yaw - self.yaw_prev > math.pi:
            self.yaw_turns -= 2 * math.pi
        elif yaw - self.yaw_prev < -math.pi:
            self.yaw_turns += 2 * math.pi
        self.yaw_prev = yaw
        self.pose[k] = (rel[0], rel[1], yaw + self.yaw_turns)
        self.slip[k] = ground.s_travel
        self.omega[k] = d.qvel[a.w_dadr]
        self.sink[k] = ground.sink
        self.tan_alpha[k] = ground.uy / tire.SIGMA

    def truth(self, t: Array) -> Truth:
        return Truth(
            t=t.copy(),
            phi=self.phi,
            theta=self.theta,
            pose=self.pose,
            slip=self.slip,
            omega=self.omega,
            sink=self.sink,
            tan_alpha=self.tan_alpha,
            current=self.current,
        )


def simulate(
    p: RoverParams, eff: Effects, t: Array, cmd: Array, *, settle: float = SETTLE_S
) -> Truth:
    """Drive the rover with targets ``cmd`` (N, 4), held from ``t[k]`` to ``t[k + 1]``."""
    grav = gravity_vector(eff.slope_deg, eff.slope_heading_deg)
    p = built(p, eff)
    z0 = _static_height(p, eff)
    xml = build_mjcf(p, timestep=DT, gravity=grav, z0=z0, rotor_armature=motor.reflected_inertia())
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    addr = _Addr.of(m)
    drives = motor.Drives.make(p.k_t, p.kp, p.ki, eff.current_limit_scale, eff.supply_scale)
    ground = _Ground(p, eff, addr)
    command = _Command(eff, t, cmd)
    mujoco.mj_forward(m, d)
    drives.reset_counts(d.qpos[addr.drv_qadr])

    n = t.shape[0]
    sample_every = round(command.ts / DT)
    if abs(sample_every * DT - command.ts) > 1e-9:
        raise ValueError(f"sample period {command.ts} is not a multiple of the {DT} s physics step")
    n_settle = round(settle / DT)
    log = _Log(n, addr)
    for step in range(n_settle + (n - 1) * sample_every + 1):
        if step == n_settle:
            log.start(d)
        if step >= n_settle and (step - n_settle) % sample_every == 0:
            k_log = (step - n_settle) // sample_every
            log.record(k_log, d, ground, drives.current(d.qvel[addr.drv_dadr]))
            if k_log == n - 1:
                break
        if step % CONTROL_EVERY == 0:
            target = command.at((step - n_settle) * DT)
            drives.control(target, d.qpos[addr.drv_qadr], DT * CONTROL_EVERY)
        mujoco.mj_step1(m, d)
        ground.apply(d)
        d.qfrc_applied[:] = 0.0
        if eff.brake_torque > 0.0:
            d.qfrc_applied[addr.w_dadr] = brake_torque(eff, d.qvel[addr.w_dadr])
        d.qfrc_applied[addr.drv_dadr] += drives.wheel_torque(d.qvel[addr.drv_dadr])
        mujoco.mj_step2(m, d)
    return log.truth(t)
