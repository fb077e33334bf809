"""Long physical checks that do not belong in the default test run; the report is committed.

- Timestep convergence: a 20 s turning drive ends within 1 % of the distance travelled of
  the same drive at a quarter of the timestep.
- Endurance: 5 minutes of random speed targets on the rough scene with no MuJoCo warning and
  no NaN; flips and arena exits are detected, reported, and the rover is put back.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import mujoco
import numpy as np
from tqdm import tqdm

from rover_env.config import RoverConfig, SimSpec, load_rover
from rover_env.sim.simulator import RoverSim


def convergence(duration: float = 20.0) -> dict[str, float]:
    """End-point difference of a turning drive at dt and dt/4, in % of distance travelled."""
    base = load_rover()
    ends = []
    dist = 0.0
    for div in (1, 4):
        cfg = dataclasses.replace(base, sim=SimSpec(timestep=base.sim.timestep / div))
        sim = RoverSim(cfg)
        n = round(0.1 / sim.dt)
        p_prev = sim.segment_truth().pos[1].copy()
        dist = 0.0
        for k in range(round(duration / 0.1)):
            t = k * 0.1
            sim.set_speed_targets([1.5, 3.0, 1.5, 3.0] if t >= 2.0 else [2.5] * 4)
            sim.step(n)
            p = sim.segment_truth().pos[1].copy()
            dist += float(np.linalg.norm(p[:2] - p_prev[:2]))
            p_prev = p
        ends.append(sim.segment_truth().pos[1].copy())
    gap = float(np.linalg.norm(ends[0][:2] - ends[1][:2]))
    return {
        "timestep": base.sim.timestep,
        "distance": dist,
        "gap": gap,
        "gap_percent": 100 * gap / dist,
    }


def endurance(
    duration: float = 300.0,
    seed: int = 0,
    hold: float = 2.0,
    rover: RoverConfig | str = "proto_explorer",
    backend: str = "numpy",
) -> dict[str, float]:
    """Random speed targets on the rough scene; counts flips and arena exits."""
    rng = np.random.default_rng(seed)
    sim = RoverSim(rover, terrain="rough", backend=backend)
    half = np.array(sim.terrain_cfg.size) / 2 - 1.0
    lim = sim.cfg.motor.max_wheel_speed
    n = round(hold / sim.dt)
    flips = exits = 0
    fz_max = 0.0
    steps = round(duration / hold)
    for _ in tqdm(range(steps), desc="rough drive", unit="cmd", leave=False):
        sim.set_speed_targets(rng.uniform(-lim, lim, 4))
        sim.step(n)  # raises SimulationError on any MuJoCo warning or NaN
        fz_max = max(fz_max, float(sim.wheel_truth().F_z.max()))
        pos = sim.segment_truth().pos[1]
        if sim.flipped():
            flips += 1
            sim.reset(x=0.0, y=0.0, yaw=float(rng.uniform(-np.pi, np.pi)))
        elif np.any(np.abs(pos[:2]) > half):
            exits += 1
            sim.reset(x=0.0, y=0.0, yaw=float(rng.uniform(-np.pi, np.pi)))
    return {"duration": duration, "flips": flips, "exits": exits, "max_F_z": fz_max}


def tip_over(
    roll_deg: float = 62.0, duration: float = 2.0, rover: RoverConfig | str = "proto_explorer"
) -> dict[str, float]:
    """Release the rover rolled past its tipping angle: it must fall and be reported flipped."""
    sim = RoverSim(rover)
    sim.reset(settle=0.0)
    q = np.zeros(4)
    mujoco.mju_axisAngle2Quat(q, np.array([1.0, 0.0, 0.0]), np.radians(roll_deg))
    sim.data.qpos[3:7] = q
    sim.data.qpos[2] += 0.05
    flipped_at = float("nan")
    for _ in range(round(duration / 0.01)):
        sim.step(round(0.01 / sim.dt))
        if sim.flipped() and not np.isfinite(flipped_at):
            flipped_at = sim.time
    return {"roll_deg": roll_deg, "flipped": float(sim.flipped()), "flipped_at": flipped_at}


def run(out_dir: str | Path, quick: bool = False) -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    conv = convergence(5.0 if quick else 20.0)
    t1 = time.perf_counter()
    end = endurance(20.0 if quick else 300.0)
    t2 = time.perf_counter()
    tip = tip_over(62.0)
    ctl = tip_over(50.0)
    ok_conv = conv["gap_percent"] < 1.0
    lines = [
        "# Validation report (`rover-env validate`)",
        "",
        "## Timestep convergence",
        f"- {conv['distance']:.2f} m turning drive at dt = {conv['timestep'] * 1e3:g} ms vs "
        f"dt/4: end points {conv['gap'] * 1e3:.2f} mm apart = {conv['gap_percent']:.3f} % of distance "
        f"({'PASS' if ok_conv else 'FAIL'}: < 1 %). Wall time {t1 - t0:.0f} s.",
        "",
        "## Endurance on the rough scene",
        f"- {end['duration']:.0f} s of random speed targets (new every 2 s, seed 0): no MuJoCo warning,"
        " no NaN (the simulator raises on either).",
        f"- Flips detected and reset: {end['flips']}; arena exits reset: {end['exits']};"
        f" largest F_z {end['max_F_z']:.1f} N. Wall time {t2 - t1:.0f} s.",
        "",
        "## Flip detection",
        f"- Rover released rolled {tip['roll_deg']:.0f} deg (past its ~58 deg tipping angle) on"
        " flat ground: "
        + (
            f"falls over, flip reported at t = {tip['flipped_at']:.2f} s (PASS)."
            if tip["flipped"]
            else "no flip reported (FAIL)."
        ),
        f"- Control, released rolled {ctl['roll_deg']:.0f} deg: "
        + ("rights itself, no flip reported (PASS)." if not ctl["flipped"] else "flip (FAIL)."),
    ]
    report = out / "validation.md"
    report.write_text("\n".join(lines) + "\n")
    return report
