"""Hidden-effect data: SPEC §6 logs from a truth model with model extensions switched on.

``rover-env make-logs --effect NAME=VALUE ... --drives N --seed S --out DIR`` simulates N
drives of a test plan with the effects on, reads them through realistic sensors (wheel
encoders quantised to 0.01 rad, 10-bit joint potentiometers with noise, an external pose
reference at 1 Hz with mm-level noise) and writes ``DIR/drive_XX.csv/.yaml`` naming the
*nominal* rover, as a real rover's logs would. The truth (effects, seeds, plan, sensors) goes
to ``DIR/truth.yaml``, which ``diagnose`` never reads.

Test plans (``--plan``), each 50 s by default, drawn with the seed:

* ``test`` (default): what a test engineer would drive to expose an unknown effect: step
  accelerations from rest, straight runs at several speeds, left and right turns, a pivot
  turn, braking to a stop, reversing straight and turning;
* ``reversals``: long forward and backward runs on one line, a long pivot, and the same on
  the crossing line (separates a slope, which helps one way, from rolling resistance, which
  opposes both, and reads the slope across the first line);
* ``turn-accel``: accelerating and braking while turning (separates combined slip, the
  friction ellipse, from the friction level);
* ``steps``: command steps of many sizes with holds of varied length (separates lag from
  delay);
* ``speeds``: slow constant speeds and gentle turns at many loads (separates rolling radius
  from slip);
* ``straight``: a measured straight: long runs at constant speed, forward and back, so the
  pose reference sees many metres of travel against many wheel turns (decides a rolling
  radius that changes all wheels alike, which only the pose can see);
* ``accel``: hard accelerations from rest and full reversals at the largest target, the
  drive that reaches a motor's torque limit (on flat ground, the nearest to a hard climb).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from rover_env.config import ConfigError, RoverConfig, load_rover, to_dict
from rover_env.effects import CATALOGUE, EffectError, effect_class
from rover_env.estimation.sensors import SensorConfig, apply_sensors
from rover_env.generators.drives import PLANS, drive_schedule
from rover_env.logs import DriveLog, write_log
from rover_env.sim.recorder import run_drive
from rover_env.sim.simulator import RoverSim

Array = NDArray[np.float64]

POSE_NOISE_M = 0.005
"""External pose reference noise (m rms), e.g. a total station or motion capture."""
POSE_NOISE_YAW = 0.005
"""Its heading noise (rad rms)."""
HEADINGS = ("same", "drawn", "unlogged")
"""Where each drive starts facing (:func:`make_logs`' ``headings``)."""
EFFORT_NOISE = 0.02
"""The motors' reported torque's noise (N m rms, white): a driver's current sense, 1/150 of
the limit (a choice; SPEC logs no torque)."""


def parse_effects(items: list[str]) -> dict[str, dict[str, float]]:
    """``NAME=VALUE`` (the effect's first parameter) or ``NAME.PARAM=VALUE`` -> extensions."""
    out: dict[str, dict[str, float]] = {}
    for item in items:
        key, sep, val = item.partition("=")
        if not sep:
            raise ConfigError(f"--effect {item!r}: expected NAME=VALUE")
        name, _, param = key.strip().partition(".")
        try:
            cls = effect_class(name)
        except EffectError as exc:
            raise ConfigError(f"--effect {item!r}: {exc}") from None
        pname = param or cls.params[0].name
        if pname not in {p.name for p in cls.params}:
            raise ConfigError(f"--effect {item!r}: {name} has no parameter {pname!r}")
        v = val.strip().lower()
        value = {"on": 1.0, "true": 1.0, "off": 0.0, "false": 0.0}.get(v)
        if value is None:
            try:
                value = float(v)
            except ValueError:
                raise ConfigError(f"--effect {item!r}: {val!r} is not a number") from None
        out.setdefault(name, {})[pname] = value
    return out


def make_logs(
    out: str | Path,
    effects: dict[str, dict[str, float]],
    drives: int = 3,
    seed: int = 0,
    duration: float = 50.0,
    plan: str = "test",
    pose_rate_hz: float | None = 1.0,
    pose_end_only: bool = False,
    rover: str | Path = "proto_explorer",
    truth_rover: RoverConfig | None = None,
    sample_rate_hz: float = 50.0,
    progress: bool = True,
    first_index: int = 0,
    effort: bool = False,
    headings: str = "same",
) -> list[Path]:
    """Write ``drives`` logs and ``truth.yaml`` to ``out``; return the CSV paths.

    ``truth_rover`` replaces the nominal rover as the truth (for effects outside the
    catalogue, e.g. a heavier rover); the logs still name ``rover``. ``effort``: the logs
    also carry the motors' torque (``effort_*``), with :data:`EFFORT_NOISE` drawn from a
    stream of its own (the other columns are the same with or without it).

    ``headings``: where each drive starts facing. "same": every drive along the world's +x
    (a slope's ``heading_deg`` then in every log's frame). "drawn": each drive's start
    heading drawn from ``seed`` and its index (:func:`start_heading`), uniform over the
    circle, and written to its YAML as ``start_heading_deg``. "unlogged": drawn alike, not
    written (drives that share no frame: ``diagnose --frames fit``). A slope's
    ``heading_deg`` is then in the world, and each log sees it turned by its start.
    """
    if headings not in HEADINGS:
        raise ValueError(f"headings must be one of {HEADINGS}, got {headings!r}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    nominal = load_rover(rover)
    base = truth_rover if truth_rover is not None else nominal
    truth_cfg = replace(base, extensions={**base.extensions, **effects})
    sensors = SensorConfig()
    paths: list[Path] = []
    starts: list[float] = []
    ss = np.random.SeedSequence(seed)
    kids = ss.spawn(first_index + drives)[first_index:]
    for i, kid in enumerate(kids):
        k = first_index + i
        # spawn(4)'s first three children are spawn(3)'s: effort's noise has the fourth.
        rng_plan, rng_sens, rng_pose, rng_eff = (np.random.default_rng(s) for s in kid.spawn(4))
        start = start_heading(seed, k) if headings != "same" else 0.0
        sim = RoverSim(facing(truth_cfg, start), "flat", backend="auto")
        sim.reset(sunk=True)
        sched = drive_schedule(plan, rng_plan, duration, nominal.motor.max_wheel_speed)
        if progress:
            print(f"make-logs: drive {k + 1}/{first_index + drives} ({plan}, {sim.backend})")
        rec = run_drive(sim, sched, duration, sample_rate_hz=sample_rate_hz)
        log = rec.to_log(
            str(rover),
            terrain="flat",
            notes=f"make-logs plan {plan}, seed {seed}, drive {k}",
            pose_rate_hz=pose_rate_hz,
            pose_end_only=pose_end_only,
            effort=effort,
        )
        log = apply_sensors(log, sensors, rng_sens)
        pose = log.pose.copy()
        m = np.isfinite(pose[:, 0])
        m[0] = False  # the origin is exact by definition
        pose[m, :2] += rng_pose.normal(0.0, POSE_NOISE_M, (int(m.sum()), 2))
        pose[m, 2] += rng_pose.normal(0.0, POSE_NOISE_YAW, int(m.sum()))
        tau = log.effort + rng_eff.normal(0.0, EFFORT_NOISE, log.effort.shape)  # NaN stays
        meta = replace(log.meta, start_heading_deg=start if headings == "drawn" else None)
        log = DriveLog(log.t, log.cmd, log.phi, log.theta, pose, meta, effort=tau)
        starts.append(start)
        paths.append(write_log(log, out / f"drive_{k:02d}.csv", overwrite=True))
    truth: dict[str, Any] = {
        "effects": effects,
        "seed": seed,
        "drives": [p.name for p in paths],
        "plan": plan,
        "duration_s": duration,
        "sample_rate_hz": sample_rate_hz,
        "pose_rate_hz": None if pose_end_only else pose_rate_hz,
        "pose_end_only": pose_end_only,
        "pose_noise": {"xy_m": POSE_NOISE_M, "yaw_rad": POSE_NOISE_YAW},
        "effort_noise_nm": EFFORT_NOISE if effort else None,
        "sensors": asdict(sensors),
        "rover": str(rover),
        "headings": headings,
        "start_headings_deg": starts,
    }
    if truth_rover is not None:
        truth["truth_rover"] = to_dict(truth_rover)
    tpath = out / "truth.yaml"
    if first_index > 0 and tpath.is_file():
        old = yaml.safe_load(tpath.read_text()) or {}
        extra = old.get("extra_drives", [])
        extra.append(
            {"plan": plan, "seed": seed, "drives": truth["drives"], "start_headings_deg": starts}
        )
        old["extra_drives"] = extra
        truth = old
    tpath.write_text(yaml.safe_dump(truth, sort_keys=False))
    return paths


def start_heading(seed: int, k: int) -> float:
    """Drive ``k``'s start heading in the world (degrees) where ``headings`` draws them: a
    stream of its own, so the drives' other draws are the same with or without it."""
    return round(float(np.random.default_rng([1998, 5, seed, k]).uniform(-180.0, 180.0)), 1)


def facing(cfg: RoverConfig, start: float) -> RoverConfig:
    """``cfg`` as a drive that started facing ``start`` (degrees) sees it: a slope rising
    toward ``heading_deg`` in the world rises toward ``heading_deg - start`` in the log's
    frame (segment 3 along +x at its start, SPEC §6), within +-180°. Other effects have no
    direction."""
    slope = cfg.extensions.get("slope")
    if not slope or start == 0.0:
        return cfg
    heading = math.remainder(float(slope.get("heading_deg", 0.0)) - start, 360.0)
    turned = {**slope, "heading_deg": heading}
    return replace(cfg, extensions={**cfg.extensions, "slope": turned})


def _cli(args: argparse.Namespace) -> int:
    effects = parse_effects(args.effect or [])
    RoverConfig(extensions=effects)  # validate before simulating
    common: dict[str, Any] = {
        "drives": args.drives,
        "seed": args.seed,
        "duration": args.duration,
        "plan": args.plan,
        "rover": args.rover,
        "progress": not args.quiet,
        "first_index": args.first_index,
    }
    if args.generator == "foreign":
        from rover_env.generators.foreign_logs import make_foreign_logs

        if args.pose_end_only or args.pose_rate != 1.0:
            raise ConfigError("--generator foreign: the pose reference is fixed at 1 Hz")
        if args.effort:
            raise ConfigError("--generator foreign logs no motor torque (--effort)")
        if args.headings != "same":
            raise ConfigError("--generator foreign: every drive starts along +x (--headings)")
        paths = make_foreign_logs(args.out, effects, **common)
    else:
        paths = make_logs(
            args.out,
            effects,
            pose_rate_hz=args.pose_rate,
            pose_end_only=args.pose_end_only,
            effort=args.effort,
            headings=args.headings,
            **common,
        )
    for p in paths:
        print(f"wrote {p}")
    print(f"truth in {Path(args.out) / 'truth.yaml'}")
    return 0


def add_cli(sub: Any) -> None:
    names = ", ".join(f"{n} ({c.params[0].name}, {c.params[0].unit})" for n, c in CATALOGUE.items())
    p = sub.add_parser(
        "make-logs",
        help="SPEC §6 logs from a truth model with hidden model extensions",
        description=f"Effects: {names}. NAME=VALUE sets the first parameter, NAME.PARAM=VALUE "
        "any other (e.g. slope.heading_deg=90); switches take on/off.",
    )
    p.add_argument("--effect", action="append", metavar="NAME=VALUE", help="repeatable")
    p.add_argument("--drives", type=int, default=3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--duration", type=float, default=50.0, help="s per drive (default 50)")
    p.add_argument("--plan", choices=PLANS, default="test", help="drive plan (default: test)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--pose-rate", type=float, default=1.0, help="Hz of the pose reference")
    g.add_argument("--pose-end-only", action="store_true", help="pose at the last sample only")
    p.add_argument("--rover", default="proto_explorer", help="nominal rover named in the logs")
    p.add_argument("--first-index", type=int, default=0, help="number drives from this index")
    p.add_argument(
        "--generator",
        choices=("rover_env", "foreign"),
        default="rover_env",
        help="rover_env: this project's simulator; foreign: a deliberately different"
        " implementation of the same rover (rover_env.generators.foreign_logs)",
    )
    p.add_argument(
        "--effort",
        action="store_true",
        help="also log the motors' torque (effort_1L .. effort_2R, N m; this simulator only)",
    )
    p.add_argument(
        "--headings",
        choices=HEADINGS,
        default="same",
        help="where each drive starts facing: same (+x), drawn (written to each YAML as"
        " start_heading_deg), unlogged (drawn, not written: diagnose with --frames fit)",
    )
    p.add_argument("--out", required=True)
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_cli)


__all__ = ["PLANS", "add_cli", "drive_schedule", "make_logs", "parse_effects"]
