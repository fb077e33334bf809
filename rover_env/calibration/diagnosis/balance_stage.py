"""Stage 5d, balance: the ground's tilt read from the motors' reported torque, or from the
wheels' slip where the logs carry no torque.

Where the logs carry ``effort_*`` columns,
:func:`rover_env.calibration.balance.read_balance` fits the force balance along the track
over the steady straight runs: a tilt vector and a resistance. Each run's heading is the
pose's, or where a log holds one fix or none (SPEC §6's pose at the end only) the free
wheels' turn fitted to that fix (:mod:`rover_env.calibration.heading`). Logs without
the torque (SPEC §6's) get the slip balance: the same fit with each run's traction read from
the driven wheels' slip against the free wheels' (``source`` "slip", its own allowance
:data:`rover_env.calibration.balance.CLEAN_SLIP_TILT`). A tilt whose interval, less
what clean builds read (:data:`rover_env.calibration.balance.CLEAN_TILT`; for the slip
:data:`rover_env.calibration.balance.CLEAN_SLIP_TILT`), stays above
level names ``slope`` from the balance, in place of a slope the windows named alone; a
balance that reads the ground level under a slope the windows named alone withdraws it;
beside a slope named in a pair the reading is reported. Where the runs leave the tilt and
the resistance one unknown it names nothing and asks for the :data:`PLAN` drive; where it
names a slope whose size its interval leaves loose (:data:`SPREAD`) it asks for it too. Why a
stage of its own: the windows read a slope through this model's joints and springs, and
clean builds of another implementation fit tilts up to 2.4° there (the clean-fit
allowance), which a slope must clear to be named; the summed wheel torque does not depend
on where the mass sits.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from rover_env.calibration.balance import (
    CLEAN_SLIP_TILT,
    CLEAN_TILT,
    SCALE,
    SLIP_SCALE,
    BalanceReading,
    Z,
    read_balance,
)
from rover_env.calibration.candidates import merge
from rover_env.calibration.diagnosis.judge import scored_beside
from rover_env.calibration.diagnosis.state import Diagnosis, Options, Scored
from rover_env.calibration.evidence import PLAN_DURATION, PLAN_SEED
from rover_env.calibration.fit import Fit, to_ext
from rover_env.calibration.plans_held import ask

NAME = "slope"
SOIL = "loose_soil"
"""Beside it the slip balance only reports: its reading assumes hard ground (stop 121, after
block 53600's soil case 53607 read 1.14° [0.82, 1.47] on level soil, forwards slipping 21.4 %
and backwards 19.7 %; block 53700's one soil, 53707, was reported so, 0.24° [0, 0.84])."""
PLAN = "reversals"
"""The drive asked for where the runs leave the tilt and the resistance one unknown, or the
tilt's interval wide (:data:`UNDECIDED`; named, :data:`SPREAD`): long runs forwards and backwards on one line, a
long pivot, and the same on the crossing line."""
TURNED_F = 100.0
"""The F ratio (:attr:`~rover_env.calibration.balance.BalanceReading.turned_f`) from which a
reading on logs without start headings says their frames may disagree (``frames`` in its
record, :data:`FRAMES`); it changes nothing the reading does. Exploratory, read after block
53900's look on its 32 spent cases: with each log's start heading given (the frames right)
F reached 46 (two slopes over 20: runs in two headings whose misfit a turn absorbs, not
frames); the same logs stripped of their start headings read over 100 on 9 of 16 slopes
(0.2-44 on the rest) and under 3 on every clean build and other effect. Not scored on
fresh cases, so it only reports."""
FRAMES = (
    "Its runs fit {f:.0f} times better with each log's frame turned on its own (turns"
    " {turns}): if the drives did not start facing the same way, give each log's start"
    " heading in a frame they share (`start_heading_deg` in its YAML) and diagnose again, or"
    " where they share none, diagnose with `--frames fit`."
)
UNDECIDED = 1.0
"""Degrees: a separated reading that names nothing while its interval for the truth reaches
this high (at the default allowance; above it by as much as ``--slip-allowance`` or
``--balance-allowance`` is set above its default, :func:`wide_at`) asks for the
:data:`PLAN` drive too. Runs all in about one heading read the slope
along it and leave the part across it loose (block 53600: three slopes of 0.97-1.16° missed
at [0, 3.2-5.6]; set after that look, then scored on block 53700: slopes of 0.6° or more 8
of 8, 12 of 32 first readings wide). A slope of 1° costs the rover 1.7 % of its weight, a
rolling resistance's size."""
SPREAD = 3.0
"""A named reading whose tilt interval's ends lie more than this factor apart names the slope
and asks for the :data:`PLAN` drive too (``why_drive`` in its record): its size is not
known, and the value ``rover.yaml`` gets is the valley's arbitrary best. Where the drives
barely cross (frames that share nothing, or runs in about one heading) the valley is flat:
block 54100 read 2.48° as 8.00° [2.29, 19.86] and 1.95° as 3.18° [0.91, 10.03]. Of the 55
named readings of blocks 53800-54100, the 44 whose ends lay at most 2.74 x apart read values
within 1.25 x of the truth (but for 54008's, a bug since fixed); of the 11 from 3.08 x up, 7
were 1.33-3.23 x off. Set after those looks; scored on fresh cases (block 54200)."""


def name_by_balance(d: Diagnosis) -> None:
    """Sets :attr:`Diagnosis.balance`; names, replaces or withdraws a slope as the reading
    says (see the module docstring)."""
    d.balance = None
    cand = next((c for c in d.cands if c.name == NAME), None)
    logs = [p.log for p in d.prepared]
    how = source(d.opts, any(log.has_effort for log in logs))
    if cand is None or how is None:
        return
    src, allow, tolerance = how
    t0 = time.perf_counter()
    fr = d.frames  # fitted frames (:mod:`.frames`): their turns' uncertainty joins the tilt's
    sd = tuple(fr["turn_sd_deg"]) if fr and fr.get("fitted") else ()
    reading, runs = read_balance(logs, d.base, tolerance, src, sd, free=fr is not None)
    reading = in_frames(reading, fr)
    windows = [s for s in d.chosen if NAME in [c.name for c in s.fit.candidates]]
    alone = [s for s in windows if len(s.fit.candidates) == 1]
    wlo = alone[0].fit.physical()[NAME]["deg"][1] if alone else None
    soil = any(c.name == SOIL for s in d.chosen for c in s.fit.candidates)
    act, rec = record(reading, len(runs), allow, wlo, len(windows) > len(alone), src, soil)
    d.balance = ask(rec, d.held_plans) if "plan" in rec else rec
    if reading is None or act not in ("withdraw", "name"):
        return
    d.chosen = [s for s in d.chosen if s not in alone]
    rec["withdrew" if act == "withdraw" else "replaced"] = [fmt_slope(s) for s in alone]
    if act == "withdraw":
        hi = reading.tilt_interval()[1]
        what = "torque" if src == "effort" else "slip"
        d.say(f"{NAME}: withdrawn, the wheels' {what} reads the ground within {hi:.2f}°")
        return
    fit = balance_fit(cand, reading, allow, time.perf_counter() - t0)
    named, _ = scored_beside(d, fit, merge(*(s.fit.ext for s in d.chosen)), k=2)
    named.significant = True
    named.test = test_text(reading, allow)
    rec.update(named=True, held_gain=named.gain)
    d.chosen.append(named)
    d.say(f"{NAME}: named by {named.test}")


def in_frames(
    reading: BalanceReading | None, frames: dict[str, Any] | None
) -> BalanceReading | None:
    """``reading`` with how its frames were placed (:attr:`~BalanceReading.frames_placed`;
    ``frames``: :attr:`Diagnosis.frames`, None where they were given): fitted or left
    unread, its heading is not known."""
    if reading is None or not frames:
        return reading
    return replace(reading, frames_placed="fitted" if frames.get("fitted") else "unread")


def source(opts: Options, effort: bool) -> tuple[str, float, float] | None:
    """Which balance a diagnosis reads (the source, its allowance in degrees, its scale
    tolerance): the torque's where the logs report it and both the torque and its balance
    are read, else the slip's; None where that is off too. Each switch turns off its own
    reading: with the torque balance off the slip still reads the tilt."""
    if effort and opts.effort_tolerance is not None and opts.balance_allowance is not None:
        return "effort", opts.balance_allowance, SCALE
    return None if opts.slip_allowance is None else ("slip", opts.slip_allowance, SLIP_SCALE)


def record(
    reading: BalanceReading | None,
    runs: int,
    allow: float,
    windows_low: float | None,
    inside: bool,
    src: str = "effort",
    soil: bool = False,
) -> tuple[str, dict[str, Any]]:
    """What a reading does (:func:`action`; "none" without a reading; "soil" for the slip's
    beside a named loose soil: reported only; "wide" for a "level" whose interval reaches
    :data:`UNDECIDED`: it asks for the drive too) and its record for ``result.json``: the
    reading, the interval for the truth with the allowance, what it did (``action``), why
    nothing was named, and the drive it asks for where its runs do not separate or its
    interval is wide (named or not: ``why_drive`` where named, :data:`SPREAD`)."""
    rec: dict[str, Any] = {
        "runs": runs,
        "read": reading is not None,
        "named": False,
        "source": src,
        "action": "none",
    }
    if reading is None:
        rec["why_not"] = (
            "fewer steady straight runs with the torque and the heading than it needs"
            if src == "effort"
            else "fewer steady straight runs with the heading than it needs"
        )
        return "none", rec
    lo, hi = reading.tilt_interval()
    rec.update(reading.as_json(), allowance=allow, truth_interval=[max(0.0, lo - allow), hi])
    act = action((lo, hi), allow, windows_low, inside, reading.separated)
    if reading.turned_f >= TURNED_F:
        turns = ", ".join(f"{t:.0f}°" for t in reading.turned_deg)
        rec["frames"] = FRAMES.format(f=reading.turned_f, turns=turns)
    if src == "slip" and soil and act != "unseparated":
        act = "soil"
    if act == "level" and hi > wide_at(allow, src):
        act = "wide"
    rec["action"] = act
    if act in WHY_NOT:
        rec["why_not"] = WHY_NOT[act].format(allow=allow, wide=wide_at(allow, src))
    if act == "name" and hi > SPREAD * lo:  # named: lo clears the allowance, so lo > 0
        rec["why_drive"] = WHY_DRIVE.format(lo=lo, hi=hi, spread=SPREAD)
    if act in ("unseparated", "wide", "open") or "why_drive" in rec:  # for drive-plan, bench
        rec.update(plan=PLAN, seed=PLAN_SEED, duration=PLAN_DURATION)
    return act, rec


def wide_at(allow: float, src: str) -> float:
    """Degrees a level reading's interval reaches to ask for the drive: :data:`UNDECIDED`
    beyond what the allowance adds over its default (``CLEAN_TILT``, or ``CLEAN_SLIP_TILT``
    for the slip). Why: a larger allowance widens the interval for the truth by itself, and
    no drive narrows what clean builds read; a narrow reading under a raised allowance would
    otherwise ask for a drive that cannot decide it."""
    return UNDECIDED + allow - (CLEAN_SLIP_TILT if src == "slip" else CLEAN_TILT)


WHY_NOT = {
    "unseparated": "the runs do not tell a tilt from a resistance (all one way, or in about one"
    " heading): drive the same line forwards and backwards, pivot long, and drive the"
    " crossing line",
    "level": "the tilt's interval, less the {allow:g}° clean builds read, reaches level",
    "wide": "the tilt's interval, less the {allow:g}° clean builds read, reaches level, and"
    " reaches {wide:g}° too (the runs read the slope across their headings poorly): drive"
    " the same line forwards and backwards, pivot long, and drive the crossing line",
    "withdraw": "the tilt's interval, less the {allow:g}° clean builds read, reaches level",
    "open": "in frames that share nothing the runs bound the tilt below and not above (each"
    " log's runs along about one line read only the tilt's part along it): drive the same"
    " line forwards and backwards, pivot long, and drive the crossing line",
    "inside": "a slope is named with another effect; the reading is reported",
    "soil": "loose soil is named, and the slip balance assumes hard ground (a tire's slip"
    " stiffness; on soil the free wheels bulldoze differently forwards and backwards): the"
    " reading is reported",
}
"""Why a reading names nothing, by :func:`action`."""
WHY_DRIVE = (
    "its size is not known: the interval [{lo:.2f}°, {hi:.2f}°] spans more than {spread:g} x"
    " (the runs barely cross): drive the same line forwards and backwards, pivot long, and"
    " drive the crossing line"
)
"""Why a named reading asks for the drive (:data:`SPREAD`)."""


def action(
    tilt: tuple[float, float],
    allow: float,
    windows_low: float | None,
    inside: bool,
    separated: bool = True,
) -> str:
    """What a reading's tilt interval (low, high; degrees) does beside the windows' slope
    (``windows_low``: the low end of its interval for the truth where they named it alone;
    ``inside``: named with another effect): "name" (the interval, less ``allow``, stays
    above level: the balance's slope replaces theirs), "inside" (a slope named in a pair:
    the reading is reported, either way), "withdraw" (it reaches level, and theirs lies
    above its high end), "level", "unseparated" (the runs do not tell a tilt from a
    resistance: nothing either way) or "open" (above level, the interval open above: in
    frames that share nothing the runs bound the size below only; nothing either way)."""
    lo, hi = tilt
    if not separated:
        return "unseparated"
    if inside:
        return "inside"
    if lo - allow > 0.0:
        return "name" if math.isfinite(hi) else "open"
    if windows_low is not None and windows_low > hi:
        return "withdraw"
    return "level"


def balance_fit(cand: Any, r: BalanceReading, allow: float, seconds: float) -> Fit:
    """The slope as the balance reads it: the tilt vector with its standard errors (the
    scale's tolerance folded in), and the clean builds' tilt as its allowance. In frames
    that share nothing the size's interval is the profile's
    (:meth:`BalanceReading.tilt_interval`): the errors widened until the low end reaches it,
    the high end's reach set to it."""
    x = np.array([r.tilt_x, r.tilt_y])
    se = np.array(r.tilt_se())
    reach = 0.0
    if r.size_bounds is not None and r.tilt > 0.0:
        lo, hi = r.tilt_interval()
        g = x / r.tilt
        along = math.sqrt(float(np.sum((g * se) ** 2)))
        need = (r.tilt - lo) / Z
        se = se * (need / along) if along > 0.0 and need > along else se
        reach = hi - r.tilt
    fit = Fit(
        candidates=[cand],
        x=x,
        ci_lo=x - Z * se,
        ci_hi=x + Z * se,
        se=se,
        cost=float("nan"),
        nfev=1,
        ext=to_ext([cand], x),
        seconds=seconds,
        which="train",
        method="balance",
    )
    fit.allowance = {NAME: (allow, 0.0)}  # below, above: clean builds read up to allow high
    if reach > 0.0:
        fit.reach = {NAME: reach}
    fit.heading_known = r.frames_placed == "given"
    return fit


def test_text(r: BalanceReading, allow: float) -> str:
    """The naming's reason, in the report's words."""
    lo, hi = r.tilt_interval()
    hlo, hhi = r.heading_interval()
    what = (
        "the wheels' summed torque"
        if r.source == "effort"
        else "the driven wheels' slip against the free wheels', forwards against backwards,"
    )
    toward = (
        f"[{hlo:.0f}°, {hhi:.0f}°]"
        if hhi - hlo < 360.0
        else "(any way: the frames were not fitted)"
        if r.frames_placed == "unread"
        else "(any way: in fitted frames the heading is not known)"
        if r.frames_placed == "fitted"
        else "(its interval the whole circle)"
    )
    return (
        f"balance: {what} over {r.runs} steady straight runs reads the ground"
        f" rising {r.tilt:.2f}° [{lo:.2f}, {hi:.2f}] toward {r.heading:.0f}° {toward}, beyond"
        f" the {allow:g}° clean builds read"
    )


def fmt_slope(s: Scored) -> dict[str, Any]:
    """A withdrawn or replaced slope, for the record."""
    v, lo, hi = s.fit.physical()[NAME]["deg"]
    return {"effects": [c.name for c in s.fit.candidates], "deg": v, "interval": [lo, hi]}
