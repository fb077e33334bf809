"""The physics timestep study (issue 49, item 2): every physical check at 1, 2 and 5 ms.

Run: nice -n 5 python benchmarks/timestep_study.py [--dts 1 2 5] [--out docs/timestep.md]

Each check of the test suite and of ``rover-env validate`` that compares the physics with a
reference is run here at every timestep with its own tolerance (the test or report it comes
from is named in the table); checks whose reference is the converged solution compare with
the same run at 0.25 ms. Rover checks run on the compiled plugin (equal to the numpy layer to
~1e-12, checked here too), the rigs on the numpy layer, as in their tests. Durations are in
seconds of simulated time, so every timestep runs the same experiment. The analytic stability
bounds of the explicitly applied tire and soil terms and the speed gain (substeps/s and env
steps/s, measured in this run, as ratios to 1 ms) are written under the table.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import write_report

import rover_env  # noqa: F401  (registers the env ids)
from rover_env.config import RoverConfig, SimSpec, TerrainConfig, from_dict, load_rover
from rover_env.experiments import paper_sim, soil_validation, validation
from rover_env.sim.recorder import run_drive
from rover_env.sim.rig import free_wheel_residual, measure_fx, measure_soil
from rover_env.sim.rut_rig import follower_sinkage
from rover_env.sim.simulator import RoverSim
from rover_env.soil import V_BLEND, load_soil, soil_forces, static_sinkage
from rover_env.tire import TireParams, tire_forces

G = 9.81
REF_DT = 2.5e-4
"""Timestep of the converged reference (a quarter of 1 ms, as ``rover-env validate``)."""
BACKEND = "plugin"


def rover_at(dt: float) -> RoverConfig:
    base = load_rover()
    return dataclasses.replace(base, sim=SimSpec(timestep=dt))


def secs(sim: RoverSim, t: float) -> int:
    return round(t / sim.dt)


# ----------------------------------------------------------------------------- hard ground


def rig_eq13(dt: float) -> dict[str, Any]:
    """tests/test_sim.py::test_single_wheel_rig_matches_eq_13, every slip of the test."""
    p = TireParams()
    err_f = err_s = 0.0
    for S in (-0.9, -0.5, -0.2, -0.05, 0.05, 0.2, 0.5, 0.9):
        rho = 0.085 - p.k_re * (2.7 + 0.35) * G / p.C_z
        v_w = 0.2 / (1 + S) if S < 0 else 0.2 * (1 - S)
        r = measure_fx(0.2, v_w / rho, load_mass=2.7, params=p, dt=dt)
        e = tire_forces(r["v_x"], 0.0, r["v_w"], r["delta"], 0.0, p)
        err_s = max(err_s, abs(float(e.S) - S))
        err_f = max(err_f, abs(r["F_servo"] / float(e.F_x) - 1.0))
    return {"err_F": err_f, "err_S": err_s}


def free_wheels(dt: float) -> dict[str, Any]:
    """A free wheel on the rig started 10 % slow (rover_env.sim.rig.free_wheel_residual)."""
    return {"static": free_wheel_residual(27.0, dt), "light": free_wheel_residual(5.0, dt)}


def at_rest(dt: float) -> dict[str, Any]:
    """tests/test_sim.py::test_at_rest_weight_deflection_and_creep (10 s)."""
    cfg = rover_at(dt)
    sim = RoverSim(cfg, backend=BACKEND)
    wt = sim.wheel_truth()
    p0 = sim.segment_truth().pos
    sim.step(secs(sim, 10.0))
    return {
        "weight": abs(wt.F_z.sum() / (cfg.masses.total * G) - 1.0),
        "deflection": float(np.max(np.abs(wt.delta / (wt.F_z / cfg.tire.C_z) - 1.0))),
        "creep": float(np.linalg.norm(sim.segment_truth().pos - p0, axis=1).max()),
    }


def parked_slope(dt: float) -> dict[str, Any]:
    """tests/test_sim.py::test_parked_on_10_degree_slope_creeps_under_1_cm (10 s)."""
    sim = RoverSim(rover_at(dt), terrain="slope10", backend=BACKEND)
    p0 = sim.segment_truth().pos
    sim.step(secs(sim, 10.0))
    return {"creep": float(np.linalg.norm(sim.segment_truth().pos - p0, axis=1).max())}


def straight(dt: float) -> dict[str, Any]:
    """tests/test_sim.py::test_equal_targets_drive_straight (10 m)."""
    sim = RoverSim(rover_at(dt), backend=BACKEND)
    sim.set_speed_targets([4.0] * 4)
    p0 = sim.segment_truth().pos[1].copy()
    while np.linalg.norm(sim.segment_truth().pos[1, :2] - p0[:2]) < 10.0 and sim.time < 80:
        sim.step(secs(sim, 1.0))
    p = sim.segment_truth().pos[1]
    return {"drift": abs(p[1] - p0[1]) / max(p[0] - p0[0], 1e-9)}


def turning(dt: float) -> dict[str, Any]:
    """tests/test_sim.py: turn (8 s), higher targets (2 s), yaw springs (15 s)."""
    sim = RoverSim(rover_at(dt), backend=BACKEND)
    sim.set_speed_targets([1.0, 3.0, 1.0, 3.0])
    sim.step(secs(sim, 8.0))
    S = sim.wheel_truth().S
    out = {
        "yaw_rate": float(sim.segment_truth().yaw_rate[1]),
        "inner": float(min(S[0], S[2])),
        "outer": float(max(S[1], S[3])),
    }
    sim = RoverSim(rover_at(dt), backend=BACKEND)
    sim.set_speed_targets([1.0, 1.0, 3.0, 3.0])
    sim.step(secs(sim, 2.0))
    rates = sim.sensors().phi_dot[:4]
    out["faster"] = float(min(rates[2] - rates[0], rates[3] - rates[1]))
    sim = RoverSim(rover_at(dt), backend=BACKEND)
    sim.reset(theta=np.array([0.0, 0.3, 0.0, 0.0, -0.3]))
    sim.set_speed_targets([3.0] * 4)
    sim.step(secs(sim, 15.0))
    th = sim.joint_angles()
    out["yaw_springs"] = float(max(abs(th[1]), abs(th[4])))
    return out


def bumps(dt: float) -> dict[str, Any]:
    """tests/test_sim.py::test_bumps_keep_every_wheel_loaded."""
    cfg = rover_at(dt)
    sim = RoverSim(cfg, terrain="bumps", backend=BACKEND)
    rho = cfg.geometry.wheel_radius - cfg.masses.total * G / 6 / cfg.tire.C_z
    sim.set_speed_targets(np.full(4, 0.2 / rho))
    static = sim.wheel_truth().F_z.copy()
    fz_min = static.copy()
    while sim.segment_truth().pos[2, 0] < 3.5 and sim.time < 40:
        sim.step(secs(sim, 0.02))
        fz_min = np.minimum(fz_min, sim.wheel_truth().F_z)
    return {"min_load": float(np.min(fz_min / static))}


def convergence(dt: float) -> dict[str, Any]:
    """rover-env validate's timestep convergence drive (20 s turning), end point."""
    sim = RoverSim(rover_at(dt), backend=BACKEND)
    n = secs(sim, 0.1)
    p_prev = sim.segment_truth().pos[1].copy()
    dist = 0.0
    for k in range(200):
        sim.set_speed_targets([1.5, 3.0, 1.5, 3.0] if k * 0.1 >= 2.0 else [2.5] * 4)
        sim.step(n)
        p = sim.segment_truth().pos[1].copy()
        dist += float(np.linalg.norm(p[:2] - p_prev[:2]))
        p_prev = p
    return {"end": p_prev[:2], "dist": dist}


def paper_drive(dt: float, terrain: str | None = None) -> dict[str, Any]:
    """rover-env paper-sim (32 s): phase means of the driven wheels' slip (and every wheel's
    sinkage on soil), the end point of segment 2."""
    sim = RoverSim(rover_at(dt), terrain=terrain or "flat", backend=BACKEND)
    rec = run_drive(sim, paper_sim.schedule, paper_sim.PHASES[-1].end, sample_rate_hz=50.0)
    tr = rec.truth()
    t = tr["t"]
    slip, sink = [], []
    for p in paper_sim.PHASES:
        sel = (t >= p.start + 2.0) & (t < p.end)
        slip.append(tr["S"][sel][:, :4].mean(axis=0))
        sink.append(tr["sinkage"][sel].mean(axis=0))
    pos = tr["seg_pos"][:, 1, :2]
    dist = float(np.sum(np.linalg.norm(np.diff(pos, axis=0), axis=1)))
    return {"slip": np.array(slip), "sink": np.array(sink), "end": pos[-1], "dist": dist}


def flips(dt: float) -> dict[str, Any]:
    """rover-env validate's flip detection, and a 20 s rough drive with no warning or NaN."""
    tip = validation.tip_over(62.0, rover=rover_at(dt))
    ctl = validation.tip_over(50.0, rover=rover_at(dt))
    try:
        validation.endurance(20.0, rover=rover_at(dt), backend=BACKEND)
        ok = 1.0
    except Exception:  # SimulationError (warning, NaN) or anything else: the check fails
        ok = 0.0
    return {"tip": tip["flipped"], "control": 1.0 - ctl["flipped"], "rough": ok}


# ----------------------------------------------------------------------------- loose soil


def soil_rig(dt: float) -> dict[str, Any]:
    """docs/validation/soil.md: the rig (6 s) on every preset and slip against soil_forces."""
    rows = soil_validation.rig_sweep(dts=(dt,))
    worst = max(max(r["err_F_x"], r["err_T"], r["err_sinkage"], r["err_F_z"]) for r in rows)
    vals = np.array([[r["F_servo"], r["T_servo"], r["sinkage"]] for r in rows])
    return {"worst": worst, "vals": vals}


def digging(dt: float) -> dict[str, Any]:
    """tests/test_soil.py::test_spinning_wheel_digs_itself_in."""
    spun = measure_soil("regolith", 1.0, load=27.0, duration=8.0, dt=dt)
    rolled = measure_soil("regolith", 0.3, load=27.0, duration=2.5, dt=dt)
    r = 0.085
    return {"spun": spun["final_depth"] / r, "rolled": rolled["final_depth"] / r}


def parked_soil(dt: float) -> dict[str, Any]:
    """docs/validation/soil.md: parked 20 s on a 10 degree slope of each preset."""
    out: dict[str, Any] = {}
    for soil in soil_validation.PRESETS:
        r = soil_validation.parked(soil, rover=rover_at(dt))
        out[f"{soil}:creep"] = r["creep_speed"]
        out[f"{soil}:vel"] = r["vel_step_rms"]
        out[f"{soil}:fx"] = float(np.max(r["fx_step_rms"] / r["resistance"]))
    return out


def ruts(dt: float) -> dict[str, Any]:
    """tests/test_soil.py: followers in the front ruts (3 s) and their steady sinkage (rut rig)."""
    t = from_dict(TerrainConfig, {"name": "sand", "size": [12.0, 6.0], "soil": "regolith"})
    sim = RoverSim(rover_at(dt), terrain=t, backend=BACKEND)
    sim.set_speed_targets([2.0] * 4)
    sim.step(secs(sim, 3.0))
    pv = sim._plugin
    assert pv is not None
    w = sim.wheel_truth()
    rut = sim.terrain.rut_grid.lookup(
        pv.state(sim.data.plugin_state)[pv.layout.rut], *w.contact_point[:, :2].T
    )
    shipped = load_soil("mars-sand").rut_cell
    mean, _ = follower_sinkage(shipped, 0.0, rover=rover_at(dt))
    return {
        "ahead": float(rut[:2].max()),
        "behind": float(rut[2:].min() / w.sinkage[0]),
        "followers": mean[2:],
    }


def soil_drive(dt: float) -> dict[str, Any]:
    """Backends agree on soil (tests/test_soil.py, 1.2 s) and 30 s of random soil driving."""
    t = from_dict(TerrainConfig, soil_validation.SOIL_ROUGH)
    a = RoverSim(rover_at(dt), terrain=t, backend="numpy")
    b = RoverSim(rover_at(dt), terrain=t, backend="plugin")
    for k in range(3):
        for sim in (a, b):
            sim.set_speed_targets([3.0, 1.5, 3.0, 1.5] if k % 2 else [2.5] * 4)
            sim.step(secs(sim, 0.4))
    gap = float(np.max(np.abs(a.data.qpos - b.data.qpos)))
    try:
        r = soil_validation.soil_endurance(30.0, rover=rover_at(dt))
        ok = float(r["finite"])
    except Exception:  # SimulationError (warning, NaN): the check fails
        ok = 0.0
    return {"backends": gap, "endurance": ok}


# ----------------------------------------------------------------------------- the table


@dataclass(frozen=True)
class Row:
    """One line of the table: ``value(result, reference)`` judged by ``ok``."""

    quantity: str
    tolerance: str
    value: Callable[[dict[str, Any], dict[str, Any] | None], float]
    ok: Callable[[float], bool]
    fmt: str = ".3g"


@dataclass(frozen=True)
class Check:
    name: str
    source: str
    run: Callable[[float], dict[str, Any]]
    rows: tuple[Row, ...]
    ref_dt: float | None = None
    """Timestep of the run the rows compare with (None: an absolute reference)."""
    extra: dict[str, Any] = field(default_factory=dict)


def _gap(r: dict[str, Any], ref: dict[str, Any] | None) -> float:
    assert ref is not None
    return 100 * float(np.linalg.norm(r["end"] - ref["end"])) / ref["dist"]


def _max_abs(key: str) -> Callable[[dict[str, Any], dict[str, Any] | None], float]:
    return lambda r, ref: float(np.max(np.abs(r[key] - ref[key])))  # type: ignore[index]


def _max_rel(key: str) -> Callable[[dict[str, Any], dict[str, Any] | None], float]:
    return lambda r, ref: 100 * float(np.max(np.abs(r[key] / ref[key] - 1)))  # type: ignore[index]


def _get(key: str, scale: float = 1.0) -> Callable[[dict[str, Any], dict[str, Any] | None], float]:
    return lambda r, ref: scale * float(r[key])


SOIL_PCT = "%"

CHECKS: tuple[Check, ...] = (
    Check("Tire rig vs eq. 13 (8 slips)", "test_sim", rig_eq13, (
        Row("worst pull error", "< 2 %", _get("err_F", 100), lambda v: v < 2),
        Row("worst slip imposed - set", "< 0.02", _get("err_S"), lambda v: v < 0.02),
    )),
    Check("Free wheel started 10 % slow (stability)", "this study", free_wheels, (
        Row("max abs F_x, 0.5-1 s, 27 N load [N]", "< 1e-3", _get("static"), lambda v: v < 1e-3),
        Row("max abs F_x, 0.5-1 s, 5 N load [N]", "< 1e-3", _get("light"), lambda v: v < 1e-3),
    )),
    Check("Rover at rest, 10 s", "test_sim", at_rest, (
        Row("sum F_z / weight - 1", "< 1 %", _get("weight", 100), lambda v: v < 1),
        Row("deflection vs F_z / C_z", "< 1 %", _get("deflection", 100), lambda v: v < 1),
        Row("creep [mm]", "< 1 mm", _get("creep", 1e3), lambda v: v < 1),
    )),
    Check("Parked on 10 deg hard slope, 10 s", "test_sim", parked_slope, (
        Row("creep [mm]", "< 10 mm", _get("creep", 1e3), lambda v: v < 10),
    )),
    Check("Equal targets drive straight, 10 m", "test_sim", straight, (
        Row("lateral drift / distance", "< 1 %", _get("drift", 100), lambda v: v < 1),
    )),
    Check("Turning (8 s), targets (2 s), yaw springs (15 s)", "test_sim", turning, (
        Row("yaw rate [rad/s]", "> 0.05", _get("yaw_rate"), lambda v: v > 0.05),
        Row("inner wheels' slip (skid)", "> 0", _get("inner"), lambda v: v > 0),
        Row("outer wheels' slip (spin)", "< 0", _get("outer"), lambda v: v < 0),
        Row("faster wheels' rate gain [rad/s]", "> 1", _get("faster"), lambda v: v > 1),
        Row("yaw angle left [rad]", "< 0.03", _get("yaw_springs"), lambda v: v < 0.03),
    )),
    Check("Bumps keep every wheel loaded", "test_sim", bumps, (
        Row("min F_z / static", "> 0.1", _get("min_load"), lambda v: v > 0.1),
    )),
    Check("Convergence drive, 20 s turning", "validation.md", convergence, (
        Row("end point vs 0.25 ms, % of distance", "< 1 %", _gap, lambda v: v < 1),
    ), ref_dt=REF_DT),
    Check("Paper drive, hard ground, 32 s", "paper-sim", paper_drive, (
        Row("end point vs 0.25 ms, % of distance", "< 1 %", _gap, lambda v: v < 1),
        Row("phase-mean slip vs 0.25 ms (max abs)", "< 0.005", _max_abs("slip"),
            lambda v: v < 0.005),
    ), ref_dt=REF_DT),
    Check("Paper drive on paper-sand, 32 s", "paper-sim", lambda dt: paper_drive(dt, "paper-sand"), (
        Row("end point vs 0.25 ms, % of distance", "< 1 %", _gap, lambda v: v < 1),
        Row("phase-mean slip vs 0.25 ms (max abs)", "< 0.005", _max_abs("slip"),
            lambda v: v < 0.005),
        Row("phase-mean sinkage vs 0.25 ms (max rel)", "< 2 %", _max_rel("sink"),
            lambda v: v < 2),
    ), ref_dt=REF_DT),
    Check("Flip detection; rough drive 20 s", "validation.md", flips, (
        Row("rolled 62 deg: flip reported", "1", _get("tip"), lambda v: v == 1),
        Row("rolled 50 deg: rights itself", "1", _get("control"), lambda v: v == 1),
        Row("rough drive: no warning, no NaN", "1", _get("rough"), lambda v: v == 1),
    )),
    Check("Soil rig vs SOIL.md steady state (3 presets x 5 slips, 6 s)", "soil.md", soil_rig, (
        Row("worst rel. error (pull, torque, sinkage, F_z)", "< 2 %", _get("worst", 100),
            lambda v: v < 2),
    )),
    Check("Soil rig: change of the settled state from 1 ms", "soil.md (dt halving)", soil_rig, (
        Row("largest change (pull, torque, sinkage)", "< 1 %", _max_rel("vals"), lambda v: v < 1),
    ), ref_dt=1e-3),
    Check("Spinning wheel digs itself in", "test_soil", digging, (
        Row("held, spun 8 s: depth / radius", "> 0.5", _get("spun"), lambda v: v > 0.5),
        Row("travelling at slip 0.3: depth / radius", "< 0.3", _get("rolled"), lambda v: v < 0.3),
    )),
    Check("Parked 20 s on a 10 deg loose slope", "soil.md", parked_soil, tuple(
        row
        for s in soil_validation.PRESETS
        for row in (
            Row(f"{s}: creep speed [mm/s]", "< 1", _get(f"{s}:creep", 1e3), lambda v: v < 1),
            Row(f"{s}: velocity jitter [mm/s]", "< 0.1", _get(f"{s}:vel", 1e3),
                lambda v: v < 0.1),
            Row(f"{s}: F_x jitter / resistance", "< 0.1", _get(f"{s}:fx"), lambda v: v < 0.1),
        )
    )),
    Check("Ruts: followers run in the leaders' ruts", "test_soil", ruts, (
        Row("rut under the front wheels [m]", "= 0", _get("ahead"), lambda v: v == 0),
        Row("rut under followers / front sinkage", "> 0.5", _get("behind"), lambda v: v > 0.5),
        Row("followers' sinkage (rut rig) [mm]", "> 8", lambda r, ref: 1e3 * float(
            np.min(r["followers"])), lambda v: v > 8),
    )),
    Check("Ruts: followers' sinkage change from 1 ms", "test_soil (3 %)", ruts, (
        Row("largest change", "< 3 %", _max_rel("followers"), lambda v: v < 3),
    ), ref_dt=1e-3),
    Check("Rough soil: backends agree; 30 s random drive", "test_soil, soil.md", soil_drive, (
        Row("numpy vs plugin, max abs qpos [m]", "< 1e-12", _get("backends"), lambda v: v < 1e-12),
        Row("30 s random driving: no warning, no NaN", "1", _get("endurance"), lambda v: v == 1),
    )),
)  # fmt: skip


# ----------------------------------------------------------------------------- bounds, speed


def _bound(m: float, k: float, c: float) -> float:
    """Largest stable dt of m x'' = -k x - c x' with both forces explicit (semi-implicit
    Euler: det 1 - c dt/m, trace 2 - k dt^2/m - c dt/m): c dt < 2 m and k dt^2 + 2 c dt < 4 m."""
    dt_c = 2 * m / c if c > 0 else math.inf
    dt_k = (-c + math.sqrt(c * c + 4 * k * m)) / k if k > 0 else dt_c
    return min(dt_c, dt_k)


def bounds() -> list[str]:
    """The analytic stability bounds of the explicitly applied terms, per wheel of the rover
    at rest on flat ground (effective masses from MuJoCo's mass matrix)."""
    sim = RoverSim(backend=BACKEND)
    m, d = sim.model, sim.data
    tp, cfg = sim.cfg.tire, sim.cfg
    minv = np.linalg.inv(_full_mass(m, d))
    w = sim.wheel_truth()
    r = cfg.geometry.wheel_radius
    lines = []
    b = cfg.geometry.wheel_width
    t0 = max(
        abs(float(soil_forces(0.1, 0.0, 0.1, static_sinkage(27.0, r, b, p), r, b, p).T))
        for p in map(load_soil, soil_validation.PRESETS)
    )
    k_soil = max(_soil_stiffness(p, r, b) for p in map(load_soil, soil_validation.PRESETS))
    c_soil = max(load_soil(s).damping for s in soil_validation.PRESETS)
    for i, name in enumerate(("1L", "1R", "2L", "2R", "3L", "3R")):
        body = int(sim.tires.bodies[i])
        dof = int(m.jnt_dofadr[_wheel_joint(m, body)])
        jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        mujoco.mj_jacBody(m, d, jp, jr, body)
        inv_z = float(jp[2] @ minv @ jp[2])
        inv_x = float(jp[0] @ minv @ jp[0])
        for delta, label in ((float(w.delta[i]), "at rest"), (5.0 / tp.C_z, "5 N load")):
            arm, r_e = r - delta, r - tp.k_re * delta
            inv_e = arm * r_e * float(minv[dof, dof]) + inv_x  # slip rate per unit F_x
            tire = _bound(1 / inv_e, tp.C_s / tp.sigma_x, tp.D_x)
            if label == "at rest":
                blend = 2.0 / (1.5 * r * t0 * float(minv[dof, dof]) / V_BLEND)
                normal = _bound(1 / inv_z, tp.C_z, tp.D_z)
                soil_n = _bound(1 / inv_z, k_soil, c_soil)
                lines.append(
                    f"| {name} | {1e3 * tire:.1f} | {1e3 * normal:.1f} | {1e3 * soil_n:.1f}"
                    f" | {1e3 * blend:.1f} |"
                )
            else:
                lines[-1] += f" {1e3 * tire:.1f} |"
    return [
        "| wheel | tire F_x, at rest [ms] | tire F_z [ms] | soil F_z [ms] | soil blend at"
        " standstill [ms] | tire F_x, 5 N load [ms] |",
        "|---|---:|---:|---:|---:|---:|",
        *lines,
        "",
        f"Tire F_x: spring C_s / sigma_x = {tp.C_s / tp.sigma_x:g} N/m and patch damping"
        f" D_x = {tp.D_x:g} N s/m on the slip velocity, against the wheel's effective mass"
        " 1 / (r_arm r_e / I_spin + 1 / m_x). Tire F_z: C_z, D_z on the vertical effective"
        f" mass. Soil F_z: Bekker slope {k_soil:.0f} N/m at the static sinkage and the damping"
        f" {c_soil:g} N s/m (the stiffest preset). Soil blend: the standstill damper"
        f" 1.5 T0 / V_BLEND (T0 = {t0:.3f} N m, V_BLEND = {V_BLEND} m/s) on the spin,"
        " dt < 2 I / (1.5 r T0 / V_BLEND) (rover_env/soil.py).",
    ]


def _full_mass(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    return full


def _wheel_joint(m: mujoco.MjModel, body: int) -> int:
    return int(np.flatnonzero(m.jnt_bodyid == body)[0])


def _soil_stiffness(p: Any, r: float, b: float) -> float:
    h = static_sinkage(27.0, r, b, p)
    f = [float(soil_forces(0.1, 0.0, 0.1, h * (1 + e), r, b, p).F_z) for e in (-0.01, 0.01)]
    return (f[1] - f[0]) / (0.02 * h)


def speed(dt: float) -> tuple[float, float]:
    """Substeps/s of the rover (plugin, 10 s turning) and env steps/s (ProtoExplorer-v0)."""
    sim = RoverSim(rover_at(dt), backend=BACKEND)
    sim.set_speed_targets([2.0, 3.0, 2.0, 3.0])
    n = secs(sim, 10.0)
    sub = 0.0
    for _ in range(3):  # best of three: the machine is shared
        t0 = time.perf_counter()
        sim.step(n)
        sub = max(sub, n / (time.perf_counter() - t0))
    env = gym.make("rover_env/ProtoExplorer-v0", timestep=dt)
    env.action_space.seed(0)
    env.reset(seed=0)
    steps = 0.0
    for _ in range(3):
        t0 = time.perf_counter()
        for _ in range(200):
            env.step(env.action_space.sample())
        steps = max(steps, 200 / (time.perf_counter() - t0))
    env.close()
    return sub, steps


# ----------------------------------------------------------------------------- main


def run_all(dts: list[float], log: Callable[[str], None]) -> list[str]:
    cache: dict[tuple[int, float], dict[str, Any]] = {}

    def result(c: Check, dt: float) -> dict[str, Any]:
        key = (id(c.run), dt)
        if key not in cache:
            t0 = time.perf_counter()
            cache[key] = c.run(dt)
            log(f"{c.name} at {dt * 1e3:g} ms: {time.perf_counter() - t0:.0f} s")
        return cache[key]

    head = " | ".join(f"{dt * 1e3:g} ms" for dt in dts)
    lines = [
        f"| check | source | quantity | tolerance | {head} | pass {'/'.join(f'{dt * 1e3:g}' for dt in dts)} |",
        "|---|---|---|---|" + "---:|" * len(dts) + "---|",
    ]
    for c in CHECKS:
        ref = result(c, c.ref_dt) if c.ref_dt is not None else None
        res = {dt: result(c, dt) for dt in dts}
        for row in c.rows:
            vals, marks = [], []
            for dt in dts:
                if c.ref_dt is not None and dt == c.ref_dt:
                    vals.append("(ref)")
                    marks.append("-")
                    continue
                v = row.value(res[dt], ref)
                vals.append(format(v, row.fmt))
                marks.append("PASS" if row.ok(v) else "**FAIL**")
            lines.append(
                f"| {c.name} | {c.source} | {row.quantity} | {row.tolerance} | "
                + " | ".join(vals)
                + f" | {' / '.join(marks)} |"
            )
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--dts", type=float, nargs="+", default=[1.0, 2.0, 5.0], help="ms")
    ap.add_argument("--out", default="docs/timestep.md")
    args = ap.parse_args()
    dts = [d * 1e-3 for d in args.dts]
    t_start = time.perf_counter()

    def log(msg: str) -> None:
        print(f"[{time.perf_counter() - t_start:6.0f} s] {msg}", flush=True)

    table = run_all(dts, log)
    speeds = {dt: speed(dt) for dt in dts}
    base = speeds[dts[0]]
    speed_lines = [
        "| timestep | substeps/s | simulated s per wall s | env steps/s | env steps/s ratio |",
        "|---|---:|---:|---:|---:|",
        *(
            f"| {dt * 1e3:g} ms | {s:.0f} | {s * dt:.1f} | {e:.0f} | {e / base[1]:.2f} |"
            for dt, (s, e) in speeds.items()
        ),
    ]
    text = "\n".join(
        [
            "# The physics timestep: every physical check at "
            + ", ".join(f"{d:g}" for d in args.dts)
            + " ms",
            "",
            "Generated by `nice -n 5 python benchmarks/timestep_study.py` (issue 49, item 2);"
            " what each check is and where its tolerance comes from: the script's docstrings."
            " 'ref': the run the row compares with. The env step stays 0.1 s at every"
            " timestep (its substep count is 0.1 s / timestep); choose the timestep with the"
            " env's `timestep=` argument or the rover configuration's `sim.timestep`.",
            "",
            *table,
            "",
            "## Stability bounds of the explicit terms",
            "",
            "MuJoCo integrates its own joints and actuators implicitly (implicitfast); the tire"
            " and soil forces enter as applied forces computed from the state at the start of"
            " the substep, i.e. explicitly. Each spring-damper so applied is stable while"
            " c dt < 2 m and k dt^2 + 2 c dt < 4 m (m its effective mass):",
            "",
            *bounds(),
            "",
            "## Speed (this run, same machine)",
            "",
            *speed_lines,
            "",
            f"Study wall time {time.perf_counter() - t_start:.0f} s.",
            "",
        ]
    )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_report(out, text)
    print(text)


if __name__ == "__main__":
    main()
