"""Joint-chain kinematics of the three-segment rover and kinematic slip (SPEC §2, eqs. 1–10).

The real rover measures only wheel angles (encoders) and joint angles (potentiometers).
Segment 3's free wheels give its own forward speed and yaw rate (eq. 1); the joint angles
and rates carry that motion forward through the chain to segments 2 and 1 (eqs. 2–6); each
driven wheel's no-slip rate follows from its own segment's motion (eqs. 7, 8), and the
measured rate minus it is the slippage (9), from which the slip ratio (10) follows.

Layout (mirrors ``rover_env.sim.model``, all numbers from the :class:`RoverConfig`): each
segment's origin is its axle centre; a child segment's origin sits at ``c = (-axle_spacing,
0, 0)`` in its parent's axes when its joints are zero; its joints share one anchor ``j =
(joint_offset, 0, joint_height)`` in the child's axes and compose in the order of SPEC §1's table,
``R_child = R_parent · R_a(θ_a) · R_b(θ_b) ...``. The paper's link vectors are the two
pieces of ``c``: ``a = c + j`` (parent origin → anchor, parent axes) and ``b = -j``
(anchor → child origin, child axes).

Everything here is numpy only and vectorised: leading axes of the inputs are sample axes
and broadcast. Vectors of a segment are returned in that segment's *own* axes (SPEC §2:
segments can be tens of degrees apart in yaw, so another segment's axes are never used).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from rover_env.config import JOINTS, RoverConfig
from rover_env.tire import slip_ratio as _tire_slip_ratio

__all__ = [
    "JOINT_AXES",
    "SEGMENT_JOINTS",
    "ChainGeometry",
    "ChainMotion",
    "axis_rotation",
    "chain_motion",
    "coupling_rotations",
    "nominal_wheel_rates",
    "rot_x",
    "rot_y",
    "rot_z",
    "segment3_twist",
    "segment_orientations",
    "segment_positions",
    "slip_ratio",
    "slippage",
]

Array = npt.NDArray[np.float64]

JOINT_AXES: dict[str, str] = {
    "theta_1": "x",
    "theta_2": "z",
    "theta_3": "x",
    "theta_4": "y",
    "theta_5": "z",
}
"""SPEC §1's table: roll x, yaw z between segments 1–2; roll x, pitch y, yaw z between 2–3."""

SEGMENT_JOINTS: dict[int, tuple[str, ...]] = {
    2: ("theta_1", "theta_2"),
    3: ("theta_3", "theta_4", "theta_5"),
}
"""The joints that place each child segment relative to its parent (seg1 → 2 → 3), in order."""

_UNIT = {"x": 0, "y": 1, "z": 2}


def _rot(angle: npt.ArrayLike, axis: int) -> Array:
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((*a.shape, 3, 3))
    i, j = [k for k in range(3) if k != axis]
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    # For the y axis the cyclic order (z, x) flips the sign of the off-diagonal terms.
    if axis == 1:
        out[..., i, j] = s
        out[..., j, i] = -s
    return out


def rot_x(angle: npt.ArrayLike) -> Array:
    """Right-handed rotation about x, shape ``angle.shape + (3, 3)``."""
    return _rot(angle, 0)


def rot_y(angle: npt.ArrayLike) -> Array:
    """Right-handed rotation about y, shape ``angle.shape + (3, 3)``."""
    return _rot(angle, 1)


def rot_z(angle: npt.ArrayLike) -> Array:
    """Right-handed rotation about z, shape ``angle.shape + (3, 3)``."""
    return _rot(angle, 2)


def axis_rotation(axis: str, angle: npt.ArrayLike) -> Array:
    """Rotation about the named body axis ('x', 'y' or 'z')."""
    return _rot(angle, _UNIT[axis])


@dataclass(frozen=True)
class ChainGeometry:
    """The numbers the kinematics needs, taken from a :class:`RoverConfig`.

    ``wheel_radii`` convert wheel rates to speeds, one per wheel in WHEELS order (the
    estimator passes its effective rolling radii); lengths in metres, x forward, y left, z up.
    """

    half_track: float
    wheel_radii: tuple[float, ...]
    child_offset: tuple[float, float, float]
    """c: a child segment's origin in its parent's axes with its joints at zero."""
    joint_anchor: tuple[float, float, float]
    """j: the coupling joints' common anchor in the child segment's axes."""

    def __post_init__(self) -> None:
        radii = tuple(float(r) for r in self.wheel_radii)
        if len(radii) != 6 or not all(np.isfinite(r) and r > 0 for r in radii):
            raise ValueError(f"wheel_radii must be 6 finite numbers > 0, got {self.wheel_radii!r}")
        object.__setattr__(self, "wheel_radii", radii)

    @classmethod
    def from_config(
        cls, cfg: RoverConfig, wheel_radius: npt.ArrayLike | None = None
    ) -> ChainGeometry:
        """Geometry of ``cfg``; ``wheel_radius`` (one, or one per wheel) defaults to d."""
        g = cfg.geometry
        r = np.broadcast_to(
            np.asarray(g.wheel_radius if wheel_radius is None else wheel_radius, dtype=float), (6,)
        )
        return cls(
            half_track=g.half_track,
            wheel_radii=tuple(float(x) for x in r),
            child_offset=(-g.axle_spacing, 0.0, 0.0),
            joint_anchor=(g.joint_offset, 0.0, g.joint_height),
        )

    @property
    def link_a(self) -> Array:
        """Parent origin → joint anchor, in the parent's axes (the paper's a_i)."""
        return np.add(self.child_offset, self.joint_anchor)

    @property
    def link_b(self) -> Array:
        """Joint anchor → child origin, in the child's axes (the paper's b_i)."""
        return -np.asarray(self.joint_anchor, dtype=np.float64)


def _joint_index(name: str) -> int:
    return JOINTS.index(name)


def coupling_rotations(theta: npt.ArrayLike) -> dict[int, Array]:
    """Child-in-parent rotation of each coupling: {2: R_12, 3: R_23}, each (..., 3, 3)."""
    th = np.asarray(theta, dtype=np.float64)
    out: dict[int, Array] = {}
    for child, names in SEGMENT_JOINTS.items():
        r = np.broadcast_to(np.eye(3), (*th.shape[:-1], 3, 3)).copy()
        for name in names:
            r = r @ axis_rotation(JOINT_AXES[name], th[..., _joint_index(name)])
        out[child] = r
    return out


def segment_orientations(theta: npt.ArrayLike) -> Array:
    """Orientation Q_n of segments 1..3 in segment 3's axes, shape (..., 3, 3, 3).

    Segment 3 is the reference because eq. (1) gives its motion in its own axes; the
    planar pose of the whole rover is only dead-reckoned, never needed here.
    """
    rc = coupling_rotations(theta)
    q3 = np.broadcast_to(np.eye(3), rc[3].shape).copy()
    q2 = np.swapaxes(rc[3], -1, -2)
    q1 = q2 @ np.swapaxes(rc[2], -1, -2)
    return np.stack([q1, q2, q3], axis=-3)


def segment_positions(theta: npt.ArrayLike, chain: ChainGeometry) -> Array:
    """Origins of segments 1..3 in segment 3's frame (segment 3 at 0), shape (..., 3, 3).

    Used to check the velocity propagation against finite differences of positions.
    """
    q = segment_orientations(theta)
    a, j = chain.link_a, np.asarray(chain.joint_anchor, dtype=np.float64)
    p3 = np.zeros((*q.shape[:-3], 3))
    p2 = p3 + q[..., 2, :, :] @ j - q[..., 1, :, :] @ a
    p1 = p2 + q[..., 1, :, :] @ j - q[..., 0, :, :] @ a
    return np.stack([p1, p2, p3], axis=-2)


def _joint_axes_in_child(theta: Array, names: tuple[str, ...]) -> list[Array]:
    """Unit axis of each joint of one coupling, in the child's axes (..., 3) per joint."""
    axes: list[Array] = []
    for k, name in enumerate(names):
        # Joint k turns about e_k of the frame after joints 0..k-1; in the child's axes
        # that is (A_{k+1} ... A_m)^T e_k = A_m^T ... A_{k+1}^T e_k: apply A_{k+1}^T first.
        e = np.zeros(3)
        e[_UNIT[JOINT_AXES[name]]] = 1.0
        v = np.broadcast_to(e, (*theta.shape[:-1], 3)).copy()
        for later in names[k + 1 :]:
            r = axis_rotation(JOINT_AXES[later], theta[..., _joint_index(later)])
            v = np.einsum("...ji,...j->...i", r, v)
        axes.append(v)
    return axes


def segment3_twist(phi_dot_free: npt.ArrayLike, chain: ChainGeometry) -> tuple[Array, Array]:
    """Eq. (1): angular and linear velocity (..., 3) of segment 3 in its own axes.

    ``phi_dot_free`` is (..., 2): rates of 3L and 3R. The free wheels are taken not to slip
    and the segment not to slide sideways, pitch or roll: all the paper's model knows.
    """
    pd = np.asarray(phi_dot_free, dtype=np.float64)
    # Tread speeds d * phi_dot, with each free wheel's own rolling radius.
    left = chain.wheel_radii[4] * pd[..., 0]
    right = chain.wheel_radii[5] * pd[..., 1]
    r = chain.half_track
    w = np.zeros((*pd.shape[:-1], 3))
    v = np.zeros((*pd.shape[:-1], 3))
    w[..., 2] = (right - left) / (2.0 * r)
    v[..., 0] = (right + left) / 2.0
    return w, v


class ChainMotion(NamedTuple):
    """Velocities of segments 1..3, each in its own axes, shape (..., 3, 3) [segment, xyz]."""

    omega: Array
    velocity: Array

    @property
    def forward_speed(self) -> Array:
        """v_x of each segment's centre along its own x axis (..., 3)."""
        return self.velocity[..., 0]

    @property
    def yaw_rate(self) -> Array:
        """Angular velocity about each segment's own z axis (..., 3)."""
        return self.omega[..., 2]


def chain_motion(
    omega3: npt.ArrayLike,
    v3: npt.ArrayLike,
    theta: npt.ArrayLike,
    theta_dot: npt.ArrayLike,
    chain: ChainGeometry,
) -> ChainMotion:
    """Eqs. (2)–(6): carry segment 3's motion forward through joints 5, 4, 3 and 2, 1.

    Across a coupling with anchor P, coming from the child (known) to the parent:
    ω_parent = ω_child − Σ θ̇_i axis_i and v_P = v_child + ω_child × (P − p_child),
    v_parent = v_P + ω_parent × (p_parent − P): rigid-body velocity transfer, computed in
    segment 3's axes and rotated into each segment's own axes at the end.
    """
    th = np.asarray(theta, dtype=np.float64)
    thd = np.asarray(theta_dot, dtype=np.float64)
    w3 = np.asarray(omega3, dtype=np.float64)
    v3_ = np.asarray(v3, dtype=np.float64)
    shape = np.broadcast_shapes(th.shape[:-1], thd.shape[:-1], w3.shape[:-1], v3_.shape[:-1])
    th = np.broadcast_to(th, (*shape, 5))
    thd = np.broadcast_to(thd, (*shape, 5))
    q = segment_orientations(th)
    a, j = chain.link_a, np.asarray(chain.joint_anchor, dtype=np.float64)

    omega = [np.broadcast_to(w3, (*shape, 3))]
    vel = [np.broadcast_to(v3_, (*shape, 3))]
    # child index in q: seg n -> n - 1; walk seg3 -> seg2 -> seg1.
    for child in (3, 2):
        qc, qp = q[..., child - 1, :, :], q[..., child - 2, :, :]
        names = SEGMENT_JOINTS[child]
        w_c, v_c = omega[-1], vel[-1]
        w_rel = np.zeros((*shape, 3))
        for name, ax in zip(names, _joint_axes_in_child(th, names), strict=True):
            w_rel = w_rel + ax * thd[..., _joint_index(name), None]
        w_p = w_c - np.einsum("...ij,...j->...i", qc, w_rel)
        v_anchor = v_c + np.cross(w_c, qc @ j)
        v_p = v_anchor + np.cross(w_p, -(qp @ a))
        omega.append(w_p)
        vel.append(v_p)
    w_all = np.stack(omega[::-1], axis=-2)
    v_all = np.stack(vel[::-1], axis=-2)
    # Into each segment's own axes: x_own = Q_n^T x.
    w_own = np.einsum("...nji,...nj->...ni", q, w_all)
    v_own = np.einsum("...nji,...nj->...ni", q, v_all)
    return ChainMotion(omega=w_own, velocity=v_own)


def nominal_wheel_rates(motion: ChainMotion, chain: ChainGeometry) -> Array:
    """Eqs. (7), (8): no-slip rates (..., 4) of 1L 1R 2L 2R from each segment's own motion.

    The hub of the left wheel moves at v + ω × (+r j), the right at v + ω × (−r j); only the
    forward (i) component rolls the wheel: (v_x ∓ r ω_z) / d in the segment's own axes.
    """
    r = chain.half_track
    vx = motion.velocity[..., :2, 0]
    wz = motion.omega[..., :2, 2]
    left = vx - r * wz
    right = vx + r * wz
    hub = np.stack([left[..., 0], right[..., 0], left[..., 1], right[..., 1]], axis=-1)
    return np.asarray(hub / np.asarray(chain.wheel_radii[:4]), dtype=np.float64)


def slippage(actual_rate: npt.ArrayLike, nominal_rate: npt.ArrayLike) -> Array:
    """Eq. (9): measured minus no-slip wheel rate (rad/s); > 0 the wheel spins ahead."""
    return np.subtract(actual_rate, nominal_rate, dtype=np.float64)


def slip_ratio(
    actual_rate: npt.ArrayLike,
    nominal_rate: npt.ArrayLike,
    wheel_radius: npt.ArrayLike,
    v_eps: float = 1e-3,
) -> Array:
    """Eq. (10) with SPEC §3's sign (< 0 spinning, > 0 skidding), via ``rover_env.tire``.

    v_x = d·φ̇_nominal (the hub's travel) and v_w = d·φ̇_actual (the tread's speed);
    ``wheel_radius`` is one radius or one per wheel (broadcast against the rates).
    """
    d = np.asarray(wheel_radius, dtype=np.float64)
    vx = d * np.asarray(nominal_rate, dtype=np.float64)
    vw = d * np.asarray(actual_rate, dtype=np.float64)
    return _tire_slip_ratio(vx, vw, v_eps)
