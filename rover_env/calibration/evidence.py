"""Missing evidence: when the held-out drive cannot confirm a candidate, ask for the drive that can.

A candidate can improve the training drives while the held-out drive cannot confirm it: the
effect is not excited there (a torque limit the drive never reaches), or only a sparse
signal carries it (a rolling radius changed on all wheels alike leaves every wheel and
joint angle as it was; only the 1 Hz pose sees it). Then the report says so and proposes
the drive that would decide (:data:`EVIDENCE_PLANS`), and shows by simulation that it
separates the hypotheses: the model with the fitted effect drives the proposed plan and
logs it; that log is replayed (the same multiple shooting as diagnose) by both the current
model and the model with the effect, and the change of every replayed signal is measured in
units of that signal's own replay floor (each signal weighed by its own noise). Through the replay, not open loop: the replay starts each window from the free
wheels, so what it can see differs from what an open-loop run shows.

Each proposal records its seed and duration (:data:`PLAN_SEED`, :data:`PLAN_DURATION`): the
real rover must DRIVE that very schedule (``rover-env drive-plan --report OUT --out DIR``
writes it as commands), be logged, imported (``rover-env import-bag``) and added to the logs
``diagnose`` reads, which hold it out beside the user's last own drive. Never simulate it:
``make-logs`` drives the nominal model, and its log added to a real rover's would corrupt
the diagnosis.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from rover_env.calibration.candidates import Extensions
from rover_env.calibration.replay import SIGNALS, Replayer, ReplaySettings, make_windows, prepare
from rover_env.config import JOINTS, WHEELS, RoverConfig, TerrainConfig, to_dict
from rover_env.generators.drives import drive_schedule
from rover_env.logs import DriveLog
from rover_env.sim.model import stable_config
from rover_env.sim.recorder import run_drive
from rover_env.sim.simulator import RoverSim

Array = NDArray[np.float64]

EVIDENCE_PLANS: dict[str, tuple[str, str]] = {
    "rolling_radius": (
        "straight",
        "a measured straight: long constant-speed runs with the pose reference, so many metres"
        " of travel are compared with many wheel turns",
    ),
    "torque_limit": (
        "accel",
        "hard accelerations from rest and full reversals (or a hard climb): the only drives"
        " that ask the motors for their limit",
    ),
    "rolling_resistance": (
        "straight",
        "long constant-speed runs forward and back: a steady resisting force shows as steady"
        " extra slip of the driven wheels and slower free wheels",
    ),
    "slope": (
        "reversals",
        "the same line forwards and backwards, a long pivot and the crossing line",
    ),
    "command_lag": ("steps", "command steps of many sizes and hold times"),
    "command_delay": ("steps", "command steps of many sizes and hold times"),
    "friction": ("turn-accel", "accelerating and braking in turns: high traction demand"),
    "combined_slip": ("turn-accel", "accelerating and braking in turns: combined slip"),
    "load_dependent_friction": ("turn-accel", "hard accelerations in turns move load"),
}


PLAN_SEED = 0
"""Seed of every proposed drive (evidence and ties): ``drive_schedule``'s draw of the plan."""
PLAN_DURATION = 50.0
"""Duration (s) of every proposed drive (evidence and ties)."""


def plan_command(plan: str, seed: int, duration: float) -> str:
    """The command that writes a proposed drive's commands, as the report and ``rover.yaml``
    quote it."""
    return f"rover-env drive-plan --plan {plan} --seed {seed} --duration {duration:g} --out DIR"


def evidence_plan(name: str) -> tuple[str, str]:
    return EVIDENCE_PLANS.get(name, ("test", "a longer test drive with a new seed"))


def simulate_plan(
    cfg: RoverConfig,
    plan: str,
    seed: int = PLAN_SEED,
    duration: float = PLAN_DURATION,
    ground: TerrainConfig | None = None,
) -> DriveLog:
    """The drive ``plan`` as ``cfg`` would log it (exact sensors, pose at 1 Hz), on the
    logs' declared ``ground`` (None: flat hard ground)."""
    where = "flat" if ground is None else ground
    sim = RoverSim(stable_config(cfg), where, backend="auto", visuals=False)
    sim.reset(sunk=True)
    sched = drive_schedule(plan, np.random.default_rng(seed), duration, cfg.motor.max_wheel_speed)
    rec = run_drive(sim, sched, duration)
    terrain = "flat" if ground is None else to_dict(ground)
    return rec.to_log("proposed", terrain=terrain, pose_rate_hz=1.0)


def separation(
    a: DriveLog, b: DriveLog, floor: dict[str, float], window: float = 3.0
) -> dict[str, float]:
    """Per signal: RMS over windows of the difference between two drives' window increments
    (wheel angles, pose) or values (joint angles), in units of the signal's replay floor."""
    t = a.t
    starts = np.arange(0.0, t[-1] - window + 1e-9, window)
    diffs: dict[str, list[float]] = {}
    for t0 in starts:
        i0, i1 = np.searchsorted(t, [t0, t0 + window])
        i1 = min(i1, len(t) - 1)
        for j, w in enumerate(WHEELS):
            da = a.phi[i1, j] - a.phi[i0, j]
            db = b.phi[i1, j] - b.phi[i0, j]
            diffs.setdefault(f"wheel_{w}", []).append(da - db)
        for j, name in enumerate(JOINTS):
            diffs.setdefault(name, []).extend(a.theta[i0:i1, j] - b.theta[i0:i1, j])
        have = np.flatnonzero(np.isfinite(a.pose[i0:i1, 0]))
        if len(have) >= 2:
            p0, p1 = i0 + have[0], i0 + have[-1]
            for j, name in enumerate(("pose_x", "pose_y", "pose_yaw")):
                dd = (a.pose[p1, j] - a.pose[p0, j]) - (b.pose[p1, j] - b.pose[p0, j])
                diffs.setdefault(name, []).append(dd)
    return {
        k: float(np.sqrt(np.mean(np.square(v))) / floor[k])
        for k, v in diffs.items()
        if v and k in floor
    }


def replay_separation(
    base: RoverConfig,
    with_effect: RoverConfig,
    log: DriveLog,
    floor: dict[str, float],
    st: ReplaySettings | None = None,
) -> tuple[dict[str, float], dict[str, float]]:
    """Per signal, the change of the replayed signal between the two models on ``log`` in
    units of the signal's replay floor: (per window RMS, over the whole drive).

    The whole-drive figure is sqrt(sum over windows of the window's mean square change) /
    floor: the evidence a drive of that many windows carries, one degree of freedom per
    window as in diagnose's tables (a rolling radius moves the pose by about one floor per
    3 s window, and a long straight has many windows).
    """
    st = st or ReplaySettings()
    prep = [prepare(log, base, "proposed", st)]
    windows = make_windows(prep, st)
    ra = Replayer(with_effect, st).run(prep, windows)
    rb = Replayer(base, st).run(prep, windows)
    per_window: dict[str, float] = {}
    total: dict[str, float] = {}
    for j, name in enumerate(SIGNALS):
        ms = []
        for a, b in zip(ra, rb, strict=True):
            col = (
                (a.resid[:, j] - b.resid[:, j])
                if j < 11
                else (a.pose_resid[:, j - 11] - b.pose_resid[:, j - 11])
            )
            col = col[np.isfinite(col)]
            if col.size:
                ms.append(float(np.mean(col**2)))
        if ms:
            per_window[name] = float(np.sqrt(np.mean(ms)) / floor[name])
            total[name] = float(np.sqrt(np.sum(ms)) / floor[name])
    return per_window, total


def propose(
    base: RoverConfig,
    name: str,
    ext: Extensions,
    floor: dict[str, float],
    held_change: dict[str, float],
    seed: int = PLAN_SEED,
    duration: float = PLAN_DURATION,
    ground: TerrainConfig | None = None,
) -> dict[str, Any]:
    """The drive that would decide candidate ``name`` (fitted ``ext``), shown by simulation
    on the logs' declared ``ground`` (None: flat hard ground)."""
    from dataclasses import replace

    plan, why = evidence_plan(name)
    with_effect = replace(base, extensions={**base.extensions, **ext})
    log = simulate_plan(with_effect, plan, seed, duration, ground)
    st = ReplaySettings(terrain=ground)
    per_window, sep = replay_separation(base, with_effect, log, floor, st)
    best = max(sep, key=lambda k: sep[k]) if sep else ""
    held_best = max(held_change, key=lambda k: held_change[k]) if held_change else ""
    return {
        "effect": name,
        "plan": plan,
        "why": why,
        "seed": seed,  # what the real rover must drive: drive_schedule(plan, seed, duration)
        "duration": duration,
        "separation": sep,
        "best_signal": best,
        "best_floor_units": sep.get(best, 0.0),
        "best_per_window": per_window.get(best, 0.0),
        "held_out_best_signal": held_best,
        "held_out_floor_units": held_change.get(held_best, 0.0),
        "separates": bool(sep) and sep.get(best, 0.0) >= 3.0,
    }


__all__ = [
    "EVIDENCE_PLANS",
    "PLAN_DURATION",
    "PLAN_SEED",
    "evidence_plan",
    "propose",
    "replay_separation",
    "separation",
    "simulate_plan",
]
