"""A second, deliberately different log generator: the same rover, another implementation.

``diagnose`` must hold on logs from an implementation it was not built with (issue 16): its
own contact and tire code, speed loop, integrator, step and sensors, with the same physical
numbers (the rover configuration) and the same effect definitions. Logs written by
:func:`make_foreign_logs` (``rover-env make-logs --generator foreign``) are SPEC §6 logs
naming the nominal rover, with the truth in ``truth.yaml``, exactly as ``make-logs``.

What differs from the project's simulator (``rover_env.sim``), on purpose:

* tire: steady-state Gim (eqs. 10-16, no relaxation: forces follow the slip instantly),
  slip regularised below ``V_EPS`` = 5 cm/s instead of the transient-slip states; the
  wheel spin is advanced semi-implicitly through the longitudinal force (a per-wheel
  scalar solve), which steady-state slip needs to stay stable on a light free wheel;
  contact geometry written here for flat ground (lowest point of the wheel disc);
* motor: a discrete PI speed loop at ``CONTROL_HZ`` (250 Hz, zero-order hold) giving
  torque directly (a plain ``motor`` actuator), anti-windup by conditional integration,
  torque bounded by the DC motor's line stall (1 - |w| / w_0) and the driver's limit,
  instead of the dcmotor actuator with an integrated angle setpoint every substep;
* integrator and step: semi-implicit Euler at 0.8 ms (the project: implicitfast, 1 ms);
* sensors: 2048-count wheel encoders (3.1 mrad), 12-bit potentiometers over 300° with
  0.6 mrad noise, pose at 1 Hz with 3 mm / 3 mrad noise;
* effects, each implemented from its definition here: rolling resistance as the forward
  offset c_rr (d - delta) of the normal force (a moment c_rr F_z (d - delta) opposing the
  spin, smoothed over ``W_RR``), slope as tilted gravity, rolling radius
  r_e = d - k_re delta + fraction d delta / delta_0, friction, load-dependent friction and
  the friction ellipse on mu, torque limit on the PI's output, lag and delay on the PI's
  input at the control rate (the delay quantised to 4 ms, not 1 ms);
* loose soil (``loose_soil``): SOIL.md's equations in this package's own quadrature on a
  rigid wheel whose sinkage is its penetration of the flat surface, with no sinkage state,
  dug hole or ruts (:mod:`rover_env.generators.foreign_soil`); the soil constants are the
  effect's (:func:`rover_env.sim.build.effect_soil`). On soil the tire's effects
  (rolling resistance, rolling radius, friction and its load dependence, the ellipse) do
  not act, as in the project's simulator, where the soil replaces the tire.

Only flat ground; the MJCF bodies, joints and springs are the configuration's (the same
physical rover), the actuators are replaced.
"""

from __future__ import annotations

import math
import re
from collections import deque
from dataclasses import replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import yaml
from numpy.typing import NDArray

from rover_env.config import JOINTS, WHEELS, ConfigError, RoverConfig, load_rover, to_dict
from rover_env.effects import build_effects
from rover_env.generators import foreign_soil
from rover_env.generators.drives import drive_schedule
from rover_env.logs import DriveLog, LogMeta, write_log
from rover_env.sim.build import effect_soil
from rover_env.sim.model import scene_xml

Array = NDArray[np.float64]

DT = 0.0008
CONTROL_HZ = 250.0
V_EPS = 0.05
"""Slip regularisation speed (m/s) of the steady-state tire."""
W_RR = 0.3
"""Spin rate (rad/s) over which the rolling-resistance moment turns on (tanh)."""
ENCODER_COUNTS = 2048
POT_BITS = 12
POT_TRAVEL = math.radians(300.0)
POT_NOISE = 6e-4
POSE_NOISE_M = 0.003
POSE_NOISE_YAW = 0.003


def lateral_slip(v_x: Array, v_y: Array, v_w: Array) -> Array:
    """Eq. (11), written here: |tan alpha| when the wheel skids, (1 - |S|) |tan alpha| =
    |v_y| / |v_w| when it spins; so |v_y| over the larger of |v_x| and |v_w|, regularised
    below ``V_EPS``. (Until stop 23 this used |v_x| alone, which is not eq. (11) when a
    wheel spins: diagnose then read friction +6 % as 0 or less on these logs.)"""
    den = np.maximum(np.maximum(np.abs(v_x), np.abs(v_w)), V_EPS)
    return np.asarray(np.abs(v_y) / den, dtype=np.float64)


def _quantise(x: Array, lsb: float) -> Array:
    return np.asarray(np.round(x / lsb) * lsb, dtype=np.float64)


class ForeignRover:
    """The rover as another team might simulate it (see the module docstring)."""

    def __init__(
        self,
        cfg: RoverConfig,
        extensions: dict[str, dict[str, float]],
        control_hz: float = CONTROL_HZ,
    ) -> None:
        per = 1.0 / (control_hz * DT) if control_hz > 0 else 0.0
        if not (per >= 1 - 1e-9 and abs(per - round(per)) < 1e-6):
            raise ConfigError(
                f"control_hz {control_hz!r}: the speed loop's period must be a whole number"
                f" of the {DT * 1e3:g} ms steps (e.g. 250 or 1250 Hz)"
            )
        self.control_hz = float(control_hz)
        self.cfg = cfg
        eff = {e.name: e for e in build_effects(extensions) if not e.is_off}
        self.ext = eff
        xml = scene_xml(replace(cfg, extensions={}), _flat())
        # Own actuators: plain torque motors driven by this module's PI loop.
        xml = re.sub(r"<dcmotor nominal=[^>]*/>", "", xml)
        xml = re.sub(
            r'<dcmotor name="(motor_\w+)" class="motor" joint="(wheel_\w+)"/>',
            r'<motor name="\1" joint="\2" gear="1"/>',
            xml,
        )
        xml = xml.replace('integrator="implicitfast"', 'integrator="Euler"')
        xml = re.sub(r'timestep="[^"]*"', f'timestep="{DT}"', xml, count=1)
        m = mujoco.MjModel.from_xml_string(xml)
        self.model, self.data = m, mujoco.MjData(m)
        self.wheel_body = np.array([m.body(f"wheel_{w}").id for w in WHEELS])
        self.wheel_jnt = np.array([m.joint(f"wheel_{w}").id for w in WHEELS])
        self.wheel_dof = m.jnt_dofadr[self.wheel_jnt]
        self.wheel_qpos = m.jnt_qposadr[self.wheel_jnt]
        self.carrier = m.body_parentid[self.wheel_body]
        self.root = int(m.body_rootid[self.wheel_body[0]])
        self.joint_qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in JOINTS])
        self.seg3 = m.body("seg3").id
        mo = cfg.motor
        m.dof_armature[self.wheel_dof[:4]] = mo.armature
        self.inertia = m.body_inertia[self.wheel_body, 1] + m.dof_armature[self.wheel_dof]
        tp = cfg.tire
        f_mu = 1.0 + (eff["friction"]["fraction"] if "friction" in eff else 0.0)
        self.mu_x, self.mu_y = tp.mu_x * f_mu, tp.mu_y * f_mu
        self.fz0 = cfg.masses.total * 9.81 / 6
        self.delta0 = self.fz0 / tp.C_z
        self.rr_frac = eff["rolling_radius"]["fraction"] if "rolling_radius" in eff else 0.0
        self.c_rr = eff["rolling_resistance"]["c_rr"] if "rolling_resistance" in eff else 0.0
        tl = eff["torque_limit"]["fraction"] if "torque_limit" in eff else 0.0
        self.tau_max = mo.torque_limit * (1.0 + tl)
        self.ellipse = "combined_slip" in eff
        self.fall = (
            eff["load_dependent_friction"]["fall"] if "load_dependent_friction" in eff else 0
        )
        self.fall_range = (
            eff["load_dependent_friction"]["range"] if "load_dependent_friction" in eff else 0.1
        )
        self.tau_lag = eff["command_lag"]["tau"] if "command_lag" in eff else 0.0
        self.delay_n = (
            round(eff["command_delay"]["delay"] * control_hz) if "command_delay" in eff else 0
        )
        if "slope" in eff:
            th = math.radians(eff["slope"]["deg"])
            ps = math.radians(eff["slope"]["heading_deg"])
            g = 9.81
            m.opt.gravity[:] = (
                -g * math.sin(th) * math.cos(ps),
                -g * math.sin(th) * math.sin(ps),
                -g * math.cos(th),
            )
        self.soil = effect_soil(_flat(), list(eff.values()))
        self.per_control = round(per)
        self.integ = np.zeros(4)
        self.lagged = np.zeros(4)
        self.queue: deque[Array] = deque()
        self.torque = np.zeros(4)
        self.reset()

    def reset(self) -> None:
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[2] = self.cfg.geometry.wheel_radius - self.delta0
        mujoco.mj_forward(m, d)
        self.integ[:] = 0.0
        self.lagged[:] = 0.0
        self.queue = deque(np.zeros(4) for _ in range(self.delay_n))
        self.torque[:] = 0.0
        # Settle on the ground; a rover on soil sinks more slowly (soft support).
        self.run(np.zeros(4), 0.6 if self.soil is None else 1.5)
        d.time = 0.0
        d.qpos[self.wheel_qpos] = 0.0
        mujoco.mj_forward(m, d)

    # ------------------------------------------------------------------ speed loop
    def _control(self, target: Array) -> None:
        """One PI update at the control rate: lag, delay, PI, torque bounds."""
        tc = 1.0 / self.control_hz
        u = target
        if self.tau_lag > 0:
            self.lagged += (1.0 - math.exp(-tc / self.tau_lag)) * (u - self.lagged)
            u = self.lagged.copy()
        if self.delay_n:
            self.queue.append(np.array(u))
            u = self.queue.popleft()
        mo = self.cfg.motor
        w = self.data.qvel[self.wheel_dof[:4]]
        e = u - w
        raw = mo.speed_gain * e + mo.integral_gain * (self.integ + e * tc)
        hi = np.minimum(self.tau_max, mo.stall_torque * (1.0 - w / mo.no_load_speed))
        lo = np.maximum(-self.tau_max, -mo.stall_torque * (1.0 + w / mo.no_load_speed))
        tau = np.clip(raw, lo, hi)
        # Conditional integration: stop integrating while the output saturates outward.
        free = (tau == raw) | (np.sign(e) != np.sign(raw))
        self.integ = np.where(free, self.integ + e * tc, self.integ)
        self.torque = tau
        self.data.ctrl[:4] = tau

    # ------------------------------------------------------------------ tire
    def _tires(self) -> None:
        m, d, tp = self.model, self.data, self.cfg.tire
        radius = self.cfg.geometry.wheel_radius
        c = d.xpos[self.wheel_body]
        a = d.xaxis[self.wheel_jnt]
        ax, ay, az = a[:, 0], a[:, 1], a[:, 2]
        # Lowest point of each wheel disc over the plane z = 0.
        un = np.sqrt(np.maximum(1.0 - az * az, 1e-12))
        down = np.column_stack([-ax * az, -ay * az, 1.0 - az * az]) / un[:, None]
        point = c - radius * down
        point[:, 2] = 0.0
        delta = radius * un - c[:, 2]
        # Rolling direction a x z and lateral z x (a x z), in the ground plane.
        xn = np.sqrt(ax * ax + ay * ay)
        xc = np.column_stack([ay / xn, -ax / xn, np.zeros(6)])
        yc = np.column_stack([ax / xn, ay / xn, np.zeros(6)])
        cv = d.cvel[self.carrier]
        w, v0 = cv[:, :3], cv[:, 3:]
        ref = d.subtree_com[self.root]
        rp = point - ref
        rc = c - ref

        def at(r: Array) -> Array:  # v0 + w x r
            return np.column_stack(
                [
                    v0[:, 0] + w[:, 1] * r[:, 2] - w[:, 2] * r[:, 1],
                    v0[:, 1] + w[:, 2] * r[:, 0] - w[:, 0] * r[:, 2],
                    v0[:, 2] + w[:, 0] * r[:, 1] - w[:, 1] * r[:, 0],
                ]
            )

        v_p = at(rp)
        v_cz = at(rc)[:, 2]
        v_x = v_p[:, 0] * xc[:, 0] + v_p[:, 1] * xc[:, 1]
        v_y = v_p[:, 0] * yc[:, 0] + v_p[:, 1] * yc[:, 1]
        if self.soil is not None:
            self._on_soil(c, a, xc, yc, delta, v_x, v_y, v_cz)
            return
        dpos = np.maximum(delta, 0.0)
        F_z = np.where(delta > 0, np.maximum(tp.C_z * delta - tp.D_z * v_cz, 0.0), 0.0)
        r_e = radius - tp.k_re * dpos + self.rr_frac * radius * dpos / self.delta0
        lever = radius - dpos
        mu_x = np.full(6, self.mu_x)
        mu_y = np.full(6, self.mu_y)
        if self.fall:
            k = 1.0 - self.fall * np.minimum(
                np.maximum((F_z - self.fz0) / (2 * self.fall_range * self.fz0), -0.5), 0.5
            )
            mu_x, mu_y = mu_x * k, mu_y * k
        omega = d.qvel[self.wheel_dof]
        tau_o = np.zeros(6)
        tau_o[:4] = self.torque
        rr = self.c_rr * F_z * lever * np.tanh(omega / W_RR) if self.c_rr else np.zeros(6)
        tau_o -= rr
        cap_x = mu_x * F_z
        s_c = 3.0 * np.maximum(cap_x, 1e-9) / tp.C_s
        abs_vx = np.abs(v_x)

        def f_x(om: Array) -> Array:
            v_w = r_e * om
            s = (v_x - v_w) / np.maximum(np.maximum(abs_vx, np.abs(v_w)), V_EPS)
            ln = np.maximum(1.0 - np.minimum(np.abs(s), 1.0) / s_c, 0.0)
            return np.asarray(-np.sign(s) * cap_x * (1.0 - ln * ln * ln), dtype=np.float64)

        # Semi-implicit in the spin: the force at the spin rate it produces after the step,
        # F = f_x(omega + dt (tau - lever F) / I), monotone in F.
        k_w = DT / self.inertia

        def g(f: Array) -> Array:
            return np.asarray(f - f_x(omega + k_w * (tau_o - lever * f)), dtype=np.float64)

        F_x = foreign_soil.monotone_root(g, -cap_x - 1e-6, cap_x + 1e-6, 7)
        s_a = lateral_slip(v_x, v_y, r_e * omega)
        s_ac = 3.0 * mu_y * np.maximum(F_z, 1e-9) / tp.C_alpha
        ln_y = np.maximum(1.0 - s_a / s_ac, 0.0)
        F_y = -np.sign(v_y) * mu_y * F_z * (1.0 - ln_y**3)
        if self.ellipse:
            fz = np.maximum(F_z, 1e-9)
            n = np.hypot(F_x / (mu_x * fz), F_y / (mu_y * fz))
            sc = 1.0 / np.maximum(n, 1.0)
            F_x, F_y = F_x * sc, F_y * sc
        force = F_x[:, None] * xc + F_y[:, None] * yc
        force[:, 2] += F_z
        torque = -rr[:, None] * a  # the offset normal force's moment about the hub
        d.qfrc_applied[:] = 0.0
        for i in range(6):
            mujoco.mj_applyFT(
                m, d, force[i], torque[i], point[i], int(self.wheel_body[i]), d.qfrc_applied
            )

    def _on_soil(
        self,
        hub: Array,
        axis: Array,
        xc: Array,
        yc: Array,
        h: Array,
        v_x: Array,
        v_y: Array,
        v_cz: Array,
    ) -> None:
        """Loose-soil contact (module docstring): forces at the hub, the resisting torque
        about the axle, both at the spin rate after the step."""
        m, d = self.model, self.data
        assert self.soil is not None
        g = self.cfg.geometry
        tau_o = np.zeros(6)
        tau_o[:4] = self.torque
        omega = d.qvel[self.wheel_dof]
        w1 = foreign_soil.spin_after_step(
            omega, tau_o, DT / self.inertia, h, v_x, v_y, g.wheel_radius, g.wheel_width, self.soil
        )
        f = foreign_soil.at_spin(w1, h, v_x, v_y, g.wheel_radius, g.wheel_width, self.soil)
        # Out of contact the stresses integrate over nothing (exactly 0); only the damping
        # needs the contact test.
        F_z = np.where(h > 0, np.maximum(f.F_z - self.soil.damping * v_cz, 0.0), 0.0)
        force = f.F_x[:, None] * xc + f.F_y[:, None] * yc
        force[:, 2] += F_z
        torque = -f.T[:, None] * axis
        d.qfrc_applied[:] = 0.0
        for i in range(6):
            mujoco.mj_applyFT(
                m, d, force[i], torque[i], hub[i], int(self.wheel_body[i]), d.qfrc_applied
            )

    def run(self, target: Array, seconds: float) -> None:
        n = round(seconds / DT)
        for k in range(n):
            if k % self.per_control == 0:
                self._control(target)
            mujoco.mj_step1(self.model, self.data)
            self._tires()
            mujoco.mj_step2(self.model, self.data)
        if not np.all(np.isfinite(self.data.qpos)):
            raise RuntimeError(f"foreign rover: state not finite at t={self.data.time:.3f}s")

    def sample(self) -> tuple[Array, Array, Array, Array]:
        d = self.data
        return (
            d.qpos[self.wheel_qpos].copy(),
            d.qpos[self.joint_qpos].copy(),
            d.xpos[self.seg3].copy(),
            d.xquat[self.seg3].copy(),
        )


def _flat() -> Any:
    from rover_env.config import load_terrain

    return load_terrain("flat")


def _relative_pose(pos: Array, quat: Array) -> Array:
    """Planar pose of segment 3 in its frame at t = 0 (written here, not the recorder's)."""
    out = np.zeros((len(pos), 3))
    r0 = np.zeros(9)
    mujoco.mju_quat2Mat(r0, quat[0])
    R0 = r0.reshape(3, 3)
    yaw = np.zeros(len(pos))
    for k in range(len(pos)):
        rk = np.zeros(9)
        mujoco.mju_quat2Mat(rk, quat[k])
        rel = R0.T @ rk.reshape(3, 3)
        out[k, :2] = (R0.T @ (pos[k] - pos[0]))[:2]
        yaw[k] = math.atan2(rel[1, 0], rel[0, 0])
    out[:, 2] = np.unwrap(yaw)
    out[0] = 0.0
    return out


FOREIGN_EFFECTS = frozenset(
    {
        "rolling_resistance",
        "slope",
        "rolling_radius",
        "torque_limit",
        "command_lag",
        "command_delay",
        "friction",
        "combined_slip",
        "load_dependent_friction",
        "loose_soil",
    }
)
"""The catalogue effects :class:`ForeignRover` implements in its own code (all of them)."""


def make_foreign_logs(
    out: str | Path,
    effects: dict[str, dict[str, float]],
    drives: int = 3,
    seed: int = 0,
    duration: float = 50.0,
    plan: str = "test",
    rover: str = "proto_explorer",
    truth_rover: RoverConfig | None = None,
    progress: bool = True,
    first_index: int = 0,
    control_hz: float = CONTROL_HZ,
) -> list[Path]:
    """Write ``drives`` SPEC §6 logs from :class:`ForeignRover` and ``truth.yaml``.
    ``control_hz``: the rate of its speed loop (a probe of the loop's form; stop 36)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    nominal = load_rover(rover)
    base = truth_rover if truth_rover is not None else nominal
    RoverConfig(extensions=effects)  # validate the effects by the catalogue's rules
    missing = sorted(set(effects) - FOREIGN_EFFECTS)
    if missing:
        raise ConfigError(
            f"effects {', '.join(missing)}: the second generator does not implement them"
            f" (it has: {', '.join(sorted(FOREIGN_EFFECTS))})"
        )
    rate = 50.0
    per_sample = round(1.0 / (rate * DT))
    enc = 2 * math.pi / ENCODER_COUNTS
    pot = POT_TRAVEL / 2**POT_BITS
    paths = []
    kids = np.random.SeedSequence([seed, 16]).spawn(first_index + drives)[first_index:]
    for i, kid in enumerate(kids):
        k = first_index + i
        rng_plan, rng_sens = (np.random.default_rng(s) for s in kid.spawn(2))
        sim = ForeignRover(base, effects, control_hz)
        sched = drive_schedule(plan, rng_plan, duration, nominal.motor.max_wheel_speed)
        if progress:
            print(f"make-logs (foreign): drive {k + 1}/{first_index + drives} ({plan})")
        n = round(duration * rate) + 1
        t = np.arange(n) / rate
        cmd = np.zeros((n, 4))
        phi = np.zeros((n, 6))
        theta = np.zeros((n, 5))
        pos = np.zeros((n, 3))
        quat = np.zeros((n, 4))
        for j in range(n):
            c = np.clip(sched(t[j]), -nominal.motor.max_wheel_speed, nominal.motor.max_wheel_speed)
            cmd[j] = c
            phi[j], theta[j], pos[j], quat[j] = sim.sample()
            if j < n - 1:
                sim.run(c, per_sample * DT)
        phi = _quantise(phi - phi[0], enc)
        theta = _quantise(theta + rng_sens.normal(0.0, POT_NOISE, theta.shape), pot)
        pose = _relative_pose(pos, quat)
        keep = np.zeros(n, dtype=bool)
        keep[:: round(rate)] = True
        pose[~keep] = np.nan
        m = keep.copy()
        m[0] = False
        pose[m, :2] += rng_sens.normal(0.0, POSE_NOISE_M, (int(m.sum()), 2))
        pose[m, 2] += rng_sens.normal(0.0, POSE_NOISE_YAW, int(m.sum()))
        meta = LogMeta(
            rover=str(rover),
            sample_rate_hz=rate,
            terrain="flat",
            notes=f"foreign generator, plan {plan}, seed {seed}, drive {k}",
        )
        log = DriveLog(t, cmd, phi, theta, pose, meta)
        paths.append(write_log(log, out / f"drive_{k:02d}.csv", overwrite=True))
    truth: dict[str, Any] = {
        "generator": "foreign (rover_env.generators.foreign_logs)",
        "effects": effects,
        "seed": seed,
        "drives": [p.name for p in paths],
        "plan": plan,
        "duration_s": duration,
        "step_s": DT,
        "control_hz": control_hz,
        "sensors": {
            "encoder_counts": ENCODER_COUNTS,
            "pot_bits": POT_BITS,
            "pot_travel_deg": math.degrees(POT_TRAVEL),
            "pot_noise_rad": POT_NOISE,
            "pose_noise": {"xy_m": POSE_NOISE_M, "yaw_rad": POSE_NOISE_YAW},
        },
        "rover": str(rover),
    }
    if truth_rover is not None:
        truth["truth_rover"] = to_dict(truth_rover)
    tpath = out / "truth.yaml"
    if first_index > 0 and tpath.is_file():
        old = yaml.safe_load(tpath.read_text()) or {}
        old.setdefault("extra_drives", []).append(
            {"plan": plan, "seed": seed, "drives": truth["drives"]}
        )
        truth = old
    tpath.write_text(yaml.safe_dump(truth, sort_keys=False))
    return paths


__all__ = ["ForeignRover", "make_foreign_logs"]
