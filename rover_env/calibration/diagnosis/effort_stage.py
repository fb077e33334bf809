"""Stage 5c, effort: the torque limit read from the torque the motors report.

Where the logs carry ``effort_*`` columns (a driver's reported torque, e.g. ROS 2
``JointState.effort``), :func:`rover_env.calibration.effort.read_limit` reads the limit from
where the torque held while the motors were asked for more. A plateau beyond the reported
torque's scale tolerance (:attr:`.state.Options.effort_tolerance`) names ``torque_limit`` with
the plateau's change and an interval from its spread and that tolerance; a plateau within it
withdraws a torque limit the windows named alone (the motors were seen giving the configured
torque). Without a plateau the largest torque given is reported as the deepest cut ruled out,
and nothing changes. Why a stage of its own: on hard ground the wheel angles show a cut under
about 60 % only while a wheel spins up, where it acts as the rotor inertia does (block 52600:
torque cuts 0/4 named); the torque itself is read there directly.
"""

from __future__ import annotations

import time
from typing import Any

from rover_env.calibration.candidates import merge
from rover_env.calibration.diagnosis.judge import scored_beside
from rover_env.calibration.diagnosis.state import Diagnosis, Scored
from rover_env.calibration.effort import EffortReading, read_limit
from rover_env.calibration.fit import read_fit
from rover_env.calibration.replay import loop_commands

NAME = "torque_limit"


def name_by_effort(d: Diagnosis) -> None:
    """Sets :attr:`Diagnosis.effort`; names, replaces or withdraws a torque limit as the
    reading says (see the module docstring)."""
    tol = d.opts.effort_tolerance
    cand = next((c for c in d.cands if c.name == NAME), None)
    d.effort = None
    if tol is None or cand is None:
        return
    # The targets the motors' loops see under what is named (a command lag or delay).
    cfg = d.ev.config(merge(*(s.fit.ext for s in d.chosen)))
    logs = [p.log for p in d.prepared]
    targets = [loop_commands(log, cfg) for log in logs]
    reading = read_limit(logs, d.base.motor.torque_limit, tol, targets)
    if reading is None:
        return
    rec: dict[str, Any] = {**reading.as_json(), "named": False}
    d.effort = rec
    cut = reading.cut()
    alone = [s for s in d.chosen if [c.name for c in s.fit.candidates] == [NAME]]
    inside = any(NAME in [c.name for c in s.fit.candidates] for s in d.chosen) and not alone
    windows = (float(alone[0].fit.ci_lo[0]), float(alone[0].fit.ci_hi[0])) if alone else None
    act = action(cut, windows, inside)
    if act in WHY_NOT:
        rec["why_not"] = WHY_NOT[act].format(tol=100 * reading.tolerance)
    if act in ("withdraw", "replace"):
        d.chosen = [s for s in d.chosen if s not in alone]
        rec["withdrew" if act == "withdraw" else "replaced"] = [fmt_fit(s) for s in alone]
    if act == "withdraw":
        d.say(f"{NAME}: withdrawn, the motors held at {reading.level:.3f} N m")
    if act not in ("name", "replace") or cut is None:
        return
    x, lo, hi = cut
    t0 = time.perf_counter()
    lo, hi = max(lo, cand.lo[0]), min(hi, cand.hi[0])
    x = min(max(x, cand.lo[0]), cand.hi[0])
    fit = read_fit(cand, (x, lo, hi), time.perf_counter() - t0, "effort")
    ref_ext = merge(*(s.fit.ext for s in d.chosen))
    s, _ = scored_beside(d, fit, ref_ext)
    s.significant = True
    s.test = test_text(reading)
    rec.update(named=True, fraction=[x, lo, hi], held_gain=s.gain)
    d.chosen.append(s)
    d.say(f"{NAME}: named by {s.test}: {x:+.4f} [{lo:+.4f}, {hi:+.4f}]")


WHY_NOT = {
    "no ceiling": "the reported torque never held at a ceiling while asked for more",
    "within": "the plateau is within the reported torque's {tol:.0f} %",
    "withdraw": "the plateau is within the reported torque's {tol:.0f} %",
    "inside": "a torque limit is named with another effect; the reading is reported",
    "agree": "the windows named a torque limit the reading agrees with",
}
"""Why a reading names nothing, by :func:`action`."""


def action(
    cut: tuple[float, float, float] | None, windows: tuple[float, float] | None, inside: bool
) -> str:
    """What a reading's ``cut`` (value, low, high) does beside the windows' torque limit
    (``windows``: its interval where they named it alone; ``inside``: named with another
    effect): "no ceiling" or "within" (nothing), "withdraw" (a ceiling within the tolerance
    of the configured limit: the motors gave it), "inside" (reported only), "agree" (the
    windows' interval meets the reading's: theirs stands), "replace" or "name"."""
    if cut is None:
        return "no ceiling"
    _, lo, hi = cut
    if lo <= 0.0 <= hi:
        return "withdraw" if windows is not None else "within"
    if inside:
        return "inside"
    if windows is None:
        return "name"
    return "agree" if windows[0] <= hi and lo <= windows[1] else "replace"


def test_text(r: EffortReading) -> str:
    """The naming's reason, in the report's words."""
    return (
        f"effort: the motors held at {r.level:.3f} N m while asked for more ({r.events} events"
        f" at demands {r.spread:.1f} x apart) against the configured {r.configured:.3f} N m, beyond the"
        f" reported torque's {100 * r.tolerance:.0f} % scale tolerance"
    )


def fmt_fit(s: Scored) -> dict[str, Any]:
    """A withdrawn or replaced fit, for the record."""
    return {
        "effects": [c.name for c in s.fit.candidates],
        "value": float(s.fit.x[0]),
        "interval": [float(s.fit.ci_lo[0]), float(s.fit.ci_hi[0])],
    }
