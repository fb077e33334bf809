"""Stage 1, split: read the logs and the rover they name, prepare them on their declared
ground, cut them into windows and split those into training and held-out sets.

Owns the split rule: the last log (by file name) is held out, the others train; a single
log alternates its windows. Why a whole held-out drive: windows of one drive share its
conditions, so a candidate must explain a drive it was not fitted on. A drive a diagnosis
asked for (a log holding a proposed plan's draw, :mod:`~rover_env.calibration.plans_held`)
joins the held-out set beside the last of the user's own drives, and the training drives
stay the first diagnosis's: every candidate is judged on both. Why (stop 131): held out
alone, a drive asked for one question judged every candidate; in block 54700 the crossing
drive asked for a slope took back right command delays and lags that the user's held-out
drive had confirmed. With
``Options.interleave`` (``--interleave``) every drive alternates its windows instead: an
effect that only one drive excites (a torque limit only its reversals reach) is then in
both sets, where the default split either cannot fit it (held out) or cannot confirm it.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import replace
from pathlib import Path

from rover_env.calibration.diagnosis.frames import fit_frames
from rover_env.calibration.diagnosis.procedure import check_options, differences
from rover_env.calibration.diagnosis.state import STRAIGHT, Diagnosis
from rover_env.calibration.ground import common_ground
from rover_env.calibration.heading import check_frames
from rover_env.calibration.plans_held import HeldPlans, held_plans
from rover_env.calibration.replay import Window, make_windows, prepare, straight_windows
from rover_env.config import RoverConfig, load_rover, resolve_path
from rover_env.logs import DriveLog, LogError, read_log


def rover_of(log: DriveLog) -> RoverConfig:
    """The rover a log names: a file beside the log, or a configuration name."""
    return load_rover(log.beside(log.meta.rover))


def asked_logs(held: HeldPlans) -> set[str]:
    """The logs that hold a proposed plan's draw: drives a diagnosis asked for."""
    return {h["log"] for draws in held.values() for h in draws}


def held_out_indices(names: list[str], asked: set[str]) -> list[int]:
    """Indices of the held-out logs (``names`` sorted): the last of the user's own drives
    and every asked drive, where at least two own drives leave one to train on; else the
    last log. Why not the asked drives in training: a tie's separating drive must judge
    the tie, and the first diagnosis's fits stay what they were."""
    own = [i for i, n in enumerate(names) if n not in asked]
    if len(own) < 2 or len(own) == len(names):
        return [len(names) - 1]
    return sorted([own[-1], *(i for i, n in enumerate(names) if n in asked)])


def split_text(names: list[str], held: list[int], asked: Collection[str] = ()) -> str:
    """The split in words, for the progress and the report; an asked drive is marked so
    that a user sees why a log that is not the last is held out."""
    train = ", ".join(n for i, n in enumerate(names) if i not in held)
    out = ", ".join(names[i] + (" (asked)" if names[i] in asked else "") for i in held)
    return f"training: {train}; held out: {out}"


def split(d: Diagnosis) -> None:
    """Sets the logs, the rover, the replay settings, the prepared logs and the windows."""
    if not d.paths:
        raise LogError("no logs given")
    # The last by file name is held out, wherever it lies: a drive a report proposed, logged
    # as drive_03 beside drive_00-02 in its own folder, is the new evidence. (Until stop 54
    # the whole path was sorted, and "followup_0/drive_03.csv" went first, into training.)
    files = sorted((Path(p) for p in d.paths), key=lambda p: (p.name, str(p)))
    logs = [read_log(p) for p in files]
    check_frames(logs, files)
    rovers = {lg.meta.rover for lg in logs}
    if len(rovers) > 1:
        raise LogError(f"the logs name different rovers ({', '.join(sorted(rovers))})", files[0])
    base = rover_of(logs[0])
    logs = fit_frames(d, logs, files, base)  # with --frames fit, each its fitted start heading
    # The ground the logs declare (flat, a uniform slope or soil), or one clear refusal.
    st = replace(d.opts.settings, terrain=common_ground(logs))
    prepared = [prepare(lg, base, f.name, st) for lg, f in zip(logs, files, strict=True)]
    all_w = make_windows(prepared, st)
    names = [f.name for f in files]
    d.held_plans = held_plans(logs, names, base.motor.max_wheel_speed)
    if len(logs) >= 2 and not d.opts.interleave:
        asked = asked_logs(d.held_plans)
        held_logs = held_out_indices(names, asked)
        train_w = [w for w in all_w if w.log_index not in held_logs]
        held_w = [w for w in all_w if w.log_index in held_logs]
        text = split_text(names, held_logs, asked)
    else:  # one log, or --interleave: each log's even windows train, its odd ones are held out
        by_log = [[w for w in all_w if w.log_index == i] for i in range(len(logs))]
        train_w = [w for ws in by_log for w in ws[0::2]]
        held_w = [w for ws in by_log for w in ws[1::2]]
        where = "every log" if len(logs) >= 2 else f"one log ({files[0].name})"
        text = f"{where}: even windows training, odd windows held out"
    if len(train_w) < 3 or len(held_w) < 3:
        raise LogError("too little data: need at least 3 training and 3 held-out windows", files[0])
    sub_w = train_w[:: max(1, d.opts.numpy_every)]
    sets: dict[str, list[Window]] = {"train": train_w, "train_sub": sub_w, "held": held_w}
    # Windows of every drive without a turn (:mod:`.straight` reads a named soil there).
    sets[STRAIGHT] = straight_windows(prepared, train_w + held_w)
    d.files, d.logs, d.base, d.st, d.prepared, d.split = files, logs, base, st, prepared, text
    d.all_w, d.train_w, d.held_w, d.sets = all_w, train_w, held_w, sets
    d.say(f"{len(logs)} log(s), {text}; windows {len(train_w)} training, {len(held_w)} held out")
    for plan, have in d.held_plans.items():
        d.say(
            f"the logs hold plan {plan!r}: "
            + ", ".join(f"seed {h['seed']} ({h['log']})" for h in have)
        )
    table = d.opts.form_allowance
    if d.allowance is not None and table is not None and d.allowance_differs is None:
        check_options(d.allowance, resolve_path(table, "calibration"))
        d.allowance_differs = differences(d.opts, d.allowance, base)
        for line in d.allowance_differs:
            d.say(f"the clean-fit allowance was measured otherwise: {line}")
