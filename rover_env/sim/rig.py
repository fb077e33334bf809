"""Single-wheel test rig: a loaded wheel spun at a fixed rate over ground at a fixed speed.

It imposes slip exactly (carrier speed and wheel rate are held by stiff velocity servos), so
the longitudinal force the tire layer produces in the MuJoCo loop can be measured from the
servo that holds the carrier and compared with eq. (13). With ``omega=None`` the wheel
rolls free (no spin servo), with ``v_y`` the carrier also slides sideways at that speed,
and ``effects`` (:mod:`rover_env.effects`: tire and hinge effects) act as in ``RoverSim``:
the rig tests of the effects' conventions (issue 16) measure them here.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from rover_env.config import TerrainConfig
from rover_env.effects import Effect, HingeEffect, TireEffect
from rover_env.sim.tire_layer import TireLayer
from rover_env.terrain import Terrain
from rover_env.tire import TireParams

RIG_XML = """
<mujoco model="single wheel rig">
  <option timestep="{dt}" integrator="implicitfast" jacobian="dense" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="carrier" pos="0 0 {z0}">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="{load_mass}" diaginertia="0.01 0.01 0.01"/>
      <body name="wheel">
        <joint name="spin" type="hinge" axis="0 1 0"/>
        <inertial pos="0 0 0" mass="0.35" diaginertia="0.0007 0.00126 0.0007"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <velocity name="drive_x" joint="x" kv="{kv_x}"/>
    <velocity name="drive_y" joint="y" kv="{kv_x}"/>
    <velocity name="drive_spin" joint="spin" kv="{kv_spin}"/>
  </actuator>
</mujoco>
"""


def _rig(
    dt: float,
    z0: float,
    load_mass: float,
    kv_spin: float,
    radius: float,
    terrain: Terrain,
    params: TireParams,
    effects: Sequence[TireEffect] = (),
    width: float = 0.05,
) -> tuple[mujoco.MjModel, mujoco.MjData, TireLayer]:
    """The rig's model and data (carrier at height z0) and its wheel's tire layer."""
    xml = RIG_XML.format(dt=dt, z0=z0, load_mass=load_mass, kv_x=2e4, kv_spin=kv_spin)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    layer = TireLayer(
        model,
        np.array([model.body("wheel").id]),
        np.array([model.joint("spin").id]),
        radius,
        terrain,
        params,
        effects=effects,
        width=width,
    )
    return model, data, layer


def measure_fx(
    v_x: float,
    omega: float | None,
    load_mass: float = 2.7,
    radius: float = 0.085,
    params: TireParams | None = None,
    duration: float = 3.0,
    dt: float = 0.001,
    v_y: float = 0.0,
    effects: Sequence[Effect] = (),
) -> dict[str, float]:
    """Run the rig to steady state; return the measured forces and the layer's own state.

    ``F_servo`` (``F_servo_y``) is the force the ground exerts on the carrier along x (y),
    measured from the servo that holds its speed; ``omega`` the wheel's mean spin rate.
    """
    params = params or TireParams()
    delta0 = (load_mass + 0.35) * 9.81 / params.C_z
    kv_spin = 50.0 if omega is not None else 0.0
    terrain = Terrain(TerrainConfig(name="rig", size=(1e3, 1e3)), params)
    model, data, layer = _rig(
        dt, radius - delta0, load_mass, kv_spin, radius, terrain, params,
        effects=[e for e in effects if isinstance(e, TireEffect)],
    )  # fmt: skip
    hinges = [e for e in effects if isinstance(e, HingeEffect)]
    spin = model.joint("spin").dofadr[0]
    w0 = omega if omega is not None else v_x / (radius - params.k_re * delta0)
    data.qvel[model.joint("x").dofadr[0]] = v_x
    data.qvel[model.joint("y").dofadr[0]] = v_y
    data.qvel[spin] = w0
    data.ctrl[:] = [v_x, v_y, omega if omega is not None else 0.0]
    n = round(duration / dt)
    acc = dict.fromkeys(
        ("F_servo", "F_servo_y", "F_x", "F_y", "F_z", "delta", "v_x", "v_w", "omega"), 0.0
    )
    n_avg = n // 3
    for k in range(n):
        mujoco.mj_step1(model, data)
        layer.apply(data)
        if hinges:  # as RoverSim: this substep's load sets the next substep's friction
            s = layer.last
            assert s is not None
            model.dof_frictionloss[spin] = sum(
                float(h.hinge_friction(s.F_z, s.delta, radius)[0]) for h in hinges
            )
        mujoco.mj_step2(model, data)
        if k >= n - n_avg:
            s = layer.last
            assert s is not None
            acc["F_servo"] += -float(data.actuator_force[0])
            acc["F_servo_y"] += -float(data.actuator_force[1])
            acc["F_y"] += float(s.F_y[0])
            acc["omega"] += float(data.qvel[spin])
            acc["F_x"] += float(s.F_x[0])
            acc["F_z"] += float(s.F_z[0])
            acc["delta"] += float(s.delta[0])
            acc["v_x"] += float(s.v_x[0])
            acc["v_w"] += float(s.v_w[0])
    return {k: v / n_avg for k, v in acc.items()}


def measure_soil(
    soil: str,
    slip: float,
    load: float = 27.0,
    v_x: float = 0.1,
    radius: float = 0.085,
    width: float = 0.05,
    duration: float = 4.0,
    dt: float = 0.001,
) -> dict[str, float]:
    """The rig on loose soil held at Wong's slip ``slip``; averages over the last third.

    ``load`` (N) is the wheel's vertical load (carrier plus wheel weight). Returns the
    drawbar pull from the carrier's servo and from the layer, F_z, the resistive torque
    from the spin servo and from the layer, the sinkage, the speeds, and the depth of the
    wheel's lowest point below the terrain (``depth``; ``final_depth`` at the end). Slip 1
    holds the carrier still and spins the wheel (a wheel digging itself in).
    """
    params = TireParams()
    wheel_mass = 0.35
    load_mass = load / 9.81 - wheel_mass
    terrain = Terrain(TerrainConfig(name="rig", size=(40.0, 4.0), soil=soil), params)
    model, data, layer = _rig(dt, radius, load_mass, 50.0, radius, terrain, params, width=width)
    if slip >= 1.0:  # spinning in place: the carrier held, the wheel at v_w = 0.25 m/s
        v_x, v_w = 0.0, 0.25
    else:
        v_w = v_x / (1.0 - slip) if slip >= 0 else v_x * (1.0 + slip)
    omega = v_w / radius
    data.qpos[model.joint("x").qposadr[0]] = -15.0
    data.qvel[model.joint("x").dofadr[0]] = v_x
    data.qvel[model.joint("spin").dofadr[0]] = omega
    data.ctrl[:] = [v_x, 0.0, omega]  # drive_x, drive_y (held at 0), drive_spin
    n = round(duration / dt)
    keys = ("F_servo", "F_x", "F_z", "T_servo", "T", "sinkage", "v_x", "v_w", "depth")
    acc = dict.fromkeys(keys, 0.0)
    n_avg = n // 3
    for k in range(n):
        mujoco.mj_step1(model, data)
        layer.apply(data)
        mujoco.mj_step2(model, data)
        if k >= n - n_avg:
            s = layer.last
            assert s is not None
            acc["F_servo"] += -float(data.actuator_force[0])
            acc["F_x"] += float(s.F_x[0])
            acc["F_z"] += float(s.F_z[0])
            acc["T_servo"] += float(data.actuator_force[2])
            acc["T"] += float(s.torque[0])
            acc["sinkage"] += float(s.sinkage[0])
            acc["v_x"] += float(s.v_x[0])
            acc["v_w"] += float(s.v_w[0])
            acc["depth"] += float(s.delta[0])
    out = {k: v / n_avg for k, v in acc.items()}
    out["final_depth"] = float(layer.last.delta[0]) if layer.last is not None else 0.0
    return out


def free_wheel_residual(
    load: float = 27.0, dt: float = 0.001, v_x: float = 0.2, radius: float = 0.085
) -> float:
    """An unpowered wheel on the rig, started 10 % slower than rolling: the largest |F_x| (N)
    over the second half of 1 s. The tire's patch spring and damping act on the wheel's spin
    explicitly (applied forces), so it settles to exactly 0 only while the timestep is below
    their stability bound (docs/timestep.md), which a light load lowers."""
    params = TireParams()
    terrain = Terrain(TerrainConfig(name="rig", size=(1e3, 1e3)), params)
    d0 = load / params.C_z
    model, data, layer = _rig(dt, radius - d0, load / 9.81 - 0.35, 0.0, radius, terrain, params)
    data.qvel[model.joint("x").dofadr[0]] = v_x
    data.ctrl[:] = [v_x, 0.0, 0.0]
    data.qvel[model.joint("spin").dofadr[0]] = 0.9 * v_x / (radius - params.k_re * d0)
    n = round(1.0 / dt)
    worst = 0.0
    for k in range(n):
        mujoco.mj_step1(model, data)
        layer.apply(data)
        mujoco.mj_step2(model, data)
        if k >= n // 2 and layer.last is not None:
            worst = max(worst, abs(float(layer.last.F_x[0])))
    return worst
