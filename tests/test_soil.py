"""Loose soil (issue 15): the steady-state model, its use in the simulator, both backends."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rover_env.config import ConfigError, FrictionPatch, TerrainConfig, from_dict
from rover_env.sim.rig import measure_soil
from rover_env.sim.simulator import RoverSim
from rover_env.soil import SoilParams, load_soil, slip_and_direction, soil_forces, static_sinkage

R, B, LOAD = 0.085, 0.05, 27.0


def test_check_values_of_notes() -> None:
    """shared/NOTES.md (adaptive quadrature of SOIL.md, regolith, rover wheel, 27 N)."""
    p = load_soil("regolith")
    assert static_sinkage(LOAD, R, B, p) == pytest.approx(0.0143, abs=5e-5)
    for s, ratio in ((0.0, -0.016), (0.2, 0.146), (0.5, 0.316), (0.9, 0.449)):
        h = static_sinkage(LOAD, R, B, p, slip=s)
        f = soil_forces(0.1, 0.0, 0.1 / (1 - s), h, R, B, p)
        assert float(f.F_z) == pytest.approx(LOAD, rel=1e-8)
        assert float(f.F_x / f.F_z) == pytest.approx(ratio, abs=5e-4), s
    q = dataclasses.replace(p, n1=0.5)
    for s, h in ((0.2, 0.020), (0.5, 0.031), (0.9, 0.051)):
        assert static_sinkage(LOAD, R, B, q, slip=s) == pytest.approx(h, abs=5e-4), s


def test_signs_and_symmetry() -> None:
    p = load_soil("regolith")
    h = 0.015
    drive = soil_forces(0.1, 0.0, 0.15, h, R, B, p)
    back = soil_forces(-0.1, 0.0, -0.15, h, R, B, p)
    assert float(drive.s) == pytest.approx(1 / 3) and float(back.s) == pytest.approx(1 / 3)
    assert drive.F_x > 0 and drive.T > 0  # pull forward, the motor works against T
    np.testing.assert_allclose([back.F_x, back.T], [-drive.F_x, -drive.T], rtol=1e-12)
    np.testing.assert_allclose(back.F_z, drive.F_z, rtol=1e-12)
    side = soil_forces(0.1, 0.02, 0.1, h, R, B, p)
    assert side.F_y < 0  # opposes lateral sliding
    skid = soil_forces(0.1, 0.0, 0.0, h, R, B, p)
    assert float(skid.s) == -1.0 and skid.F_x < 0  # a locked wheel brakes
    none = soil_forces(0.1, 0.0, 0.1, -0.001, R, B, p)
    assert none.F_x == 0 and none.F_z == 0 and none.T == 0
    s, d = slip_and_direction(0.0, 0.0)
    assert float(s) == 0.0 and float(d) == 1.0  # +1 at rest


def test_soil_config_errors(tmp_path) -> None:
    with pytest.raises(ConfigError, match="give mu_x and mu_y, or soil"):
        FrictionPatch(name="p", center=(0, 0), size=(1, 1))
    with pytest.raises(ConfigError, match="takes no mu_x"):
        FrictionPatch(name="p", center=(0, 0), size=(1, 1), mu_x=0.3, mu_y=0.3, soil="regolith")
    with pytest.raises(ConfigError, match="no shipped soil configuration named 'nope'"):
        load_soil("nope")
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nk_x: -1\n")
    with pytest.raises(ConfigError, match=r"bad.yaml.*k_x must be > 0"):
        load_soil(bad)
    with pytest.raises(ConfigError, match="lam must be in"):
        SoilParams(lam=1.5)


@pytest.mark.parametrize("slip", [0.3, -0.2])
def test_rig_settles_to_soil_forces(slip: float) -> None:
    """The single-wheel rig at constant slip settles to soil_forces at its static sinkage."""
    p = load_soil("regolith")
    m = measure_soil("regolith", slip, load=LOAD, duration=2.5)
    s = float(slip_and_direction(m["v_x"], m["v_w"])[0])  # the slip the servos achieved
    assert abs(s - slip) < 0.02
    h = static_sinkage(LOAD, R, B, p, slip=s)
    ref = soil_forces(m["v_x"], 0.0, m["v_w"], h, R, B, p)
    assert m["F_z"] == pytest.approx(LOAD, rel=2e-3)
    assert m["sinkage"] == pytest.approx(h, rel=0.02)
    assert m["F_servo"] == pytest.approx(float(ref.F_x), rel=0.02)  # drawbar pull
    assert m["T_servo"] == pytest.approx(float(ref.T), rel=0.02)  # the motor's torque


def test_spinning_wheel_digs_itself_in() -> None:
    """Sustained slip buries a wheel: held still and spun, it sinks past half its radius."""
    m = measure_soil("regolith", 1.0, load=LOAD, duration=8.0)
    assert m["final_depth"] > 0.5 * R
    settled = measure_soil("regolith", 0.3, load=LOAD, duration=2.5)
    assert settled["final_depth"] < 0.3 * R  # travelling, it leaves its hole behind


SOIL_TERRAIN = {
    "name": "soil-mix",
    "size": [12.0, 6.0],
    "slope_deg": [5.0, 2.0],
    "roughness": {"rms": 0.01, "correlation_length": 0.4, "modes": 8, "seed": 3},
    "soil": "regolith",
    "patches": [
        {"name": "ice", "center": [1.0, 0.0], "size": [0.6, 3.0], "mu_x": 0.1, "mu_y": 0.1},
    ],
}


def test_backends_agree_on_soil() -> None:
    """numpy reference and compiled plugin: the same rover on soil, ruts and all."""
    t = from_dict(TerrainConfig, SOIL_TERRAIN)
    a = RoverSim(terrain=t, backend="numpy")
    b = RoverSim(terrain=t, backend="plugin")
    for k in range(3):
        for sim in (a, b):
            sim.set_speed_targets([3.0, 1.5, 3.0, 1.5] if k % 2 else [2.5, 2.5, 2.5, 2.5])
            sim.step(400)
    np.testing.assert_allclose(a.data.qpos, b.data.qpos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.data.qvel, b.data.qvel, rtol=0, atol=1e-10)
    wa, wb = a.wheel_truth(), b.wheel_truth()
    np.testing.assert_allclose(wa.sinkage, wb.sinkage, atol=1e-12)
    assert (wa.soil == wb.soil).all() and wa.soil.max() == 1
    assert wa.sinkage.min() > 0.005  # every wheel stands in the soil
    pv = b._plugin
    assert pv is not None
    rut_b = pv.state(b.data.plugin_state)[pv.layout.rut]
    assert rut_b.max() > 0.005  # the wheels left ruts
    np.testing.assert_allclose(a.tires.rut, rut_b, atol=1e-12)


def test_middle_wheels_run_in_the_front_ruts() -> None:
    """Straight on flat soil: the middle and rear wheels meet the front wheels' rut."""
    t = from_dict(TerrainConfig, {"name": "sand", "size": [12.0, 6.0], "soil": "regolith"})
    sim = RoverSim(terrain=t, backend="plugin")
    sim.set_speed_targets([2.0] * 4)
    sim.step(3000)
    pv = sim._plugin
    assert pv is not None
    g = sim.terrain.rut_grid
    w = sim.wheel_truth()
    rut_here = g.lookup(pv.state(sim.data.plugin_state)[pv.layout.rut], *w.contact_point[:, :2].T)
    assert np.all(rut_here[:2] == 0.0)  # nothing ahead of the front wheels
    assert np.all(rut_here[2:] > 0.5 * w.sinkage[0])  # followers stand in the front ruts


def test_backends_agree_braking_on_soil() -> None:
    """Both backends where the arcs split at sign changes of j_x (braking: s < 0, issue 15).

    Driven forward, then reversed: the front wheels, pushed by the others, brake at s ~ -0.3,
    deep and slow enough for the shear displacement to change sign inside the contact arc.
    """
    t = from_dict(TerrainConfig, SOIL_TERRAIN)
    a = RoverSim(terrain=t, backend="numpy")
    b = RoverSim(terrain=t, backend="plugin")
    for targets in ([2.5] * 4, [-2.5] * 4):
        for sim in (a, b):
            sim.set_speed_targets(targets)
            sim.step(300)
    np.testing.assert_allclose(a.data.qpos, b.data.qpos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.data.qvel, b.data.qvel, rtol=0, atol=1e-10)
    w = b.wheel_truth()
    np.testing.assert_allclose(a.wheel_truth().sinkage, w.sinkage, atol=1e-12)
    s = slip_and_direction(w.v_x, w.v_w)[0]
    lam = load_soil("regolith").lam
    kinked = 0
    for s_i, h in zip(s, w.sinkage, strict=True):
        th_f = np.arccos(1.0 - h / R)
        th = np.linspace(-np.arccos(1.0 - lam * h / R), th_f, 2001)[:-1]
        j_x = (th_f - th) - (1.0 - s_i) * (np.sin(th_f) - np.sin(th))
        kinked += bool((j_x < 0.0).any())
    assert kinked >= 2  # the case this test is for did occur


POW_TERRAIN = {
    "name": "dune-and-mars",
    "size": [12.0, 6.0],
    "slope_deg": [3.0, 1.0],
    "soil": "dune-sand",
    "patches": [{"name": "mars", "center": [1.0, 0.0], "size": [2.0, 4.0], "soil": "mars-sand"}],
}


def test_backends_agree_where_the_exponent_is_not_one(monkeypatch: pytest.MonkeyPatch) -> None:
    """Soils with n != 1 (n = n0 + n1 |s|: the node stress takes e^(n log base)), numpy against
    the plugin at both of its vector widths (4 lanes where the CPU has AVX2, 2 forced by
    ROVER_ENV_SOIL_LANES): the same arithmetic lane by lane, so the same rover to the bit."""
    t = from_dict(TerrainConfig, POW_TERRAIN)
    a = RoverSim(terrain=t, backend="numpy")
    b = RoverSim(terrain=t, backend="plugin")
    monkeypatch.setenv("ROVER_ENV_SOIL_LANES", "2")
    c = RoverSim(terrain=t, backend="plugin")
    soils: set[int] = set()
    for targets in ([3.0, 2.0, 3.0, 2.0], [-2.0] * 4):
        for sim in (a, b, c):
            sim.set_speed_targets(targets)
            sim.step(250)
        soils |= set(b.wheel_truth().soil.tolist())
    np.testing.assert_allclose(a.data.qpos, b.data.qpos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.data.qvel, b.data.qvel, rtol=0, atol=1e-10)
    np.testing.assert_array_equal(b.data.qpos, c.data.qpos)
    np.testing.assert_array_equal(b.data.qvel, c.data.qvel)
    assert soils == {1, 2}  # dune sand (n0 1.1) and the Mars-sand patch (n0 0.92)
    assert b.wheel_truth().sinkage.min() > 0.003


def test_exp_and_log_twins_are_accurate() -> None:
    """soil._exp and soil._log (the node arithmetic shared with the C plugin) against numpy's
    exp and log: within 2 ulp over the ranges the nodes use and beyond; their edges."""
    from rover_env import soil

    rng = np.random.default_rng(7)
    x = np.concatenate([rng.uniform(-700.0, 700.0, 20000), rng.uniform(-40.0, 1.0, 20000)])
    x = np.concatenate([x, [0.0, -0.0, 1e-300, -1e-20, 709.0, -708.0]])
    np.testing.assert_allclose(soil._exp(x), np.exp(x), rtol=4.5e-16, atol=0)
    edge = soil._exp(np.array([-708.5, -1e6, -np.inf, 709.5, np.inf, np.nan]))
    assert (edge[:3] == 0.0).all() and np.isinf(edge[3:5]).all() and np.isnan(edge[5])
    b = np.concatenate([10.0 ** rng.uniform(-307.0, 300.0, 20000), rng.uniform(0.0, 0.2, 20000)])
    b = np.concatenate([b[b > 0.0], [2.0**-1022, 1.0, 0.5**0.5, 2.0**0.5, 1.7e308]])
    np.testing.assert_allclose(soil._log(b), np.log(b), rtol=2.5e-16, atol=1e-300)
    base = rng.uniform(1e-6, 0.085, 2000)  # Bekker's base^n as the nodes take it
    for n in (0.6, 0.92, 1.1, 1.9):
        np.testing.assert_allclose(soil._exp(n * soil._log(base)), base**n, rtol=3e-15)


def test_backends_agree_on_soil_without_memory() -> None:
    """``memory`` 0 (a surface that forgets): no rut is written and no hole dug, in both
    backends alike, and the rover still stands in the soil."""
    from rover_env.config import RoverConfig

    cfg = dataclasses.replace(
        RoverConfig(), extensions={"loose_soil": {"k_phi": 8e5, "memory": 0.0}}
    )
    a = RoverSim(cfg, "flat", backend="numpy")
    b = RoverSim(cfg, "flat", backend="plugin")
    for targets in ([3.0, 1.5, 3.0, 1.5], [-2.5] * 4):
        for sim in (a, b):
            sim.set_speed_targets(targets)
            sim.step(400)
    np.testing.assert_allclose(a.data.qpos, b.data.qpos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.data.qvel, b.data.qvel, rtol=0, atol=1e-10)
    assert a.wheel_truth().sinkage.min() > 0.003
    pv = b._plugin
    assert pv is not None
    assert not pv.state(b.data.plugin_state)[pv.layout.rut].any()
    assert not a.tires.rut.any() and not a.tires.dig.any()
    with pytest.raises(ConfigError, match="memory"):
        SoilParams(memory=1.5)


def _followers_sinkage(rut_cell: float, yaw: float) -> np.ndarray:
    """Mean sinkage (m) of the middle and rear wheels (rover_env.sim.rut_rig)."""
    from rover_env.sim.rut_rig import follower_sinkage

    return follower_sinkage(rut_cell, yaw)[0][2:]


def test_followers_sinkage_is_the_soils_not_the_rut_grids() -> None:
    """The middle and rear wheels' steady sinkage in the front wheels' ruts is a property of
    the soil: the same at 0.1 rad across the grid as along it, and within 3 % when the rut
    cell is halved (a discretisation that converges)."""
    shipped = load_soil("mars-sand").rut_cell
    ref = _followers_sinkage(shipped, 0.0)
    assert np.all(ref > 0.008)  # in the ruts, deeper than a front wheel (6.5 mm)
    np.testing.assert_allclose(_followers_sinkage(shipped, 0.1), ref, rtol=0.03)
    np.testing.assert_allclose(_followers_sinkage(shipped / 2, 0.0), ref, rtol=0.03)
    np.testing.assert_allclose(_followers_sinkage(shipped / 2, 0.1), ref, rtol=0.03)
