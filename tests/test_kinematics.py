"""Joint-chain kinematics and kinematic slip (issue 3): closed forms and finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rover_env import kinematics as kin
from rover_env.config import RoverConfig, load_rover
from rover_env.tire import slip_ratio as tire_slip_ratio


@pytest.fixture(scope="module")
def cfg() -> RoverConfig:
    return load_rover()


@pytest.fixture(scope="module")
def chain(cfg: RoverConfig) -> kin.ChainGeometry:
    return kin.ChainGeometry.from_config(cfg, 0.06)


def _skew_to_vec(w: np.ndarray) -> np.ndarray:
    return np.array([w[2, 1], w[0, 2], w[1, 0]])


# --------------------------------------------------------------------------- rotations


def test_rotations_are_right_handed() -> None:
    e = np.eye(3)
    q = np.pi / 2
    np.testing.assert_allclose(kin.rot_z(q) @ e[0], e[1], atol=1e-15)
    np.testing.assert_allclose(kin.rot_x(q) @ e[1], e[2], atol=1e-15)
    np.testing.assert_allclose(kin.rot_y(q) @ e[2], e[0], atol=1e-15)
    for f in (kin.rot_x, kin.rot_y, kin.rot_z):
        r = f(np.array([0.3, -1.2]))
        assert r.shape == (2, 3, 3)
        np.testing.assert_allclose(
            r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-14
        )
        np.testing.assert_allclose(np.linalg.det(r), 1.0)


def test_joint_table_matches_the_simulator_model() -> None:
    from rover_env.sim import model

    named = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}
    assert {j: named[a] for j, a in kin.JOINT_AXES.items()} == model.JOINT_AXES
    assert kin.SEGMENT_JOINTS == model.SEGMENT_JOINTS


def test_chain_geometry_comes_from_the_config() -> None:
    cfg = RoverConfig()
    g = cfg.geometry
    other = RoverConfig(geometry=type(g)(axle_spacing=0.5, half_track=0.3))
    ch = kin.ChainGeometry.from_config(other)
    assert ch.child_offset == (-0.5, 0.0, 0.0)
    assert ch.joint_anchor == (0.25, 0.0, 0.0)
    assert ch.half_track == 0.3
    assert ch.wheel_radii == (g.wheel_radius,) * 6
    with pytest.raises(ValueError):
        kin.ChainGeometry.from_config(cfg, [0.05] * 5)


def test_orientations_compose_in_spec_order() -> None:
    th = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    q = kin.segment_orientations(th)
    r12 = kin.rot_x(0.1) @ kin.rot_z(0.2)
    r23 = kin.rot_x(0.3) @ kin.rot_y(0.4) @ kin.rot_z(0.5)
    # R_3 = R_1 R12 R23 with segment 3 the reference: Q_1 = (R12 R23)^T, Q_2 = R23^T.
    np.testing.assert_allclose(q[2], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(q[1], r23.T, atol=1e-15)
    np.testing.assert_allclose(q[0], (r12 @ r23).T, atol=1e-15)


def test_positions_at_zero_angles(cfg: RoverConfig, chain: kin.ChainGeometry) -> None:
    L = cfg.geometry.axle_spacing
    p = kin.segment_positions(np.zeros(5), chain)
    expected = np.array([[2 * L, 0, 0], [L, 0, 0], [0, 0, 0]], dtype=float)
    np.testing.assert_allclose(p, expected, atol=1e-15)


def test_yaw_joint_swings_segment_about_its_anchor(cfg: RoverConfig, chain) -> None:
    """theta_5 alone: segments 1, 2 rotate rigidly about the 2-3 anchor (left for +theta_5 seen
    from segment 2 means segment 3 is yawed left of segment 2, so segment 2 lies to its right)."""
    L, j = cfg.geometry.axle_spacing, cfg.geometry.joint_offset
    a = 0.4
    p = kin.segment_positions(np.array([0, 0, 0, 0, a]), chain)
    anchor = np.array([j, 0, 0])
    # Segment 2's centre is (L - j) ahead of the anchor along segment 2's own x axis,
    # which is rotated by -a in segment 3's axes.
    u2 = np.array([np.cos(-a), np.sin(-a), 0])
    np.testing.assert_allclose(p[1], anchor + (L - j) * u2, atol=1e-15)
    np.testing.assert_allclose(p[0], anchor + (2 * L - j) * u2, atol=1e-15)


# --------------------------------------------------------------------------- eq. (1)


def test_segment3_twist_eq1(chain: kin.ChainGeometry) -> None:
    d, r = chain.wheel_radii[4], chain.half_track
    w, v = kin.segment3_twist(np.array([[1.5, 2.5], [2.0, 2.0]]), chain)
    np.testing.assert_allclose(w[0], [0, 0, d * (2.5 - 1.5) / (2 * r)])
    np.testing.assert_allclose(v[0], [d * (2.5 + 1.5) / 2, 0, 0])
    np.testing.assert_allclose(w[1], 0)


# --------------------------------------------------------------------------- closed forms


def test_straight_line_all_rates_equal_and_no_slip(chain: kin.ChainGeometry) -> None:
    rate = 2.3
    w3, v3 = kin.segment3_twist(np.array([rate, rate]), chain)
    m = kin.chain_motion(w3, v3, np.zeros(5), np.zeros(5), chain)
    d = chain.wheel_radii[0]
    np.testing.assert_allclose(m.velocity, [[d * rate, 0, 0]] * 3, atol=1e-15)
    np.testing.assert_allclose(m.omega, 0, atol=1e-15)
    nominal = kin.nominal_wheel_rates(m, chain)
    np.testing.assert_allclose(nominal, rate)
    np.testing.assert_allclose(kin.slippage(np.full(4, rate), nominal), 0, atol=1e-15)
    np.testing.assert_allclose(kin.slip_ratio(np.full(4, rate), nominal, d), 0, atol=1e-15)


def test_constant_radius_turn_of_the_straight_chain(cfg: RoverConfig, chain) -> None:
    """Joints locked at zero: the chain is one rigid body turning about segment 3's ICR."""
    L, r, d = cfg.geometry.axle_spacing, chain.half_track, chain.wheel_radii[0]
    left, right = 1.6, 2.4
    omega = d * (right - left) / (2 * r)
    radius = r * (right + left) / (right - left)  # ICR to segment 3's centre
    w3, v3 = kin.segment3_twist(np.array([left, right]), chain)
    m = kin.chain_motion(w3, v3, np.zeros(5), np.zeros(5), chain)
    np.testing.assert_allclose(m.yaw_rate, omega)
    np.testing.assert_allclose(m.forward_speed, omega * radius)
    # Segments ahead of the ICR line slide sideways: lever arm 2L (segment 1), L (segment 2).
    np.testing.assert_allclose(m.velocity[:, 1], [2 * L * omega, L * omega, 0], atol=1e-15)
    # Inner (left) and outer (right) no-slip rates: omega (R -+ r) / d, the free wheels' rates.
    nominal = kin.nominal_wheel_rates(m, chain)
    np.testing.assert_allclose(nominal, [omega * (radius - r) / d, omega * (radius + r) / d] * 2)
    np.testing.assert_allclose(nominal, [left, right, left, right])


def test_steady_articulated_turn_matches_rigid_rotation(chain) -> None:
    """Constant joint angles: every segment turns at segment 3's rate about the same ICR."""
    th = np.array([0.05, 0.3, -0.04, 0.02, 0.25])
    w3, v3 = kin.segment3_twist(np.array([1.7, 2.2]), chain)
    m = kin.chain_motion(w3, v3, th, np.zeros(5), chain)
    q = kin.segment_orientations(th)
    p = kin.segment_positions(th, chain)
    icr = np.array([0.0, v3[0] / w3[2], 0.0])
    for n in range(3):
        np.testing.assert_allclose(q[n] @ m.omega[n], w3, atol=1e-14)
        np.testing.assert_allclose(q[n] @ m.velocity[n], np.cross(w3, p[n] - icr), atol=1e-14)


def test_theta2_alone_swings_segment1_about_the_joint(cfg: RoverConfig, chain) -> None:
    """Segment 3 at rest, only theta_2 turning: segment 2 stays still and segment 1 moves as
    omega x lever arm, the lever being the anchor-to-axle distance along its own x axis."""
    lever = cfg.geometry.axle_spacing - cfg.geometry.joint_offset
    for theta2 in (0.0, 0.35):
        rate = 0.7
        th = np.array([0.0, theta2, 0.0, 0.0, 0.0])
        m = kin.chain_motion(np.zeros(3), np.zeros(3), th, np.array([0, rate, 0, 0, 0]), chain)
        np.testing.assert_allclose(m.velocity[1:], 0, atol=1e-15)
        np.testing.assert_allclose(m.omega[1:], 0, atol=1e-15)
        # Segment 1 turns by -theta_2 relative to segment 2 (R_2 = R_1 Rz(theta_2)).
        np.testing.assert_allclose(m.omega[0], [0, 0, -rate], atol=1e-15)
        np.testing.assert_allclose(m.velocity[0], [0, -rate * lever, 0], atol=1e-15)
        # Its wheels' no-slip rates: -+ r * yaw rate over d.
        r, d = chain.half_track, chain.wheel_radii[0]
        nominal = kin.nominal_wheel_rates(m, chain)
        np.testing.assert_allclose(nominal[:2], [r * rate / d, -r * rate / d])


def test_theta4_alone_pitches_the_front_segments(cfg: RoverConfig, chain) -> None:
    L, j = cfg.geometry.axle_spacing, cfg.geometry.joint_offset
    rate = -0.4
    m = kin.chain_motion(np.zeros(3), np.zeros(3), np.zeros(5), [0, 0, 0, rate, 0], chain)
    # Rotation -rate about y through the 2-3 anchor; segment 2's centre is (L - j) ahead of it.
    np.testing.assert_allclose(m.omega[:2], [[0, -rate, 0]] * 2, atol=1e-15)
    np.testing.assert_allclose(m.velocity[1], [0, 0, rate * (L - j)], atol=1e-15)
    np.testing.assert_allclose(m.velocity[0], [0, 0, rate * (2 * L - j)], atol=1e-15)


# --------------------------------------------------------------------------- finite differences


@settings(max_examples=40, deadline=None)
@given(
    th=st.lists(st.floats(-0.7, 0.7), min_size=5, max_size=5),
    thd=st.lists(st.floats(-1.0, 1.0), min_size=5, max_size=5),
    w3=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    v3=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
)
def test_velocity_propagation_matches_finite_differences(th, thd, w3, v3) -> None:
    """Eqs. (2)-(6) against differentiated forward kinematics of the whole 3-D chain."""
    chain = kin.ChainGeometry.from_config(RoverConfig())
    th0, thd_, w, v = (np.array(x, dtype=float) for x in (th, thd, w3, v3))

    def pose(t: float) -> tuple[np.ndarray, np.ndarray]:
        # Segment 3 moves with constant body twist (w, v); at t = 0 it is the reference frame.
        ang = np.linalg.norm(w) * t
        k = w / np.linalg.norm(w) if np.linalg.norm(w) > 0 else np.zeros(3)
        kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        r3 = np.eye(3) + np.sin(ang) * kx + (1 - np.cos(ang)) * kx @ kx
        thi = th0 + thd_ * t
        q = kin.segment_orientations(thi)
        p = kin.segment_positions(thi, chain)
        return r3 @ q, v * t + p @ r3.T

    h = 1e-6
    (rp, pp), (rm, pm) = pose(h), pose(-h)
    r0, _ = pose(0.0)
    m = kin.chain_motion(w, v, th0, thd_, chain)
    for n in range(3):
        w_fd = _skew_to_vec(r0[n].T @ (rp[n] - rm[n]) / (2 * h))
        v_fd = r0[n].T @ (pp[n] - pm[n]) / (2 * h)
        np.testing.assert_allclose(m.omega[n], w_fd, atol=1e-7)
        np.testing.assert_allclose(m.velocity[n], v_fd, atol=1e-7)


def test_vectorised_over_samples(chain) -> None:
    rng = np.random.default_rng(3)
    th = rng.uniform(-0.5, 0.5, (7, 5))
    thd = rng.uniform(-1, 1, (7, 5))
    pd = rng.uniform(0.5, 3, (7, 2))
    w3, v3 = kin.segment3_twist(pd, chain)
    batch = kin.chain_motion(w3, v3, th, thd, chain)
    nominal = kin.nominal_wheel_rates(batch, chain)
    assert batch.velocity.shape == (7, 3, 3) and nominal.shape == (7, 4)
    for i in range(7):
        one = kin.chain_motion(w3[i], v3[i], th[i], thd[i], chain)
        np.testing.assert_allclose(one.velocity, batch.velocity[i], atol=1e-15)
        np.testing.assert_allclose(kin.nominal_wheel_rates(one, chain), nominal[i], atol=1e-15)


# --------------------------------------------------------------------------- eqs. (9), (10)


def test_slip_ratio_sign_convention() -> None:
    d = 0.06
    nominal = np.array([2.0, 2.0, -2.0, -2.0])
    actual = np.array([2.5, 1.5, -2.5, -1.5])
    s = kin.slip_ratio(actual, nominal, d)
    # Spinning (tread faster than travel) is negative, skidding positive, either direction.
    assert s[0] < 0 and s[1] > 0 and s[2] < 0 and s[3] > 0
    np.testing.assert_allclose(s[:2], [(2.0 - 2.5) / 2.5, (2.0 - 1.5) / 2.0])
    np.testing.assert_allclose(s, tire_slip_ratio(d * nominal, d * actual, 1e-3))
    np.testing.assert_allclose(kin.slippage(actual, nominal), actual - nominal)
    # Per-wheel radii broadcast.
    radii = np.array([0.05, 0.06, 0.07, 0.08])
    np.testing.assert_allclose(
        kin.slip_ratio(actual, nominal, radii),
        tire_slip_ratio(radii * nominal, radii * actual, 1e-3),
    )


def test_per_wheel_radii_enter_eq1_and_eq7(cfg: RoverConfig) -> None:
    radii = (0.050, 0.051, 0.052, 0.053, 0.054, 0.056)
    ch = kin.ChainGeometry.from_config(cfg, radii)
    w3, v3 = kin.segment3_twist(np.array([2.0, 2.0]), ch)
    # Equal rates on unequal free wheels: the tread speeds differ, so segment 3 turns.
    assert v3[0] == pytest.approx(0.054 + 0.056)
    assert w3[2] == pytest.approx((0.056 - 0.054) * 2.0 / (2 * ch.half_track))
    m = kin.chain_motion(np.zeros(3), np.array([1.0, 0, 0]), np.zeros(5), np.zeros(5), ch)
    np.testing.assert_allclose(kin.nominal_wheel_rates(m, ch), 1.0 / np.array(radii[:4]))


@pytest.mark.parametrize("joint_height", [0.0, 0.05])
def test_segment_positions_match_the_simulator_bodies(joint_height: float) -> None:
    """The chain here and the MJCF built from the same configuration place the segments
    alike at any joint angles, with the joints on the axle line or above it
    (``geometry.joint_height``): a height set in one and not the other shows here."""
    from dataclasses import replace

    import mujoco

    from rover_env.sim.model import robot_xml

    base = load_rover()
    cfg = replace(base, geometry=replace(base.geometry, joint_height=joint_height))
    m = mujoco.MjModel.from_xml_string(robot_xml(cfg))
    d = mujoco.MjData(m)
    chain = kin.ChainGeometry.from_config(cfg)
    rng = np.random.default_rng(3)
    for _ in range(5):
        th = rng.uniform(-0.4, 0.4, 5)
        for j, v in zip(kin.JOINTS, th, strict=True):
            d.qpos[m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)]] = v
        mujoco.mj_kinematics(m, d)
        seg = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"seg{i}") for i in (1, 2, 3)]
        r3 = d.xmat[seg[2]].reshape(3, 3)
        sim = np.array([r3.T @ (d.xpos[b] - d.xpos[seg[2]]) for b in seg])
        np.testing.assert_allclose(kin.segment_positions(th, chain), sim, atol=1e-9)
    # the height matters: a pitch of theta_4 lifts segment 2 about a higher anchor
    pitched = np.array([0, 0, 0, 0.3, 0])
    on_axle = kin.ChainGeometry.from_config(base)
    shift = kin.segment_positions(pitched, chain) - kin.segment_positions(pitched, on_axle)
    assert (np.abs(shift).max() > 0.005) == (joint_height != 0.0)
