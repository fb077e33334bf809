"""MJCF generation from the typed configuration (configuration is the only source of numbers).

The robot file and scene files in ``assets/`` are written by :func:`write_assets` from the
default configuration, and a test checks they are up to date. At run time the simulator
builds the same text from whatever configuration it is given.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rover_env.config import (
    DRIVEN_WHEELS,
    JOINTS,
    WHEELS,
    RoverConfig,
    TerrainConfig,
    load_terrain,
)
from rover_env.terrain import Terrain
from rover_env.tire import stable_step as tire_stable_step

JOINT_AXES = {
    "theta_1": "1 0 0",
    "theta_2": "0 0 1",
    "theta_3": "1 0 0",
    "theta_4": "0 1 0",
    "theta_5": "0 0 1",
}
"""SPEC §1: roll x, yaw z between segments 1-2; roll x, pitch y, yaw z between 2-3."""

SEGMENT_JOINTS = {2: ("theta_1", "theta_2"), 3: ("theta_3", "theta_4", "theta_5")}


@dataclass(frozen=True)
class SegmentInertia:
    mass: float
    com: np.ndarray
    diaginertia: np.ndarray


def segment_inertia(cfg: RoverConfig, seg: int) -> SegmentInertia:
    """Chassis box (structure + electronics + batteries) plus motors as point masses."""
    g, m = cfg.geometry, cfg.masses
    box_mass = m.chassis[seg - 1] + m.battery * m.battery_segments.count(seg)
    box_c = np.array([0.0, 0.0, g.chassis_lift + g.chassis_height / 2])
    parts: list[tuple[float, np.ndarray, np.ndarray]] = [
        (
            box_mass,
            box_c,
            box_mass
            / 12
            * np.array(
                [
                    g.chassis_width**2 + g.chassis_height**2,
                    g.chassis_length**2 + g.chassis_height**2,
                    g.chassis_length**2 + g.chassis_width**2,
                ]
            ),
        )
    ]
    if seg in (1, 2):
        # Motors sit inboard of each driven wheel, on the axle line.
        y = g.chassis_width / 2 - 0.04
        for s in (1, -1):
            parts.append((m.motor, np.array([0.0, s * y, 0.0]), np.zeros(3)))
    mass = float(sum(p[0] for p in parts))
    com = np.sum([p[0] * p[1] for p in parts], axis=0) / mass
    inertia = np.zeros(3)
    for pm, pc, pi in parts:
        r = pc - com
        inertia += pi + pm * np.array(
            [r[1] ** 2 + r[2] ** 2, r[0] ** 2 + r[2] ** 2, r[0] ** 2 + r[1] ** 2]
        )
    if g.com_height is not None:  # a measured height: the same body, its mass placed there
        com = np.array([com[0], com[1], g.com_height])
    return SegmentInertia(mass=float(mass), com=com, diaginertia=inertia)


def wheel_load(cfg: RoverConfig) -> float:
    """The weight shared equally by six wheels (N): what a wheel carries at rest on level ground."""
    return cfg.masses.total * 9.81 / 6


def wheel_spin_inertia(cfg: RoverConfig) -> float:
    """A wheel's inertia about its axle (kg m^2): a uniform disc, no rotor behind it."""
    return 0.5 * cfg.masses.wheel * cfg.geometry.wheel_radius**2


def stable_step(cfg: RoverConfig) -> float:
    """The largest physics step at which the tire's patch spring leaves the lightest wheel
    (a free one) stable (:func:`rover_env.tire.stable_step`)."""
    return tire_stable_step(cfg.tire, wheel_spin_inertia(cfg), cfg.geometry.wheel_radius)


def stable_config(cfg: RoverConfig) -> RoverConfig:
    """``cfg`` itself where its physics step is within :func:`stable_step`, else at that
    step halved until it is: a model form with a short relaxation length (0.16 mm, the
    bottom of ``diagnose``'s ladder) rings the free wheels even at the rover's 1 ms."""
    step, bound = cfg.sim.timestep, stable_step(cfg)
    if step < bound:
        return cfg
    while step >= bound:
        step /= 2
    return replace(cfg, sim=replace(cfg.sim, timestep=step))


def static_deflection(cfg: RoverConfig) -> float:
    """Tire compression under :func:`wheel_load` (m)."""
    return wheel_load(cfg) / cfg.tire.C_z


def _f(v: float) -> str:
    return f"{v:.6g}"


def _v(a: np.ndarray | tuple[float, ...]) -> str:
    return " ".join(_f(float(x)) for x in a)


def _defaults_xml(cfg: RoverConfig, add: Callable[[str], None]) -> None:
    """The compiler settings, default classes (joints, geoms, wheels, motors) and materials."""
    mo = cfg.motor
    add('  <compiler angle="radian" autolimits="true"/>')
    add("  <default>")
    add('    <default class="rover">')
    add('      <joint limited="true" armature="0.0001"/>')
    add('      <default class="visual">')
    add('        <geom contype="0" conaffinity="0" group="2" density="0"/>')
    add("      </default>")
    add('      <default class="collision">')
    add(
        '        <geom group="3" density="0" contype="1" conaffinity="1" friction="0.8 0.02 0.001"/>'
    )
    add('        <default class="wheel_collision">')
    add(
        "          <!-- Bit 2 only: wheels meet obstacles, never the ground (the tire layer owns that). -->"
    )
    add('          <geom type="cylinder" contype="2" conaffinity="2"/>')
    add("        </default>")
    add("      </default>")
    add('      <default class="wheel">')
    add('        <joint type="hinge" axis="0 1 0" limited="false" damping="0" armature="0"/>')
    add("      </default>")
    add('      <default class="motor">')
    add(
        f'        <dcmotor nominal="{_f(mo.voltage)} {_f(mo.stall_torque)} {_f(mo.no_load_speed)}"'
        f' saturation="{_f(mo.torque_limit)} 0 0" armature="{_f(mo.armature)}" input="pos vel"'
        f' controller="{_f(mo.integral_gain)} 0 {_f(mo.speed_gain)} 0 0 {_f(mo.voltage)}"/>'
    )
    add("      </default>")
    add("    </default>")
    add("  </default>")
    add("  <asset>")
    add('    <material name="body" rgba="0.82 0.80 0.74 1"/>')
    add('    <material name="tire" rgba="0.15 0.15 0.15 1"/>')
    add('    <material name="hub" rgba="0.6 0.6 0.65 1"/>')
    add('    <material name="battery" rgba="0.2 0.35 0.6 1"/>')
    add("  </asset>")


def _segment_xml(cfg: RoverConfig, seg: int, indent: str, add: Callable[[str], None]) -> None:
    """Segment ``seg``'s inertia, chassis, IMU site and two wheels (bodies inside its body)."""
    g, m = cfg.geometry, cfg.masses
    d, w = g.wheel_radius, g.wheel_width
    iw_axis = wheel_spin_inertia(cfg)
    iw_other = m.wheel * (3 * d**2 + w**2) / 12
    si = segment_inertia(cfg, seg)
    bz = g.chassis_lift + g.chassis_height / 2
    half = (g.chassis_length / 2, g.chassis_width / 2, g.chassis_height / 2)
    add(
        f'{indent}<inertial pos="{_v(si.com)}" mass="{_f(si.mass)}" diaginertia="{_v(si.diaginertia)}"/>'
    )
    add(
        f'{indent}<geom name="chassis{seg}" class="collision" type="box" pos="0 0 {_f(bz)}" size="{_v(half)}"/>'
    )
    add(
        f'{indent}<geom class="visual" type="box" pos="0 0 {_f(bz)}" size="{_v(half)}" material="body"/>'
    )
    if seg in m.battery_segments:
        add(
            f'{indent}<geom class="visual" type="box" pos="0 0 {_f(g.chassis_lift + g.chassis_height + 0.02)}"'
            f' size="0.08 0.06 0.02" material="battery"/>'
        )
    add(f'{indent}<site name="imu_seg{seg}" pos="0 0 0" size="0.01"/>')
    for side, sgn in (("L", 1), ("R", -1)):
        wname = f"{seg}{side}"
        add(f'{indent}<body name="wheel_{wname}" pos="0 {_f(sgn * g.half_track)} 0">')
        add(
            f'{indent}  <inertial pos="0 0 0" mass="{_f(m.wheel)}"'
            f' diaginertia="{_f(iw_other)} {_f(iw_axis)} {_f(iw_other)}"/>'
        )
        add(f'{indent}  <joint name="wheel_{wname}" class="wheel"/>')
        add(
            f'{indent}  <geom name="wheel_{wname}" class="wheel_collision" size="{_f(d)} {_f(w / 2)}"'
            f' euler="1.5707963 0 0"/>'
        )
        add(
            f'{indent}  <geom class="visual" type="cylinder" size="{_f(d)} {_f(w / 2)}"'
            f' euler="1.5707963 0 0" material="tire"/>'
        )
        add(
            f'{indent}  <geom class="visual" type="box" size="{_f(0.7 * d)} {_f(w / 2 + 0.002)} 0.008"'
            f' material="hub"/>'
        )
        add(f"{indent}</body>")


def _sensors_xml(add: Callable[[str], None]) -> None:
    """Encoders and rates of every wheel and joint; an IMU (attitude, gyro, accelerometer) per
    segment: what ``RoverSim.sensors`` reads."""
    add("  <sensor>")
    for wn in WHEELS:
        add(f'    <jointpos name="phi_{wn}" joint="wheel_{wn}"/>')
    for wn in WHEELS:
        add(f'    <jointvel name="phidot_{wn}" joint="wheel_{wn}"/>')
    for j in JOINTS:
        add(f'    <jointpos name="{j}" joint="{j}"/>')
    for j in JOINTS:
        add(f'    <jointvel name="{j}_dot" joint="{j}"/>')
    for seg in (1, 2, 3):
        add(f'    <framequat name="imu_seg{seg}_quat" objtype="site" objname="imu_seg{seg}"/>')
        add(f'    <gyro name="imu_seg{seg}_gyro" site="imu_seg{seg}"/>')
        add(f'    <accelerometer name="imu_seg{seg}_accel" site="imu_seg{seg}"/>')
    add("  </sensor>")


def robot_xml(cfg: RoverConfig) -> str:
    """The rover as an MJCF fragment (``<mujoco model="proto_explorer">`` with no scene)."""
    g = cfg.geometry
    hub_z = g.wheel_radius - static_deflection(cfg)
    lines: list[str] = []
    add = lines.append
    add(f'<mujoco model="{cfg.name}">')
    add(
        "  <!-- Generated by rover_env.sim.model from the rover configuration: edit the YAML, not this file. -->"
    )
    _defaults_xml(cfg, add)
    add("  <worldbody>")
    add(f'    <body name="seg1" pos="0 0 {_f(hub_z)}" childclass="rover">')
    add('      <freejoint name="root"/>')
    add(
        '      <camera name="track" mode="trackcom" pos="-1.6 -1.6 1.2" xyaxes="0.707 -0.707 0 0.35 0.35 0.87"/>'
    )
    _segment_xml(cfg, 1, "      ", add)
    indent = "      "
    for seg in (2, 3):
        add(f'{indent}<body name="seg{seg}" pos="{_f(-g.axle_spacing)} 0 0">')
        indent += "  "
        for j in SEGMENT_JOINTS[seg]:
            js = cfg.joints[j]
            add(
                f'{indent}<joint name="{j}" type="hinge" pos="{_f(g.joint_offset)} 0 {_f(g.joint_height)}" axis="{JOINT_AXES[j]}"'
                f' stiffness="{_f(js.stiffness)}" damping="{_f(js.damping)}" range="{_f(-js.limit)} {_f(js.limit)}"/>'
            )
        add(
            f'{indent}<geom class="visual" type="capsule" fromto="0 0 {_f(g.chassis_lift + 0.05)}'
            f' {_f(g.joint_offset)} 0 {_f(g.chassis_lift + 0.05)}" size="0.015" material="hub"/>'
        )
        _segment_xml(cfg, seg, indent, add)
    for _ in (3, 2):
        indent = indent[:-2]
        add(f"{indent}</body>")
    add("    </body>")
    add("  </worldbody>")
    add("  <actuator>")
    for wn in DRIVEN_WHEELS:
        add(f'    <dcmotor name="motor_{wn}" class="motor" joint="wheel_{wn}"/>')
    add("  </actuator>")
    _sensors_xml(add)
    add("</mujoco>")
    return "\n".join(lines) + "\n"


def hfield_shape(terrain: TerrainConfig) -> tuple[int, int]:
    """(nrow, ncol) of the MuJoCo heightfield for an arena."""
    sx, sy = terrain.size
    return round(sy / terrain.resolution) + 1, round(sx / terrain.resolution) + 1


def hfield_data(terrain: TerrainConfig) -> tuple[np.ndarray, float, float]:
    """Normalised elevations (row-major, rows along y), base height and elevation range."""
    nrow, ncol = hfield_shape(terrain)
    _, _, h = Terrain(terrain).sample_grid(ncol, nrow)
    lo, hi = float(h.min()), float(h.max())
    span = max(hi - lo, 1e-3)
    return ((h - lo) / span).astype(np.float32), lo, span


def scene_xml(
    cfg: RoverConfig,
    terrain: TerrainConfig,
    robot_file: str | None = None,
    hfield_file: str | None = None,
) -> str:
    """A scene: options, ground, obstacles, light, plus the robot (included or inlined).

    With ``hfield_file`` the heightfield's elevations come from that file; without it the
    caller fills ``model.hfield_data`` after compiling (:func:`fill_hfield`).
    """
    sx, sy = terrain.size
    lines = [f'<mujoco model="{cfg.name} on {terrain.name}">']
    add = lines.append
    add(
        "  <!-- Generated by rover_env.sim.model from the configuration: edit the YAML, not this file. -->"
    )
    add(
        f'  <option timestep="{_f(cfg.sim.timestep)}" integrator="implicitfast" jacobian="dense"'
        ' cone="elliptic"/>'
    )
    add('  <visual><global offwidth="640" offheight="480"/><quality shadowsize="2048"/></visual>')
    add("  <asset>")
    add(
        '    <texture name="grid" type="2d" builtin="checker" rgb1="0.55 0.45 0.35" rgb2="0.5 0.4 0.3"'
        ' width="512" height="512" mark="edge" markrgb="0.4 0.32 0.25"/>'
    )
    add(
        '    <material name="ground" texture="grid" texrepeat="1 1" texuniform="true" reflectance="0"/>'
    )
    add('    <material name="rock" rgba="0.45 0.42 0.4 1"/>')
    if not terrain.is_flat:
        nrow, ncol = hfield_shape(terrain)
        _, lo, span = hfield_data(terrain)
        src = f' file="{hfield_file}"' if hfield_file else f' nrow="{nrow}" ncol="{ncol}"'
        add(f'    <hfield name="terrain"{src} size="{_f(sx / 2)} {_f(sy / 2)} {_f(span)} 0.5"/>')
    add("  </asset>")
    add("  <worldbody>")
    add('    <light name="sun" pos="0 0 6" dir="0.3 0.3 -1" directional="true"/>')
    if terrain.is_flat:
        add(
            f'    <geom name="ground" type="plane" size="{_f(sx / 2)} {_f(sy / 2)} 0.1" material="ground"'
            ' contype="1" conaffinity="1"/>'
        )
    else:
        _, lo, span = hfield_data(terrain)
        add(
            f'    <geom name="ground" type="hfield" hfield="terrain" pos="0 0 {_f(lo)}" material="ground"'
            ' contype="1" conaffinity="1"/>'
        )
    for ob in terrain.obstacles:
        add(
            f'    <geom name="{ob.name}" type="box" pos="{_v(ob.pos)}" size="{_v(ob.size)}"'
            f' euler="0 0 {_f(np.radians(ob.yaw_deg))}" material="rock" contype="3" conaffinity="3"'
            ' friction="0.8 0.02 0.001"/>'
        )
    add("  </worldbody>")
    if robot_file:
        lines.insert(2, f'  <include file="{robot_file}"/>')
        add("</mujoco>")
        return "\n".join(lines) + "\n"
    add("</mujoco>")
    robot = robot_xml(cfg).splitlines()
    # Inline the robot's children into the scene (same result as <include>).
    body = [ln for ln in robot[1:-1]]
    lines[1:1] = body
    return "\n".join(lines) + "\n"


def physics_only(xml: str) -> str:
    """``xml`` (from :func:`scene_xml`) without what only a renderer reads: the visual geoms,
    the camera, the light and the ground's texture. The visual geoms have no mass (density 0)
    and collide with nothing, so the model moves the same to the bit (tested); each substep
    then places 10 geoms instead of 29 and a build skips the 512 x 512 texture. For models
    nobody renders: the calibration's replays."""
    drop = ('<geom class="visual"', "<camera ", "<light ", "<texture ")
    lines = [ln for ln in xml.splitlines() if not ln.lstrip().startswith(drop)]
    return "\n".join(lines).replace(' texture="grid"', "") + "\n"


def fill_hfield(model: object, terrain: TerrainConfig) -> None:
    """Copy the analytic terrain's samples into a compiled model's heightfield."""
    if terrain.is_flat:
        return
    data, _, _ = hfield_data(terrain)
    model.hfield_data[:] = data.ravel()  # type: ignore[attr-defined]


SCENES = {"scene_flat": "flat", "scene_rough": "rough"}


def write_assets(out: Path, cfg: RoverConfig) -> list[Path]:
    """Write the robot file and scene files (with heightfield binaries) into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "proto_explorer.xml"]
    written[0].write_text(robot_xml(cfg))
    for scene, tname in SCENES.items():
        terrain = load_terrain(tname)
        hfile = None
        if not terrain.is_flat:
            nrow, ncol = hfield_shape(terrain)
            data, _, _ = hfield_data(terrain)
            hfile = f"{scene}.hfield"
            header = np.array([nrow, ncol], dtype=np.int32).tobytes()
            (out / hfile).write_bytes(header + data.astype(np.float32).tobytes())
            written.append(out / hfile)
        p = out / f"{scene}.xml"
        p.write_text(scene_xml(cfg, terrain, robot_file="proto_explorer.xml", hfield_file=hfile))
        written.append(p)
    return written
