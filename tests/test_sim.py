"""Acceptance checks of the simulation core (issue 2): statics, parking, driving, rig, scenes."""

from __future__ import annotations

import filecmp
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from rover_env.config import assets_dir, configs_dir, load_rover
from rover_env.sim.model import static_deflection, write_assets
from rover_env.sim.rig import measure_fx
from rover_env.sim.simulator import FRICTION_DOF, RoverSim
from rover_env.tire import TireParams, tire_forces

G = 9.81


@pytest.fixture(scope="module")
def cfg():
    return load_rover()


def test_masses_match_table_2(cfg) -> None:
    assert cfg.masses.total == pytest.approx(16.4, abs=1e-9)
    sim = RoverSim(cfg)
    assert float(np.sum(sim.model.body_mass)) == pytest.approx(16.4, abs=1e-9)


def test_assets_are_generated_from_the_default_config(tmp_path: Path, cfg) -> None:
    written = write_assets(tmp_path, cfg)
    for p in written:
        shipped = assets_dir() / p.name
        assert shipped.exists(), f"{shipped} missing: run `rover-env build-assets`"
        assert filecmp.cmp(p, shipped, shallow=False), (
            f"{shipped} is stale: run `rover-env build-assets`"
        )


@pytest.mark.parametrize("scene", ["scene_flat.xml", "scene_rough.xml"])
def test_scene_files_compile_and_step_without_warnings(scene: str) -> None:
    model = mujoco.MjModel.from_xml_path(str(assets_dir() / scene))
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, 200)
    assert all(data.warning[i].number == 0 for i in range(len(data.warning)))


@pytest.mark.parametrize(
    "terrain", sorted(p.stem for p in (configs_dir() / "terrain").glob("*.yaml"))
)
def test_every_terrain_builds_and_steps_with_tires(terrain: str) -> None:
    sim = RoverSim(terrain=terrain)  # settles 0.5 s; RoverSim.step raises on any MuJoCo warning
    sim.set_speed_targets([2.0, 2.0, 2.0, 2.0])
    sim.step(500)
    assert not sim.flipped()
    assert np.all(sim.wheel_truth().F_z > 0)


def test_at_rest_weight_deflection_and_creep(cfg) -> None:
    sim = RoverSim(cfg)
    wt = sim.wheel_truth()
    assert wt.F_z.sum() == pytest.approx(cfg.masses.total * G, rel=0.01)
    np.testing.assert_allclose(wt.delta, wt.F_z / cfg.tire.C_z, rtol=0.01)
    p0 = sim.segment_truth().pos
    sim.step(10_000)
    creep = np.linalg.norm(sim.segment_truth().pos - p0, axis=1)
    assert creep.max() < 1e-3, creep


def test_parked_on_10_degree_slope_creeps_under_1_cm() -> None:
    sim = RoverSim(terrain="slope10", rover="proto_explorer")
    p0 = sim.segment_truth().pos
    sim.step(10_000)
    creep = np.linalg.norm(sim.segment_truth().pos - p0, axis=1)
    assert creep.max() < 0.01, creep


def test_equal_targets_drive_straight() -> None:
    sim = RoverSim()
    sim.set_speed_targets([4.0, 4.0, 4.0, 4.0])
    p0 = sim.segment_truth().pos[1].copy()
    while np.linalg.norm(sim.segment_truth().pos[1, :2] - p0[:2]) < 10.0:
        sim.step(1000)
        assert sim.time < 80, "rover did not travel 10 m"
    p = sim.segment_truth().pos[1]
    assert abs(p[1] - p0[1]) < 0.01 * (p[0] - p0[0])


def test_flat_drive_is_the_same_without_mujoco_contacts() -> None:
    """The calibration replay runs with ``contacts=False``: on flat ground MuJoCo's own
    contacts (chassis on ground, wheel on wheel) must never fire, so a drive with turns is
    identical to the bit; a rover that bottomed out or a wheel hitting a wheel would differ."""
    runs = []
    for contacts in (True, False):
        sim = RoverSim(backend="auto", contacts=contacts)
        for targets in ([3.0, 3.0, 3.0, 3.0], [-2.0, 4.0, -2.0, 4.0], [4.0, 1.0, 4.0, 1.0]):
            sim.set_speed_targets(targets)
            sim.step(1500)
        runs.append(np.concatenate([sim.data.qpos, sim.data.qvel]))
        assert sim.data.ncon == 0
    np.testing.assert_array_equal(runs[0], runs[1])


@pytest.mark.parametrize("backend", ["numpy", "plugin"])
def test_state_is_the_same_without_the_sensor_stage(backend: str) -> None:
    """The calibration replay runs with ``sensors=False`` (no accelerometer pass): the state
    must not depend on MuJoCo's sensor stage, in either tire backend; a tire layer reading
    ``sensordata`` would differ. ``sensors()`` then refuses rather than return stale data."""
    runs = []
    for sensors in (True, False):
        sim = RoverSim(backend=backend, contacts=False, sensors=sensors)
        for targets in ([3.0, 3.0, 3.0, 3.0], [-2.0, 4.0, -2.0, 4.0]):
            sim.set_speed_targets(targets)
            sim.step(600)
        runs.append(np.concatenate([sim.data.qpos, sim.data.qvel]))
    np.testing.assert_array_equal(runs[0], runs[1])
    with pytest.raises(RuntimeError, match="sensors=False"):
        sim.sensors()


@pytest.mark.parametrize(
    ("backend", "terrain", "extensions"),
    [
        ("numpy", "flat", {}),
        ("plugin", "flat", {}),
        ("plugin", "sand", {}),
        ("plugin", "flat", {"rolling_resistance": {"c_rr": 0.05}}),
    ],
)
def test_motion_is_the_same_without_the_visual_model(
    backend: str, terrain: str, extensions: dict
) -> None:
    """The calibration replays build their models with ``visuals=False``: without the visual
    geoms (massless, colliding with nothing), camera, light and texture the rover must move
    and sense the same to the bit, on hard ground, on soil and with a hinge effect. A visual
    geom that carried mass or collided would move it differently."""
    cfg = replace(load_rover("proto_explorer"), extensions=extensions)
    runs = []
    for visuals in (True, False):
        sim = RoverSim(cfg, terrain, backend=backend, visuals=visuals)
        for targets in ([3.0, 3.0, 3.0, 3.0], [-2.0, 4.0, -2.0, 4.0]):
            sim.set_speed_targets(targets)
            sim.step(600)
        runs.append(np.concatenate([sim.data.qpos, sim.data.qvel, sim.data.sensordata]))
    np.testing.assert_array_equal(runs[0], runs[1])
    full = RoverSim(cfg, terrain, backend=backend).model
    lean = sim.model  # the last run's, built with visuals=False
    assert np.sum(full.geom_group == 2) > 0 and full.ncam and full.nlight and full.ntex
    assert not np.any(lean.geom_group == 2)


def _react_from_rows(self: RoverSim, share: np.ndarray) -> None:
    """The ground's reaction on the carriers computed from the dry-friction rows themselves
    (what :meth:`RoverSim._react_on_ground` reads off the dofs' constraint forces)."""
    d = self.data
    rows = d.efc_type[: d.nefc] == FRICTION_DOF
    per_dof = np.zeros(self.model.nv)
    per_dof[d.efc_id[: d.nefc][rows]] = d.efc_force[: d.nefc][rows]
    wheel_dof = self.index.wheel_dof
    torque = (per_dof[wheel_dof] * share)[:, None] * d.xaxis[self.index.wheel_jnt]
    carriers = np.unique(self.model.body_parentid[self.index.wheel_body])
    incidence = carriers[:, None] == self.model.body_parentid[self.index.wheel_body][None, :]
    d.xfrc_applied[carriers, 3:] = incidence.astype(float) @ torque


@pytest.mark.parametrize("backend", ["numpy", "plugin"])
def test_the_ground_reaction_reads_the_friction_rows_to_the_bit(
    backend: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A hinge effect's reaction on the carriers reads each wheel's dry-friction force off
    its dof's constraint force where no contact or equality row is present: the same drive
    to the bit as picking the friction rows out, through starts, stops and reversals."""
    cfg = replace(load_rover("proto_explorer"), extensions={"rolling_resistance": {"c_rr": 0.05}})
    runs = []
    for from_rows in (False, True):
        if from_rows:
            monkeypatch.setattr(RoverSim, "_react_on_ground", _react_from_rows)
        sim = RoverSim(cfg, backend=backend, contacts=False, visuals=False)
        for targets in ([3.0, 3.0, 3.0, 3.0], [0.0, 0.0, 0.0, 0.0], [-2.0, 4.0, -2.0, 4.0]):
            sim.set_speed_targets(targets)
            sim.step(400)
        runs.append(np.concatenate([sim.data.qpos, sim.data.qvel, sim.data.xfrc_applied.ravel()]))
    assert np.any(runs[0][-60:] != 0.0)  # the reaction acted
    np.testing.assert_array_equal(runs[0], runs[1])


def test_turn_outer_wheels_spin_inner_wheels_skid() -> None:
    sim = RoverSim()
    sim.set_speed_targets([1.0, 3.0, 1.0, 3.0])  # right side faster: a left turn
    sim.step(8000)
    assert sim.segment_truth().yaw_rate[1] > 0.05
    S = sim.wheel_truth().S
    assert S[0] > 0 and S[2] > 0, S  # inner (left) driven wheels skid
    assert S[1] < 0 and S[3] < 0, S  # outer (right) driven wheels spin


def test_higher_targets_turn_wheels_faster() -> None:
    sim = RoverSim()
    sim.set_speed_targets([1.0, 1.0, 3.0, 3.0])
    sim.step(2000)
    rates = sim.sensors().phi_dot[:4]
    assert rates[2] > rates[0] + 1.0 and rates[3] > rates[1] + 1.0


def test_yaw_springs_straighten_the_rover() -> None:
    sim = RoverSim()
    sim.reset(theta=np.array([0.0, 0.3, 0.0, 0.0, -0.3]))
    sim.set_speed_targets([3.0, 3.0, 3.0, 3.0])
    sim.step(15_000)
    th = sim.joint_angles()
    assert abs(th[1]) < 0.03 and abs(th[4]) < 0.03, th


def test_bumps_keep_every_wheel_loaded(cfg) -> None:
    sim = RoverSim(terrain="bumps")
    rho = cfg.geometry.wheel_radius - static_deflection(cfg)
    sim.set_speed_targets(np.full(4, 0.2 / rho))
    static = sim.wheel_truth().F_z.copy()
    fz_min = static.copy()
    while sim.segment_truth().pos[2, 0] < 3.5:  # rear axle well over the bumps
        sim.step(20)
        fz_min = np.minimum(fz_min, sim.wheel_truth().F_z)
        assert sim.time < 40
    assert np.all(fz_min > 0.1 * static), fz_min / static


def test_flip_is_detected() -> None:
    sim = RoverSim()
    assert not sim.flipped()
    sim.data.qpos[3:7] = [0.0, 1.0, 0.0, 0.0]  # upside down
    mujoco.mj_forward(sim.model, sim.data)
    assert sim.flipped()


def test_nan_speed_target_is_refused() -> None:
    sim = RoverSim()
    with pytest.raises(ValueError, match="2L"):
        sim.set_speed_targets([1.0, 1.0, np.nan, 1.0])


@pytest.mark.parametrize("S", [-0.9, -0.5, -0.2, -0.05, 0.05, 0.2, 0.5, 0.9])
def test_single_wheel_rig_matches_eq_13(S: float) -> None:
    params = TireParams()
    v_x = 0.2
    rho = 0.085 - params.k_re * (2.7 + 0.35) * G / params.C_z  # rolling radius r_e
    v_w = v_x / (1 + S) if S < 0 else v_x * (1 - S)
    r = measure_fx(v_x, v_w / rho, load_mass=2.7, params=params)
    expected = tire_forces(r["v_x"], 0.0, r["v_w"], r["delta"], 0.0, params)
    assert float(expected.S) == pytest.approx(S, abs=0.02)  # the servos impose the slip
    assert r["F_servo"] == pytest.approx(float(expected.F_x), rel=0.02)


def test_shipped_rover_yaml_equals_the_typed_defaults() -> None:
    from rover_env.config import RoverConfig

    assert load_rover() == RoverConfig()
