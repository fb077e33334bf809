"""The independent generator's rover: its nominal numbers and its own MJCF, from SPEC.md alone.

SPEC gives the chain (three segments; roll+yaw between 1 and 2, roll+pitch+yaw between 2 and 3,
leaf springs on the yaw and pitch joints), the masses of Table 2 and the tire table. Everything
else here is this module's own choice, stated beside the number:

- wheel radius ``d`` 0.085 m: SPEC's "170" read as a diameter (SOIL.md's orientation figures use
  the same wheel); wheel width 0.05 m;
- overall width 500 mm is read as over the wheel outer faces: half track 0.225 m to wheel centres;
- axle spacing 0.36 m between neighbouring segments (a ~0.9 m body with 0.17 m wheels), the
  inter-segment joints midway between axles, 0.05 m above the axles;
- masses: 0.35 kg per wheel (tyre, hub, potentiometer), 4.77 kg per segment body so that each axle
  carries a third of 16.4 kg; segments 1 and 2 hold two 0.3 kg motors and one 0.7 kg battery each,
  segment 3 the logger and electronics; segment bodies are 0.30 x 0.40 x 0.12 m boxes for inertia,
  centre of mass 0.03 m above the axle;
- leaf springs: yaw joints 15 N m/rad, the pitch joint 25 N m/rad, damping 0.4 N m s/rad on each;
  roll joints are free (no spring), 0.05 N m s/rad of bearing damping;
- no MuJoCo collision at all: every wheel-ground force comes from :mod:`tire` or :mod:`soil`.
  Gravity is rotated instead of the ground for a slope (same physics, a flat z = 0 plane).

The chain is built with segment 1 as the floating root; segment 2 is a child of segment 1 with
hinges about x then z at the shared anchor, segment 3 a child of 2 with x, y, z hinges. MuJoCo
composes a body's hinges left to right in the frame already rotated by the earlier ones, which is
SPEC's R_2 = R_1 Rx(theta_1) Rz(theta_2), R_3 = R_2 Rx(theta_3) Ry(theta_4) Rz(theta_5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

WHEELS = ("1L", "1R", "2L", "2R", "3L", "3R")
DRIVEN = ("1L", "1R", "2L", "2R")
JOINTS = ("theta_1", "theta_2", "theta_3", "theta_4", "theta_5")
JOINT_AXES = {"theta_1": "x", "theta_2": "z", "theta_3": "x", "theta_4": "y", "theta_5": "z"}
G = 9.81


@dataclass
class RoverParams:
    """Every physical number of the simulated rover (nominal values; :mod:`nuisance` perturbs)."""

    wheel_radius: list[float] = field(default_factory=lambda: [0.085] * 6)
    wheel_width: float = 0.05
    half_track: float = 0.225
    axle_spacing: float = 0.36
    joint_height: float = 0.05
    wheel_mass: float = 0.35
    seg_mass: list[float] = field(default_factory=lambda: [4.77, 4.77, 4.77])
    seg_com: list[list[float]] = field(default_factory=lambda: [[0.0, 0.0, 0.03]] * 3)
    seg_box: tuple[float, float, float] = (0.30, 0.40, 0.12)
    # theta_1..theta_5: stiffness (N m/rad) and damping (N m s/rad)
    spring_k: list[float] = field(default_factory=lambda: [0.0, 15.0, 0.0, 25.0, 15.0])
    spring_c: list[float] = field(default_factory=lambda: [0.05, 0.4, 0.05, 0.4, 0.4])
    # tire (SPEC Table 3)
    mu_x: float = 0.4
    mu_y: float = 0.5
    c_s: float = 100.0
    c_alpha: float = 50.0
    c_z: float = 1000.0
    d_z: float = 72.2
    # motors: per driven wheel torque constant (N m/A), PI gains
    k_t: list[float] = field(default_factory=lambda: [0.02] * 4)
    kp: list[float] = field(default_factory=lambda: [6.0] * 4)
    ki: list[float] = field(default_factory=lambda: [30.0] * 4)
    # sensors
    pot_gain: list[float] = field(default_factory=lambda: [1.0] * 5)
    encoder_cpr: int = 1024
    # what the outside-the-catalogue effects change (:mod:`effects`): none on the drawing
    payload_mass: float = 0.0  # kg on segment 2's deck
    toe_rad: float = 0.0  # segment 1's wheels yawed inward (toe-in > 0)

    def total_mass(self) -> float:
        return float(sum(self.seg_mass) + 6 * self.wheel_mass + self.payload_mass)


def _box_inertia(m: float, dims: tuple[float, float, float]) -> tuple[float, float, float]:
    a, b, c = dims
    return (m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12)


def _f(v: float) -> str:
    return repr(float(v))


PAYLOAD_HEIGHT = 0.14
"""Centre of a payload above segment 2's axle: a 0.1 m tall load on the deck (top at 0.09 m)."""
PAYLOAD_BOX = (0.2, 0.2, 0.1)


def _wheel_xml(
    name: str, y: float, r: float, m: float, driven: bool, armature: float, yaw: float = 0.0
) -> str:
    iy = 0.5 * m * r * r
    ix = 0.25 * m * r * r
    arm = armature if driven else 0.0
    damp = 2e-4  # bearing (+ potentiometer wiper on the free wheels), N m s/rad
    return (
        f'<body name="w{name}" pos="0 {_f(y)} 0" euler="0 0 {_f(yaw)}">'
        f'<joint name="phi_{name}" type="hinge" axis="0 1 0" armature="{_f(arm)}" damping="{_f(damp)}"/>'
        f'<inertial pos="0 0 0" mass="{_f(m)}" diaginertia="{_f(ix)} {_f(iy)} {_f(ix)}"/>'
        "</body>"
    )


def build_mjcf(
    p: RoverParams,
    *,
    timestep: float,
    gravity: np.ndarray,
    z0: float,
    rotor_armature: float,
) -> str:
    """The rover's MJCF: segment 1 at x = +spacing, segment 2 at 0, segment 3 at -spacing."""
    L = p.axle_spacing
    h = p.joint_height

    def seg_inertial(i: int) -> str:
        ixx, iyy, izz = _box_inertia(p.seg_mass[i], p.seg_box)
        c = p.seg_com[i]
        return (
            f'<inertial pos="{_f(c[0])} {_f(c[1])} {_f(c[2])}" mass="{_f(p.seg_mass[i])}" '
            f'diaginertia="{_f(ixx)} {_f(iyy)} {_f(izz)}"/>'
        )

    def wheels(seg: int) -> str:
        out = []
        for j, side in enumerate("LR"):
            k = 2 * (seg - 1) + j
            y = p.half_track if side == "L" else -p.half_track
            # toe-in turns a left wheel's front toward -y (clockwise seen from above)
            yaw = (-p.toe_rad if side == "L" else p.toe_rad) if seg == 1 else 0.0
            out.append(
                _wheel_xml(
                    f"{seg}{side}", y, p.wheel_radius[k], p.wheel_mass, seg < 3, rotor_armature, yaw
                )
            )
        return "".join(out)

    def payload() -> str:
        if p.payload_mass <= 0.0:
            return ""
        ixx, iyy, izz = _box_inertia(p.payload_mass, PAYLOAD_BOX)
        return (
            f'<body name="payload" pos="0 0 {_f(PAYLOAD_HEIGHT)}">'
            f'<inertial pos="0 0 0" mass="{_f(p.payload_mass)}" '
            f'diaginertia="{_f(ixx)} {_f(iyy)} {_f(izz)}"/></body>'
        )

    def joint(name: str, anchor_x: float) -> str:
        i = JOINTS.index(name)
        axis = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}[JOINT_AXES[name]]
        return (
            f'<joint name="{name}" type="hinge" axis="{axis}" pos="{_f(anchor_x)} 0 {_f(h)}" '
            f'stiffness="{_f(p.spring_k[i])}" damping="{_f(p.spring_c[i])}"/>'
        )

    g = gravity
    return (
        '<mujoco model="proto_explorer_independent">'
        '<compiler angle="radian" autolimits="true"/>'
        f'<option timestep="{_f(timestep)}" integrator="implicitfast" '
        f'gravity="{_f(g[0])} {_f(g[1])} {_f(g[2])}"><flag contact="disable"/></option>'
        "<worldbody>"
        f'<body name="seg1" pos="{_f(L)} 0 {_f(z0)}"><freejoint name="root"/>{seg_inertial(0)}'
        f"{wheels(1)}"
        f'<body name="seg2" pos="{_f(-L)} 0 0">'
        f"{joint('theta_1', L / 2)}{joint('theta_2', L / 2)}{seg_inertial(1)}{wheels(2)}{payload()}"
        f'<body name="seg3" pos="{_f(-L)} 0 0">'
        f"{joint('theta_3', L / 2)}{joint('theta_4', L / 2)}{joint('theta_5', L / 2)}"
        f"{seg_inertial(2)}{wheels(3)}"
        "</body></body></body></worldbody></mujoco>"
    )


def gravity_vector(slope_deg: float, heading_deg: float) -> np.ndarray:
    """Gravity in the ground frame for ground rising at ``slope_deg`` toward ``heading_deg``.

    ``heading_deg`` is measured from the rover's initial forward axis, counter-clockwise (0: the
    rover faces uphill for a positive slope, 90: uphill is to its left).
    """
    a = math.radians(slope_deg)
    psi = math.radians(heading_deg)
    hvec = np.array([math.cos(psi), math.sin(psi), 0.0])
    return G * (-math.sin(a) * hvec - math.cos(a) * np.array([0.0, 0.0, 1.0]))
