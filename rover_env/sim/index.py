"""Where a compiled rover model keeps its parts, and what a simulation reads out of it:
the index arrays (:class:`SimIndex`), the privileged per-wheel and per-segment state
(:class:`WheelTruth`, :class:`SegmentTruth`), the sensors (:class:`SensorReadings`) and the
error a failed step raises. Apart from :mod:`rover_env.sim.simulator` so that readers need
not import the simulator to name them."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import mujoco
import numpy as np
from numpy.typing import NDArray

from rover_env.config import DRIVEN_WHEELS, JOINTS, WHEELS

Array = NDArray[np.float64]


def as_slice(index: NDArray[np.intp]) -> slice | NDArray[np.intp]:
    """``index`` as the equal slice where its entries are evenly spaced and increasing (a
    slice writes a row into ``MjData`` arrays several times faster than an index array);
    else ``index`` itself."""
    a = np.asarray(index, dtype=np.intp).reshape(-1)
    if a.size == 0:
        return a
    step = int(a[1] - a[0]) if a.size > 1 else 1
    if step <= 0 or not np.array_equal(a, a[0] + step * np.arange(a.size)):
        return a
    return slice(int(a[0]), int(a[-1]) + 1, step)


@dataclass(frozen=True, eq=False)
class SimIndex:
    """Where a compiled rover model keeps its wheels, joints, segments, motors and sensors.

    Index arrays into ``MjData``/``MjModel`` fields, for code that reads or writes a
    simulator's arrays directly (batched readers, replays, the compiled sample loops)
    rather than through :class:`RoverSim`'s methods. Wheels in ``WHEELS`` order, joints in
    ``JOINTS`` order, segments 1-3; the driven wheels are the first four.
    """

    wheel_body: NDArray[np.intp]
    wheel_jnt: NDArray[np.intp]
    wheel_dof: NDArray[np.intp]
    """qvel addresses of the six wheel hinges."""
    wheel_qpos: NDArray[np.intp]
    joint_dof: NDArray[np.intp]
    """qvel addresses of the five passive joints."""
    joint_qpos: NDArray[np.intp]
    seg_body: NDArray[np.intp]
    """Body ids of the three segments."""
    seg_root: NDArray[np.intp]
    """Root body of each segment (``subtree_com`` row of ``mj_objectVelocity``)."""
    ctrl_pos: NDArray[np.intp]
    """ctrl addresses of the driven wheels' angle setpoints."""
    ctrl_vel: NDArray[np.intp]
    """ctrl addresses of the driven wheels' speed targets."""
    sensor: Mapping[str, slice]
    """sensordata slice of each named sensor."""

    driven_dof: NDArray[np.intp]
    """qvel addresses of the driven wheels (1L 1R 2L 2R): ``wheel_dof[:4]``."""
    driven_qpos: NDArray[np.intp]

    @classmethod
    def of_model(cls, m: mujoco.MjModel) -> SimIndex:
        """The index of a model built by :func:`rover_env.sim.model.scene_xml`."""
        wheel_body = np.array([m.body(f"wheel_{w}").id for w in WHEELS])
        wheel_jnt = np.array([m.joint(f"wheel_{w}").id for w in WHEELS])
        seg_body = np.array([m.body(f"seg{i}").id for i in (1, 2, 3)])
        act = [m.actuator(f"motor_{w}").id for w in DRIVEN_WHEELS]
        ctrl_pos = m.actuator_ctrladr[act]
        wheel_dof, wheel_qpos = m.jnt_dofadr[wheel_jnt], m.jnt_qposadr[wheel_jnt]
        nd = len(DRIVEN_WHEELS)
        out = cls(
            wheel_body=wheel_body,
            wheel_jnt=wheel_jnt,
            wheel_dof=wheel_dof,
            wheel_qpos=wheel_qpos,
            joint_dof=np.array([m.jnt_dofadr[m.joint(j).id] for j in JOINTS]),
            joint_qpos=np.array([m.jnt_qposadr[m.joint(j).id] for j in JOINTS]),
            seg_body=seg_body,
            seg_root=m.body_rootid[seg_body].copy(),
            ctrl_pos=ctrl_pos,
            ctrl_vel=ctrl_pos + 1,
            driven_dof=wheel_dof[:nd],
            driven_qpos=wheel_qpos[:nd],
            sensor=MappingProxyType(
                {
                    m.sensor(i).name: slice(m.sensor_adr[i], m.sensor_adr[i] + m.sensor_dim[i])
                    for i in range(m.nsensor)
                }
            ),
        )
        for f in dataclasses.fields(out):
            v = getattr(out, f.name)
            if isinstance(v, np.ndarray):
                v.flags.writeable = False
        return out


class SimulationError(RuntimeError):
    """MuJoCo reported a warning (instability, contact overflow, ...) or the state is not finite."""


@dataclass(frozen=True)
class WheelTruth:
    """Privileged per-wheel state in ``WHEELS`` order (arrays of shape (6,) or (6, 3))."""

    S: Array
    """Slip ratio, eq. (10) with SPEC's sign: < 0 spinning, > 0 skidding."""
    S_alpha: Array
    F_x: Array
    F_y: Array
    F_z: Array
    delta: Array
    v_x: Array
    v_y: Array
    v_w: Array
    contact_point: Array
    patch: NDArray[np.int64]
    """Friction patch index: 0 default ground, i the terrain's i-th patch."""
    sinkage: Array
    """Sinkage below the loose-soil surface (m); 0 on hard ground."""
    soil: NDArray[np.int64]
    """0 on hard ground, k on the terrain's soil ``soils[k-1]`` (rover_env.soil)."""


@dataclass(frozen=True)
class SegmentTruth:
    """Per segment (seg1..seg3): pose and velocity, world frame; body-frame rates."""

    pos: Array
    quat: Array
    lin_vel: Array
    ang_vel: Array
    forward_speed: Array
    """Velocity of each segment's centre along its own x axis (m/s)."""
    yaw_rate: Array
    """Angular velocity about each segment's own z axis (rad/s)."""


@dataclass(frozen=True)
class SensorReadings:
    """What the real rover measures: potentiometers and encoders, plus an IMU per segment."""

    t: float
    phi: Array
    """Wheel angles (6,), WHEELS order, cumulative."""
    phi_dot: Array
    theta: Array
    """Joint angles theta_1..theta_5."""
    theta_dot: Array
    imu_quat: Array
    """(3, 4) attitude of each segment (w, x, y, z)."""
    imu_gyro: Array
    imu_accel: Array
