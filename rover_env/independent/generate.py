"""``make_independent_logs``: SPEC §6 drive logs of one independently built rover, plus truth.

A case is one rover (one nuisance draw, from ``seed``) driven ``drives`` times, each with its own
plan, its own sensor noise and its own world seed. Logs are written at 50 Hz (``sample_rate_hz``
50: a choice; SPEC gives no rate), ``rover: proto_explorer``, ``terrain: flat`` (what a tester
would write even on a slope or loose soil: the effect is what diagnose must find), with a
``truth.yaml`` beside them holding the effects, the nuisance draw and the drive plans.

``plan`` drives a given plan instead of the seeded ones (every drive the same targets): a list of
(duration, left, right, ramp) manoeuvres (:mod:`.drive`; the drive lasts their total) or a
:class:`~rover_env.independent.drive.Schedule` (it lasts until its last row). ``first_index``
numbers the files from there (``drive_03.csv``...) and draws their sensor noise as the drives of
that index would: a follow-up drive of the same rover (same ``seed``: the same build) adds to
the first ones without repeating their noise.

``headings``: where each drive starts facing. ``same`` (every drive along the world's +x, the
slope's ``heading_deg`` then in every log's frame); ``drawn`` (each drive's start heading
drawn from ``seed`` and its index, uniform over the circle, and written to its YAML as
``start_heading_deg``: a rover whose drives start wherever the last ended, with a compass);
``unlogged`` (drawn as ``drawn``, not written: the same rover without one). The slope's
``heading_deg`` is then in the world, and each log sees it turned by its start.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

import rover_env.independent.drive as drive
import rover_env.independent.motor as motor
import rover_env.independent.nuisance as nuisance_mod
import rover_env.independent.sensors as sensors
import rover_env.independent.tire as tire
from rover_env.independent.effects import resolve
from rover_env.independent.model import RoverParams
from rover_env.independent.simulate import CONTROL_EVERY, DT, SETTLE_S, simulate
from rover_env.logs import DriveLog, LogMeta, write_log

HEADINGS = ("same", "drawn", "unlogged")
"""Where each drive starts facing (module docstring)."""

SAMPLE_HZ = 50.0


def make_independent_logs(
    out: str | Path,
    effects: dict[str, dict[str, float]],
    drives: int = 3,
    seed: int = 0,
    duration: float = 50.0,
    nuisance: bool | Sequence[str] = True,
    plan: list[drive.Manoeuvre] | drive.Schedule | None = None,
    first_index: int = 0,
    effort: bool = False,
    headings: str = "same",
    kinds: Sequence[str] = (),
) -> list[Path]:
    """Write ``drives`` logs of ``duration`` seconds (or ``plan``'s) into ``out``; returns the
    CSV paths. ``nuisance``: the build drawn from ``seed`` (True), built to drawing (False),
    or drawn in the named part or parts only (:data:`~rover_env.independent.nuisance.GROUPS`).
    ``effort``: the logs also carry the drivers' reported motor torque (``effort_*`` columns).
    ``kinds``: drive ``i`` is of kind ``kinds[i % len(kinds)]`` (:data:`.drive.KINDS`; empty:
    the kinds rotate with the index and the seed)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    eff = resolve(effects)
    if headings not in HEADINGS:
        raise ValueError(f"headings must be one of {HEADINGS}, got {headings!r}")
    if first_index < 0:
        raise ValueError(f"first_index must be >= 0, got {first_index}")
    unknown = [k for k in kinds if k not in drive.KINDS]
    if unknown:
        raise ValueError(f"unknown drive kind(s) {unknown}; known: {', '.join(drive.KINDS)}")
    if isinstance(plan, drive.Schedule):
        duration = plan.duration
    elif plan is not None:
        if not plan or any(len(m) != 4 or m[0] <= 0 or m[3] < 0 for m in plan):
            raise ValueError("plan: manoeuvres are (duration > 0, left, right, ramp >= 0)")
        plan = [(float(a), float(b), float(c), float(d)) for a, b, c, d in plan]
        duration = float(sum(m[0] for m in plan))
    # The parts drawn off the drawing: None for all (True) or none (False); one name or several.
    groups: list[str] | None = None
    if isinstance(nuisance, bool):
        draw = nuisance_mod.draw(seed) if nuisance else nuisance_mod.nominal()
    else:
        groups = [nuisance] if isinstance(nuisance, str) else list(nuisance)
        draw = nuisance_mod.partial(seed, groups)
    params = nuisance_mod.apply(RoverParams(), draw)
    t = np.round(np.arange(0.0, duration + 0.5 / SAMPLE_HZ, 1.0 / SAMPLE_HZ), 9)
    paths: list[Path] = []
    plans: list[dict[str, Any]] = []
    for i in range(first_index, first_index + drives):
        kind, record, cmd = _targets(plan, i, seed, duration, t, tuple(kinds))
        start = start_heading(seed, i) if headings != "same" else 0.0
        seen = dataclasses.replace(eff, slope_heading_deg=eff.slope_heading_deg - start)
        truth = simulate(params, seen, t, cmd)
        rng = np.random.default_rng([47, 3, seed, i])
        phi = sensors.encoder_angles(truth.phi, params.encoder_cpr, rng.uniform(0.0, 1.0, 6))
        theta = sensors.potentiometers(
            truth.theta, np.array(params.pot_gain), np.array(draw["pot_offset_rad"]), rng
        )
        pose = sensors.pose_fixes(t, truth.pose, rng)
        meta = LogMeta(
            rover="proto_explorer",
            sample_rate_hz=SAMPLE_HZ,
            terrain="flat",
            notes=f"independent generator (issue 47), seed {seed}, drive {i} ({kind})",
            start_heading_deg=start if headings == "drawn" else None,
        )
        tau = np.zeros((0, 4))
        if effort:  # its own stream: the other columns are the same with or without it
            per_amp = motor.K_T_DATASHEET * motor.GEAR * motor.EFF
            tau = sensors.effort(truth.current, per_amp, np.random.default_rng([47, 4, seed, i]))
        log = DriveLog(t=t, cmd=cmd, phi=phi, theta=theta, pose=pose, meta=meta, effort=tau)
        paths.append(write_log(log, out / f"drive_{i:02d}.csv", overwrite=True))
        plans.append({"file": paths[-1].name, "kind": kind, "start_heading_deg": start, **record})
    truth_doc = {
        "generator": "rover_env.independent",
        "seed": seed,
        "duration_s": duration,
        "effects": {k: {kk: float(vv) for kk, vv in v.items()} for k, v in effects.items()},
        "nuisance": draw if nuisance else None,
        **({} if groups is None else {"nuisance_groups": groups}),
        "forms": {
            "physics_step_s": DT,
            "integrator": "implicitfast",
            "speed_loop_hz": 1.0 / (DT * CONTROL_EVERY),
            "log_rate_hz": SAMPLE_HZ,
            "settle_s": SETTLE_S,
            "rolling_radius": "d - delta/3 (tire), d (soil)",
            "tire_relaxation_length_m": tire.SIGMA,
            "anti_windup": f"back-calculation, T_t {motor.T_TRACK} s",
        },
        "drives": plans,
    }
    (out / "truth.yaml").write_text(yaml.safe_dump(truth_doc, sort_keys=False), encoding="utf-8")
    return paths


def start_heading(seed: int, i: int) -> float:
    """Drive ``i``'s start heading in the world (degrees) where ``headings`` draws them."""
    return round(float(np.random.default_rng([47, 7, seed, i]).uniform(-180.0, 180.0)), 1)


def _targets(
    plan: list[drive.Manoeuvre] | drive.Schedule | None,
    i: int,
    seed: int,
    duration: float,
    t: np.ndarray,
    kinds: tuple[str, ...] = (),
) -> tuple[str, dict[str, Any], np.ndarray]:
    """Drive ``i``'s plan kind, its record for truth.yaml, and its (N, 4) targets at ``t``."""
    if isinstance(plan, drive.Schedule):
        rows = {"t": plan.t.tolist(), "cmd": plan.cmd.tolist()}
        return "given schedule", {"schedule": rows}, plan.at(t)
    if plan is not None:
        return "given manoeuvres", {"manoeuvres": [list(m) for m in plan]}, drive.targets(plan, t)
    kind = kinds[i % len(kinds)] if kinds else drive.drive_kind(i, seed)
    manoeuvres = drive.plan(kind, duration, seed * 1000 + i)
    return kind, {"manoeuvres": [list(m) for m in manoeuvres]}, drive.targets(manoeuvres, t)
