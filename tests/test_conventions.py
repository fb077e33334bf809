"""Each catalogue effect's parameter means its textbook definition, measured in the simulator
(issue 16): one rig test per effect, on the single-wheel rig or the rover at rest."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from rover_env.config import RoverConfig, TerrainConfig, from_dict
from rover_env.effects import (
    CATALOGUE,
    LOOSE_SOIL_BASE,
    CombinedSlip,
    Friction,
    LoadDependentFriction,
    RollingRadius,
    RollingResistance,
)
from rover_env.sim.model import static_deflection
from rover_env.sim.rig import measure_fx
from rover_env.sim.simulator import RoverSim
from rover_env.soil import load_soil, static_sinkage

G = 9.81
CFG = RoverConfig()
FZ0 = CFG.masses.total * G / 6
WHEEL_MASS = 0.35  # the rig's wheel


def test_every_catalogue_effect_has_a_rig_test() -> None:
    tested = {
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
    assert set(CATALOGUE) == tested


@pytest.mark.parametrize("load_mass", [2.0, 4.0])
def test_rolling_resistance_is_c_rr_times_the_wheels_own_load(load_mass: float) -> None:
    """Free-rolling wheel pulled at steady speed: the ground resists with c_rr F_z (2 %)."""
    c = 0.04
    r = measure_fx(0.3, None, load_mass=load_mass, effects=[RollingResistance({"c_rr": c})])
    assert r["F_z"] == pytest.approx((load_mass + WHEEL_MASS) * G, rel=0.01)  # its own load
    assert -r["F_servo"] == pytest.approx(c * r["F_z"], rel=0.02)
    off = measure_fx(0.3, None, load_mass=load_mass)
    assert abs(off["F_servo"]) < 1e-3 * c * off["F_z"]


def test_rolling_resistance_is_the_grounds_moment_not_the_bearings() -> None:
    """Rolling resistance comes from the ground (the normal force's forward offset), so the
    wheel's carrier feels only hub forces, not a bearing torque. Measured where it shows:
    segment 3's pitch joint theta_4 at steady straight rolling, against the second
    implementation (foreign generator), which applies the moment as the ground's couple on
    the wheel. A bearing friction pitches segment 3 by 1.34 x as much."""
    from dataclasses import replace

    from rover_env.generators.foreign_logs import ForeignRover

    def foreign(c: float) -> np.ndarray:
        r = ForeignRover(CFG, {"rolling_resistance": {"c_rr": c}} if c else {})
        r.reset()
        r.run(np.full(4, 2.0), 1.5)
        return np.mean([(r.run(np.full(4, 2.0), 0.05), r.sample()[1])[1] for _ in range(10)], 0)

    def own(c: float) -> np.ndarray:
        ext = {"rolling_resistance": {"c_rr": c}} if c else {}
        sim = RoverSim(replace(CFG, extensions=ext))
        sim.reset()
        sim.set_speed_targets(np.full(4, 2.0))
        sim.step(1500)
        return np.mean([(sim.step(50), sim.joint_angles())[1] for _ in range(10)], 0)

    ref = foreign(0.05)[3] - foreign(0.0)[3]  # theta_4 with c_rr 0.05, minus without
    assert abs(ref) > 5e-3  # the effect is there to be compared
    assert own(0.05)[3] - own(0.0)[3] == pytest.approx(ref, rel=0.05)


def test_rolling_resistance_runs_alike_on_both_tire_backends() -> None:
    ext = {"rolling_resistance": {"c_rr": 0.05}}
    runs = {}
    for backend in ("plugin", "numpy"):
        sim = RoverSim(RoverConfig(extensions=ext), backend=backend)
        assert sim.backend == backend
        sim.set_speed_targets((2.0, 2.0, 1.0, 3.0))
        sim.step(300)
        wt = sim.wheel_truth()
        # Each hinge's friction moment is c_rr F_z (d - delta) of its own wheel.
        lever = CFG.geometry.wheel_radius - wt.delta
        fl = sim.model.dof_frictionloss[sim._wheel_dof]
        np.testing.assert_allclose(fl, 0.05 * wt.F_z * lever, rtol=0.05)
        assert np.ptp(wt.F_z) > 0.5  # loads differ, and so do the moments
        runs[backend] = sim.sensors().phi
    np.testing.assert_allclose(runs["plugin"], runs["numpy"], atol=1e-9)


def test_slope_is_the_tilt_of_the_ground_in_degrees() -> None:
    """Rover standing still: the specific force its accelerometer measures, turned into the
    ground's axes (x, y in the ground plane, z its normal), leans by ``deg`` from the
    normal, toward ``heading_deg``: the ground rises by ``deg`` in that direction."""
    ext = {"slope": {"deg": 6.0, "heading_deg": 30.0}}
    sim = RoverSim(RoverConfig(extensions=ext), backend="plugin")
    f = np.zeros(3)
    seg2 = sim._seg_body[1]
    for _ in range(50):
        sim.step(10)
        rot = sim.data.xmat[seg2].reshape(3, 3)  # segment 2's axes in the ground's
        f += rot @ sim.sensors().imu_accel[1]
    tilt = math.degrees(math.atan2(math.hypot(f[0], f[1]), f[2]))
    assert tilt == pytest.approx(6.0, abs=0.1)
    # The specific force (-gravity) points uphill in the ground plane: toward the heading.
    assert math.degrees(math.atan2(f[1], f[0])) == pytest.approx(30.0, abs=1.0)


def test_rolling_radius_changes_travel_per_turn_by_fraction_of_d_at_static_load() -> None:
    load = FZ0 / G - WHEEL_MASS  # the rover's static wheel load on the rig
    base = measure_fx(0.2, None, load_mass=load, params=CFG.tire)
    eff = RollingRadius({"fraction": -0.05})
    cfg = eff.apply_config(CFG)
    changed = measure_fx(0.2, None, load_mass=load, params=cfg.tire)
    r0, r1 = base["v_x"] / base["omega"], changed["v_x"] / changed["omega"]
    assert r1 - r0 == pytest.approx(-0.05 * CFG.geometry.wheel_radius, rel=0.02)


def test_torque_limit_is_a_fraction_of_the_motor_limit() -> None:
    peak = {}
    for f in (0.0, -0.6):
        sim = RoverSim(RoverConfig(extensions={"torque_limit": {"fraction": f}} if f else {}))
        sim.set_speed_targets((4.0, 4.0, 4.0, 4.0))
        m = 0.0
        for _ in range(30):
            sim.step(2)
            m = max(m, float(np.abs(sim.motor_torque()).max()))
        peak[f] = m
    lim = CFG.motor.torque_limit
    assert peak[0.0] > 0.4 * lim * 1.05  # without it the step asks for more than 0.4 limit
    assert peak[-0.6] == pytest.approx(0.4 * lim, rel=1e-6)  # (1 + fraction) x the limit


def _targets_seen(ext: dict, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    sim = RoverSim(RoverConfig(extensions=ext), backend="plugin")
    sim.set_speed_targets((2.0, 2.0, 2.0, 2.0))
    n = round(seconds / sim.dt)
    u = np.zeros(n)
    for k in range(n):
        sim.step(1)
        u[k] = sim.data.ctrl[sim._ctrl_vel][0]
    return (np.arange(n) + 1) * sim.dt, u / 2.0


def test_command_lag_is_a_first_order_time_constant() -> None:
    tau = 0.25
    t, u = _targets_seen({"command_lag": {"tau": tau}}, 1.0)
    k = int(np.argmin(np.abs(t - tau)))
    assert u[k] == pytest.approx(1 - math.exp(-1), abs=0.005)  # 63 % after one tau
    np.testing.assert_allclose(u, 1 - np.exp(-t / tau), atol=0.005)


def test_command_delay_is_a_dead_time() -> None:
    delay = 0.12
    t, u = _targets_seen({"command_delay": {"delay": delay}}, 0.3)
    assert np.all(u[t < delay - 1e-9] == 0.0)
    assert np.all(u[t > delay + 1e-3] == 1.0)


def test_friction_is_a_fraction_of_mu() -> None:
    """A locked wheel dragged along: F_x = mu_x (1 + fraction) F_z."""
    for f in (0.0, -0.4):
        tire = Friction({"fraction": f}).apply_config(CFG).tire
        r = measure_fx(0.3, 0.0, params=tire)
        assert -r["F_x"] / r["F_z"] == pytest.approx(CFG.tire.mu_x * (1 + f), rel=0.01)
        assert -r["F_servo"] / r["F_z"] == pytest.approx(CFG.tire.mu_x * (1 + f), rel=0.01)


def test_combined_slip_keeps_the_force_pair_inside_the_friction_ellipse() -> None:
    """Locked wheel dragged forward and sideways: both directions saturate off, the pair
    lies on the ellipse (F_x / mu_x F_z)^2 + (F_y / mu_y F_z)^2 = 1 on."""
    tp = CFG.tire

    def ellipse(on: float) -> float:
        eff = [CombinedSlip({"on": on})] if on else []
        r = measure_fx(0.3, 0.0, v_y=0.2, params=tp, effects=eff, duration=2.0)
        return math.hypot(r["F_x"] / (tp.mu_x * r["F_z"]), r["F_y"] / (tp.mu_y * r["F_z"]))

    assert ellipse(1.0) == pytest.approx(1.0, abs=0.01)
    assert ellipse(0.0) > 1.3


def test_load_dependent_friction_falls_by_fall_across_the_operating_range() -> None:
    eff = LoadDependentFriction({"fall": 0.3, "range": 0.1})
    eff.apply_model(None, CFG)
    mu = {}
    for s in (-1.0, 1.0):  # loads F_z0 (1 - range) and F_z0 (1 + range)
        load = FZ0 * (1 + s * 0.12) / G - WHEEL_MASS  # just beyond the range: the clip holds
        r = measure_fx(0.3, 0.0, load_mass=load, params=CFG.tire, effects=[eff], duration=2.0)
        mu[s] = -r["F_x"] / r["F_z"]
    assert (mu[-1.0] - mu[1.0]) / CFG.tire.mu_x == pytest.approx(0.3, rel=0.01)


def test_static_deflection_matches_the_rig_lever() -> None:
    # The rolling-resistance lever d - delta at static load (used before the first substep).
    assert static_deflection(CFG) == pytest.approx(FZ0 / CFG.tire.C_z)


def test_plugin_load_view_is_the_committed_truth() -> None:
    sim = RoverSim(RoverConfig(extensions={"rolling_resistance": {"c_rr": 0.02}}), "flat", "plugin")
    sim.set_speed_targets((1.0, 2.0, 1.0, 2.0))
    sim.step(50)
    assert sim._load_view is not None
    wt = sim.wheel_truth()
    np.testing.assert_array_equal(sim._load_view[0], wt.F_z)
    np.testing.assert_array_equal(sim._load_view[1], wt.delta)


def test_hinge_and_command_effects_together_agree_across_backends() -> None:
    ext = {"rolling_resistance": {"c_rr": 0.05}, "command_lag": {"tau": 0.1}}
    runs = {}
    for backend in ("plugin", "numpy"):
        sim = RoverSim(RoverConfig(extensions=ext), backend=backend)
        sim.set_speed_targets((2.0, 1.0, 2.0, 1.0))
        for _ in range(13):
            sim.step(7)  # steps that do not line up with the 10-substep hinge updates
        runs[backend] = sim.sensors().phi
    np.testing.assert_allclose(runs["plugin"], runs["numpy"], atol=1e-9)


def _settled_on(
    ext: dict[str, dict[str, float]], terrain: TerrainConfig | str = "flat"
) -> RoverSim:
    sim = RoverSim(RoverConfig(extensions=ext), terrain, backend="plugin")
    sim.step(2000)  # 2 s at rest: the wheels sink to where the soil carries them
    return sim


def test_loose_soil_k_phi_is_bekkers_modulus() -> None:
    """Static sinkage of each wheel follows Bekker's law p = (k_c / b + k_phi) z^n: for a rigid
    wheel z is proportional to (k_c / b + k_phi)^(-2 / (2 n + 1)) (Wong, Theory of Ground
    Vehicles, ch. 2), and it is the sinkage at which the soil model carries the wheel's load."""
    base = load_soil(LOOSE_SOIL_BASE)
    width = CFG.geometry.wheel_width
    z = {}
    for k_phi in (5e5, 8e6):
        sim = _settled_on({"loose_soil": {"k_phi": k_phi}})
        w = sim.wheel_truth()
        assert np.all(w.soil == 1)
        soil = dataclasses.replace(base, k_phi=k_phi)
        ref = [static_sinkage(f, CFG.geometry.wheel_radius, width, soil) for f in w.F_z]
        np.testing.assert_allclose(w.sinkage, ref, rtol=0.02)
        z[k_phi] = w.sinkage
    k_s = {k: base.k_c / width + k for k in z}
    bekker = (k_s[8e6] / k_s[5e5]) ** (2.0 / (2.0 * base.n0 + 1.0))
    np.testing.assert_allclose(z[5e5] / z[8e6], bekker, rtol=0.02)


def test_loose_soil_on_hard_ground_is_the_soil_of_its_base_preset() -> None:
    """At a preset's k_phi, phi and n0 the effect drives exactly as that soil over the ground;
    off (k_phi 0) it is hard ground, and a soil patch keeps its own soil."""
    base = load_soil(LOOSE_SOIL_BASE)
    ext = {"loose_soil": {"k_phi": base.k_phi, "phi_deg": base.phi_deg, "n0": base.n0}}
    a = RoverSim(RoverConfig(extensions=ext), "flat", backend="plugin")
    t = from_dict(TerrainConfig, {"name": "flat", "soil": LOOSE_SOIL_BASE})
    b = RoverSim(RoverConfig(), t, backend="plugin")
    for sim in (a, b):
        sim.set_speed_targets([2.0] * 4)
        sim.step(1500)
    assert np.array_equal(a.data.qpos, b.data.qpos)
    assert a.wheel_truth().sinkage.min() > 0.005
    off = _settled_on({"loose_soil": {"k_phi": 0.0}})
    assert np.all(off.wheel_truth().soil == 0)
    # "Softer than modelled": on a terrain with loose soil the effect replaces its k_phi.
    dune = from_dict(TerrainConfig, {"name": "flat", "soil": "dune-sand"})
    softer = _settled_on({"loose_soil": {"k_phi": 3e5, "phi_deg": 28.0, "n0": 1.1}}, dune)
    plain = _settled_on({}, dune)
    assert np.all(softer.wheel_truth().sinkage > 1.3 * plain.wheel_truth().sinkage)


def test_loose_soil_stays_when_the_terrain_is_swapped() -> None:
    """``set_terrain`` (per-episode terrain in the environments) keeps the effect's soil."""
    sim = _settled_on({"loose_soil": {"k_phi": 1e6}})
    sim.set_terrain(from_dict(TerrainConfig, {"name": "flat"}))
    sim.reset()
    sim.step(1000)
    assert np.all(sim.wheel_truth().soil == 1)
    assert sim.wheel_truth().sinkage.min() > 0.003


def test_the_free_wheels_slip_under_rolling_resistance_as_the_independent_rover_does() -> None:
    """Rolling resistance drags the free wheels: they need c_rr F_z of ground force, got by
    slip. Measured against the independent implementation (``rover_env.independent``: its own
    MJCF, tire and contact code; nominal build): the free wheels' steady rate over the driven
    wheels', with c_rr 0.05 minus without, agrees to 5 % of the change (stop 93: -2.0 % there,
    -2.0 % here; segment 3's pitch, by contrast, moves 1.4 x as much here: the joints read
    it through each implementation's own form, docs/calibration "A rolling resistance is
    read at about half its size")."""
    from rover_env.independent import effects as ind_effects
    from rover_env.independent import model as ind_model
    from rover_env.independent.simulate import simulate

    t = np.round(np.arange(0.0, 4.0 + 1e-9, 0.02), 9)
    steady = t >= 2.5  # the step starts at 1 s

    def theirs(c: float) -> float:
        cmd = np.where((t >= 1.0)[:, None], 2.0, 0.0) * np.ones((1, 4))
        eff = ind_effects.resolve({"rolling_resistance": {"c_rr": c}} if c else {})
        om = simulate(ind_model.RoverParams(), eff, t, cmd, settle=0.5).omega[steady].mean(axis=0)
        return float(om[4:].mean() / om[:4].mean())

    def ours(c: float) -> float:
        ext = {"rolling_resistance": {"c_rr": c}} if c else {}
        sim = RoverSim(dataclasses.replace(CFG, extensions=ext))
        sim.reset()
        sim.step(round(1.0 / sim.dt))
        sim.set_speed_targets(np.full(4, 2.0))
        sim.step(round(1.5 / sim.dt))
        phi0 = sim.sensors().phi.copy()
        sim.step(round(1.5 / sim.dt))
        rate = sim.sensors().phi - phi0
        return float(rate[4:].mean() / rate[:4].mean())

    ref = theirs(0.05) - theirs(0.0)
    assert ref < -0.01  # the drag is there to be compared
    assert ours(0.05) - ours(0.0) == pytest.approx(ref, rel=0.05)
