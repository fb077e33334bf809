"""Stage 1 (part), frames: each log's start heading fitted where the drives share no frame
and the logs cannot say (``--frames fit``).

SPEC §6 puts each log's pose in its own frame, segment 3 at its start. A rover whose heading
starts anew each drive (a gyro integrated from power-on, no compass) logs drives that may
have started facing any way, and a slope then reads in as many directions as there are
logs. With ``Options.frames`` "fit" the balance's steady straight runs
(:func:`rover_env.calibration.balance.frame_turns`) turn each log's frame into the first's
where that fits them :data:`FIT_F` times better or more, and the logs are read on as if
each gave that turn as its ``start_heading_deg``: the windows' tilted gravity, both
balances and the report all use it. Under :data:`FIT_F` (a small slope, runs in few
headings, level ground) the logs are read as facing the same way, as with "given". Either
way the balance gives a slope's size and no heading
(:attr:`rover_env.calibration.balance.BalanceReading.frames_placed`): the turns decide the
size, not the heading (block 54000, docs/calibration/studies.md); and the size and its
interval are its profile's over each log's free turn
(:mod:`rover_env.calibration.size_profile`), which needs no turn decided.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from rover_env.calibration.balance import frame_turns
from rover_env.calibration.diagnosis.balance_stage import TURNED_F, source
from rover_env.calibration.diagnosis.state import Diagnosis
from rover_env.config import RoverConfig
from rover_env.logs import DriveLog, LogError

FRAMES = ("given", "fit")
"""What ``Options.frames`` may be."""
FIT_F = TURNED_F
"""The F ratio of the turned runs (:func:`rover_env.calibration.balance.turned_frames`) from
which the turns are taken; under it the logs are read as facing the same way. Why: free
turns fit noise and misfit too, and a tilt read through them comes out larger and pointing
wherever the turns put it. Exploratory seed 74834 (a 0.71° slope, its drives started at
0°, -176° and -47°, one log with no steady straight run): turned at F 5.7 the turns were
42-126° off and the balance named 1.41° [0.69, 1.84] pointing 97° off the truth. Taken
where the frames' note speaks (:data:`.balance_stage.TURNED_F`)."""


def fit_frames(
    d: Diagnosis, logs: list[DriveLog], files: list[Path], base: RoverConfig
) -> list[DriveLog]:
    """``logs`` as the diagnosis reads them: unchanged with ``frames`` "given"; with "fit",
    each with its fitted turn as its start heading, recorded in :attr:`Diagnosis.frames`.
    One clear error where a log already gives its start heading."""
    how = d.opts.frames
    if how not in FRAMES:
        raise ValueError(f"frames must be one of {FRAMES}, got {how!r}")
    if how == "given":
        return logs
    given = [f for f, lg in zip(files, logs, strict=True) if lg.meta.start_heading_deg is not None]
    if given:
        raise LogError(
            "key 'start_heading_deg' is given, and --frames fit fits every log's frame: drop"
            " the option (the drives share the frame the key gives) or the key",
            given[0],
        )
    src = (source(d.opts, any(lg.has_effort for lg in logs)) or ("slip",))[0]
    got = frame_turns(logs, base, src)
    if got is None:
        d.frames = {
            "fitted": False,
            "source": src,
            "why_not": "fewer steady straight runs than the balance needs",
        }
        d.say("frames: too few steady straight runs to fit; read as facing the same way")
        return logs
    f, counts = got.f, got.runs
    if f < FIT_F:
        d.frames = {
            "fitted": False,
            "source": src,
            "f": f,
            "why_not": f"the runs fit {f:.1f} times better with each log's frame turned, under"
            f" {FIT_F:g}",
        }
        d.say(f"frames: turned, the runs fit {f:.1f} times better (under {FIT_F:g}); not fitted")
        return logs
    first = next((i for i, n in enumerate(counts) if n), 0)
    d.frames = {
        "fitted": True,
        "source": src,
        "turns_deg": list(got.deg),
        "turn_sd_deg": list(got.sd_deg),
        "f": f,
        "runs": list(counts),
        "first": files[first].name,
        "unread": [files[i].name for i, n in enumerate(counts) if not n],
    }
    each = ", ".join(
        f"{p.name} {t:.0f}° ± {sd:.0f}°"
        for p, t, sd in zip(files, got.deg, got.sd_deg, strict=True)
    )
    d.say(f"frames fitted into {files[first].name}'s: {each} (F {f:.1f})")
    return [
        replace(lg, meta=replace(lg.meta, start_heading_deg=float(t)))
        for lg, t in zip(logs, got.deg, strict=True)
    ]
