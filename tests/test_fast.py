"""The tire plugin backend (issue 5) against the numpy reference tire layer."""

from __future__ import annotations

import copy
import dataclasses
import os
import shutil

import mujoco
import numpy as np
import pytest

from rover_env.config import FrictionPatch, RoverConfig, TerrainConfig
from rover_env.sim.batch import BatchRoverSim
from rover_env.sim.fast import PluginView
from rover_env.sim.simulator import RoverSim

pytestmark = pytest.mark.skipif(
    not any(shutil.which(c) for c in (os.environ.get("CC") or "gcc", "cc")),
    reason="backend='plugin' compiles its C plugin on first use and no C compiler (gcc) is installed",
)

TOL = 1e-12
WHEEL_FIELDS = ("v_x", "v_y", "v_w", "F_x", "F_y", "F_z", "delta", "point", "normal")


@pytest.fixture(scope="module", params=["flat", "rough"])
def pair(request: pytest.FixtureRequest) -> tuple[RoverSim, RoverSim]:
    """A settled numpy-backend rover and its plugin-backend twin on one terrain."""
    return RoverSim(terrain=request.param), RoverSim(terrain=request.param, backend="plugin")


def _close(got: np.ndarray, ref: np.ndarray, scale: float, what: str) -> None:
    np.testing.assert_allclose(got, ref, rtol=TOL, atol=TOL * max(scale, 1e-300), err_msg=what)


def test_forces_match_numpy_on_random_states(pair: tuple[RoverSim, RoverSim]) -> None:
    ref_sim, fast_sim = pair
    m, mp = ref_sim.model, fast_sim.model
    pv = PluginView(mp)
    rng = np.random.default_rng(5)
    base_q, base_v = ref_sim.data.qpos.copy(), ref_sim.data.qvel.copy()
    terrain = ref_sim.terrain
    wheel_qpos = ref_sim._wheel_qpos
    in_contact = 0
    patches: set[int] = set()
    for _ in range(60):
        qpos, qvel = base_q.copy(), base_v.copy()
        # Anywhere on the arena's centre (friction patches included), ground height followed.
        xy = rng.uniform(-4.0, 4.0, 2)
        dz = terrain.height(xy[:1], xy[1:])[0] - terrain.height(base_q[:1], base_q[1:2])[0]
        qpos[:2] = xy
        qpos[2] += dz + rng.normal(0.0, 0.004)
        qpos[3:7] += rng.normal(0.0, 0.03, 4)
        qpos[3:7] /= np.linalg.norm(qpos[3:7])
        qpos[7:] += rng.normal(0.0, 0.05, m.nq - 7)
        qpos[wheel_qpos] = rng.uniform(-np.pi, np.pi, 6)
        qvel += rng.normal(0.0, 0.3, m.nv)
        qvel[ref_sim._wheel_dof] = rng.normal(0.0, 4.0, 6)
        u_x, u_y = rng.uniform(-0.03, 0.03, (2, 6))  # beyond the clamp at times

        d = mujoco.MjData(m)
        d.qpos[:], d.qvel[:] = qpos, qvel
        mujoco.mj_forward(m, d)
        layer = ref_sim.tires
        layer.u_x, layer.u_y = u_x.copy(), u_y.copy()
        layer.apply(d)
        last = layer.last
        assert last is not None

        dp = mujoco.MjData(mp)
        dp.qpos[:], dp.qvel[:] = qpos, qvel
        st = pv.state(dp.plugin_state)
        st[pv.layout.u_x], st[pv.layout.u_y] = u_x, u_y
        mujoco.mj_forward(mp, dp)

        # Generalized tire forces: the plugin adds them to qfrc_passive (springs, dampers),
        # the numpy layer writes them alone into qfrc_applied.
        applied = dp.qfrc_passive - d.qfrc_passive
        scale = max(np.abs(d.qfrc_applied).max(), np.abs(d.qfrc_passive).max())
        _close(applied, d.qfrc_applied, scale, "generalized tire forces")
        out = pv.truth(dp.plugin_state, pending=True)
        fscale = float(np.abs(last.F_z).max())
        for name in WHEEL_FIELDS:
            ref = getattr(last, name)
            scale = fscale if name.startswith("F") else float(np.abs(ref).max())
            _close(getattr(out, name), ref, scale, name)
        np.testing.assert_array_equal(out.patch, last.patch)
        ux, uy = pv.pending_u(dp.plugin_state)
        _close(ux, layer.u_x, 0.03, "u_x")
        _close(uy, layer.u_y, 0.03, "u_y")
        in_contact += int(np.sum(last.F_z > 0))
        patches.update(int(p) for p in last.patch)
    assert in_contact > 60 * 6 // 3, "too few wheels in contact to test the forces"
    if not ref_sim.terrain.flat:
        assert len(patches) > 1, "no wheel landed on a friction patch"


def test_flat_drive_matches_numpy() -> None:
    ref, fast = RoverSim(), RoverSim(backend="plugin")
    rng = np.random.default_rng(11)
    start = ref.data.qpos[:3].copy()
    for _ in range(10):  # 10 s, new targets every second
        targets = rng.uniform(0.5, 4.0, 4) * rng.choice([1.0, 1.0, -0.5], 4)
        ref.set_speed_targets(targets)
        fast.set_speed_targets(targets)
        ref.step(1000)
        fast.step(1000)
    assert np.linalg.norm(ref.data.qpos[:2] - start[:2]) > 0.5
    assert np.linalg.norm(fast.data.qpos[:3] - ref.data.qpos[:3]) < 1e-6
    np.testing.assert_allclose(fast.data.qpos, ref.data.qpos, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(fast.data.ctrl, ref.data.ctrl)  # the same setpoints
    a, b = ref.wheel_truth(), fast.wheel_truth()
    np.testing.assert_allclose(b.F_z, a.F_z, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(b.S, a.S, rtol=0, atol=1e-6)


def test_slip_floor_drive_matches_numpy() -> None:
    # TireParams.v_floor (the transient form's low-speed floor) in both backends: a slow
    # pivot-like turn, where the wheels pass below the floor.
    base = RoverConfig()
    cfg = dataclasses.replace(base, tire=dataclasses.replace(base.tire, v_floor=0.05))
    ref, fast = RoverSim(cfg), RoverSim(cfg, backend="plugin")
    plain = RoverSim(base, backend="plugin")
    for sim in (ref, fast, plain):
        sim.set_speed_targets(np.array([-0.78, -0.08, -0.78, -0.08]))
        sim.step(2000)
    np.testing.assert_allclose(fast.data.qpos, ref.data.qpos, rtol=0, atol=1e-6)
    # and it matters there: the free wheels turn differently without it
    assert (
        np.abs(fast.data.qpos[fast._wheel_qpos[4:]] - plain.data.qpos[plain._wheel_qpos[4:]]).max()
        > 0.05
    )


def test_lateral_split_pivot_matches_numpy() -> None:
    # TireParams.lateral_split (eq. 11 for every sign) in both backends: a straight, then a
    # pivot, where the driven wheels turn against their hubs' travel.
    base = RoverConfig()
    cfg = dataclasses.replace(base, tire=dataclasses.replace(base.tire, lateral_split=1.0))
    ref, fast = RoverSim(cfg), RoverSim(cfg, backend="plugin")
    plain = RoverSim(base, backend="plugin")
    for sim in (ref, fast, plain):
        sim.set_speed_targets(np.full(4, 2.45))
        sim.step(1000)
        sim.set_speed_targets(np.array([-1.5, 1.5, -1.5, 1.5]))
        sim.step(2000)
    np.testing.assert_allclose(fast.data.qpos, ref.data.qpos, rtol=0, atol=1e-6)
    # and it matters there: segment 3's free wheels roll differently without it
    free = fast._wheel_qpos[4:]
    assert np.abs(fast.data.qpos[free] - plain.data.qpos[free]).max() > 0.1


def test_setpoints_are_written_before_actuation() -> None:
    """compute() runs in mj_passive, before mj_fwdActuation reads ctrl in the same mj_forward."""
    sim = RoverSim(backend="plugin")
    m, d = sim.model, sim.data
    pv = PluginView(m)
    targets = np.array([1.0, -2.0, 3.0, 0.5])
    sim.set_speed_targets(targets)
    d.ctrl[sim._ctrl_vel] = targets
    setpoints = d.qpos[sim._driven_qpos] + np.array([0.1, -0.2, 0.7, 0.05])
    pv.set_setpoints(d.plugin_state, setpoints)
    d.ctrl[sim._ctrl_pos] = 123.0  # stale value the actuators must not see
    mujoco.mj_forward(m, d)
    q = d.qpos[sim._driven_qpos]
    err = sim.cfg.motor.max_angle_error
    expect = np.clip(setpoints + targets * sim.dt, q - err, q + err)
    np.testing.assert_array_equal(d.ctrl[sim._ctrl_pos], expect)
    assert expect[2] == q[2] + err  # the anti-windup clamp was exercised
    # The same model without the plugin, given those controls, produces the same torques.
    plain = RoverSim()
    d2 = mujoco.MjData(plain.model)
    d2.qpos[:], d2.qvel[:], d2.ctrl[:] = d.qpos, d.qvel, d.ctrl
    mujoco.mj_forward(plain.model, d2)
    np.testing.assert_array_equal(d.actuator_force, d2.actuator_force)
    assert np.abs(d.actuator_force[:4]).max() > 0.1


def test_forward_is_idempotent_and_copies_carry_the_state() -> None:
    sim = RoverSim(backend="plugin")
    m, d = sim.model, sim.data
    pv = PluginView(m)
    sim.set_speed_targets([2.0, 3.0, 2.0, 3.0])
    sim.step(100)
    committed = slice(0, pv.layout.pending)
    before = pv.state(d.plugin_state)[committed].copy()
    truth = sim.wheel_truth()
    mujoco.mj_forward(m, d)
    mujoco.mj_forward(m, d)
    np.testing.assert_array_equal(pv.state(d.plugin_state)[committed], before)
    np.testing.assert_array_equal(sim.wheel_truth().F_x, truth.F_x)
    twin = copy.copy(d)
    sim.step(200)
    mujoco.mj_step(m, twin, 200)
    np.testing.assert_array_equal(twin.qpos, d.qpos)
    np.testing.assert_array_equal(twin.plugin_state, d.plugin_state)


def test_batch_equals_separate_plugin_sims() -> None:
    n = 4
    batch = BatchRoverSim(n, nthread=2)
    sims = [RoverSim(backend="plugin") for _ in range(n)]
    rng = np.random.default_rng(2)
    for _ in range(3):
        targets = rng.uniform(-4.0, 4.0, (n, 4))
        batch.set_speed_targets(targets)
        for sim, t in zip(sims, targets, strict=True):
            sim.set_speed_targets(t)
            sim.step(200)
        batch.step(200)
    np.testing.assert_array_equal(batch.qpos, np.stack([s.data.qpos for s in sims]))
    np.testing.assert_array_equal(batch.qvel, np.stack([s.data.qvel for s in sims]))
    np.testing.assert_array_equal(batch.sensordata, np.stack([s.data.sensordata for s in sims]))
    truth = batch.wheel_truth()
    for i, sim in enumerate(sims):
        one = sim.wheel_truth()
        for name in ("F_x", "F_y", "F_z", "S", "v_w", "contact_point", "patch"):
            np.testing.assert_array_equal(getattr(truth, name)[i], getattr(one, name))
    assert len({tuple(np.round(q[:2], 6)) for q in batch.qpos}) == n  # they went different ways
    np.testing.assert_array_equal(batch.time, np.full(n, sims[0].time))


def test_set_terrain_reaches_the_plugin() -> None:
    ref, fast = RoverSim(), RoverSim(backend="plugin")
    icy = TerrainConfig(
        name="icy",
        patches=(
            FrictionPatch(name="ice", center=(0.3, 0.0), size=(1.5, 1.5), mu_x=0.1, mu_y=0.12),
        ),
    )
    for sim in (ref, fast):
        sim.set_terrain(icy)
        sim.reset()
        sim.set_speed_targets([3.0, 3.0, 3.0, 3.0])
        sim.step(1000)
    assert (fast.wheel_truth().patch == 1).any()
    np.testing.assert_allclose(fast.data.qpos, ref.data.qpos, rtol=0, atol=1e-9)
    too_many = TerrainConfig(
        name="many",
        patches=tuple(
            FrictionPatch(name=f"p{i}", center=(i, 0.0), size=(1.0, 1.0), mu_x=0.2, mu_y=0.2)
            for i in range(40)
        ),
    )
    with pytest.raises(ValueError, match="capacity"):
        fast.set_terrain(too_many)
    assert fast.terrain_cfg is icy  # refused before anything changed


def test_plugin_backend_refuses_model_extensions() -> None:
    cfg = RoverConfig()
    # RoverConfig itself refuses every extension today; bypass its check the way a future,
    # numpy-only extension would arrive, and make sure the fast path does not ignore it.
    object.__setattr__(cfg, "extensions", {"future_extension": {"gain": 1.0}})
    with pytest.raises(NotImplementedError, match="future_extension"):
        RoverSim(cfg, backend="plugin")


def test_unknown_backend_is_refused() -> None:
    with pytest.raises(ValueError, match="backend"):
        RoverSim(backend="cuda")


@pytest.mark.parametrize(
    "ext",
    [
        {"combined_slip": {"on": 1.0}},
        {"load_dependent_friction": {"fall": 0.5}},
        {"combined_slip": {"on": 1.0}, "load_dependent_friction": {"fall": 0.3}},
    ],
    ids=["combined-slip", "load-dependent-friction", "both"],
)
def test_tire_effects_run_on_the_plugin(ext: dict[str, dict[str, float]]) -> None:
    """The tire-layer extensions: plugin = numpy reference, and the effect does change the drive."""
    cfg = dataclasses.replace(RoverConfig(), extensions=ext)
    ref, fast, plain = (
        RoverSim(cfg, backend="numpy"),
        RoverSim(cfg, backend="plugin"),
        RoverSim(backend="plugin"),
    )
    assert RoverSim(cfg, backend="auto").backend == "plugin"  # no fallback to numpy
    rng = np.random.default_rng(5)
    for _ in range(4):  # 4 s of hard driving: large slip, where both effects act
        targets = rng.uniform(-4.0, 4.0, 4)
        for s in (ref, fast, plain):
            s.set_speed_targets(targets)
            s.step(1000)
    np.testing.assert_allclose(fast.data.qpos, ref.data.qpos, rtol=0, atol=1e-9)
    a, b = ref.wheel_truth(), fast.wheel_truth()
    np.testing.assert_allclose(b.F_x, a.F_x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(b.F_y, a.F_y, rtol=0, atol=1e-9)
    assert np.max(np.abs(plain.data.qpos[:3] - fast.data.qpos[:3])) > 1e-4, "effect had no effect"


@pytest.mark.parametrize(
    "ext",
    [
        {"command_lag": {"tau": 0.05}},
        {"command_delay": {"delay": 0.013}},
        {"command_lag": {"tau": 0.05}, "command_delay": {"delay": 0.013}},
    ],
    ids=["lag", "delay", "both"],
)
def test_queued_commands_equal_feeding_the_motors_substep_by_substep(
    ext: dict[str, dict[str, float]],
) -> None:
    """Command effects on the plugin: the rows queued in its state (one ``mj_step`` call per
    ``SCHEDULE_ROWS`` substeps) drive the rover exactly as writing each substep's targets
    to ``ctrl[vel]`` before a one-substep ``mj_step`` does, across blocks longer than the
    queue; the effects' own ``step``, chained in the simulator's order, gives the rows."""
    from rover_env.effects import CommandEffect, build_effects
    from rover_env.sim.fast.plugin import SCHEDULE_ROWS

    cfg = dataclasses.replace(RoverConfig(), extensions=ext)
    queued, fed, plain = (
        RoverSim(cfg, backend="plugin"),
        RoverSim(backend="plugin"),
        RoverSim(backend="plugin"),
    )
    effects = [e for e in build_effects(ext) if isinstance(e, CommandEffect)]
    assert len(effects) == len(ext)
    for e in effects:
        e.reset(np.zeros(4))
    m, d = fed.model, fed.data
    rng = np.random.default_rng(8)
    for n in (7, SCHEDULE_ROWS + 37, 1, 20):
        targets = rng.uniform(-4.0, 4.0, 4)
        for s in (queued, fed, plain):
            s.set_speed_targets(targets)
        queued.step(n)
        plain.step(n)
        for _ in range(n):
            u = fed.speed_targets.copy()
            for e in effects:
                u = e.step(u, fed.dt)
            d.ctrl[fed._ctrl_vel] = u
            mujoco.mj_step(m, d, 1)
    pv = PluginView(queued.model)
    assert pv.queued_left(queued.data.plugin_state) == 0
    np.testing.assert_array_equal(queued.data.qpos, fed.data.qpos)
    np.testing.assert_array_equal(queued.data.qvel, fed.data.qvel)
    np.testing.assert_array_equal(queued.data.ctrl, fed.data.ctrl)
    np.testing.assert_array_equal(queued.wheel_truth().F_x, fed.wheel_truth().F_x)
    assert np.max(np.abs(plain.data.qpos[:3] - queued.data.qpos[:3])) > 1e-4, "no effect"


def test_queue_refuses_rows_it_cannot_hold() -> None:
    from rover_env.sim.fast.plugin import SCHEDULE_ROWS

    sim = RoverSim(backend="plugin")
    pv = PluginView(sim.model)
    for bad in (np.zeros((SCHEDULE_ROWS + 1, 4)), np.zeros((3, 5)), np.zeros((0, 4))):
        with pytest.raises(ValueError, match="queue_commands"):
            pv.queue_commands(sim.data.plugin_state, bad)
    assert pv.queued_left(sim.data.plugin_state) == 0
