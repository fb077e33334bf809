"""Stage 6, evidence: the drives the logs lack.

Owns the candidates the training drives support but the held-out drive cannot confirm (not
excited, seen in the 1 Hz pose only, or leaning towards it at a p its few windows cannot
bring under alpha): for each, the drive that would decide is proposed and simulated
(:func:`rover_env.calibration.evidence.propose`). Why a stage of its own: it names nothing;
it says what to drive next.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rover_env.calibration import evidence, fit
from rover_env.calibration.diagnosis.rotor import rotor_floor, traction_torque
from rover_env.calibration.diagnosis.state import Diagnosis, Options, Scored
from rover_env.calibration.fit import Evaluator
from rover_env.calibration.plans_held import HeldPlans, ask
from rover_env.config import RoverConfig


def seek_evidence(d: Diagnosis) -> None:
    """Sets :attr:`Diagnosis.evidence`."""
    read = {"slope"} if balance_settled(d) else set()
    d.evidence = missing_evidence(
        d.ev, d.ranked, d.chosen, d.noise, d.base, d.opts, d.say, frozenset(read), d.held_plans
    )
    d.untested = untested_limit(d)


def balance_settled(d: Diagnosis) -> bool:
    """Whether the balance (torque or slip) settled the slope, so the windows need no drive
    for it: its runs separate and it named or withdrew one, or its interval ends below
    the tilt the windows could name from (the clean-fit allowance's edge). A separated
    reading can still reach beyond that edge (a clean build's 0-9°, exploratory seed 74761):
    that settles nothing. (The balance asks for its own drive from 1° up,
    ``balance_stage.UNDECIDED``; one proposal of that plan results either way.)"""
    bal = d.balance or {}
    if not bal.get("separated"):
        return False
    if bal.get("named") or bal.get("withdrew"):
        return True
    hi = (bal.get("tilt_interval") or [None, None])[1]
    edge = d.allowance.edge("slope", "deg") if d.allowance is not None else 0.0
    return hi is not None and hi <= edge


def missing_evidence(
    ev: Evaluator,
    ranked: list[Scored],
    chosen: list[Scored],
    noise: dict[str, float],
    base: RoverConfig,
    opts: Options,
    say: Any,
    read: frozenset[str] = frozenset(),
    held: HeldPlans | None = None,
) -> list[dict[str, Any]]:
    """Candidates the training drives support but the held-out drive cannot confirm (none
    of ``read``: effects a direct reading settled); each drive a draw the logs do not hold
    (``held``, :mod:`~rover_env.calibration.plans_held`).

    A candidate qualifies when it is not named, lowers the training BIC, moves some training
    signal by at least one replay floor, and on the held-out drive either moves no signal
    by a floor (not excited), or only the 1 Hz pose (a sparse signal), or improves it by the
    window test's margin at a p the held-out windows cannot bring under alpha (leaning), or
    improves it at all while not significant and its training ΔBIC is "strong"
    (:attr:`Options.strong_bic`).
    For each (at most ``opts.evidence``, best training BIC first) the drive that would
    decide is proposed and simulated (:func:`rover_env.calibration.evidence.propose`).
    """
    named = {c.name for s in chosen for c in s.fit.candidates}
    out: list[dict[str, Any]] = []
    for s in sorted(ranked, key=lambda s: s.d_bic):
        if len(out) >= opts.evidence:
            break
        name = s.fit.name
        if name in named or name in read or s.d_bic >= 0 or s.fit.x.size == 0:
            continue
        if all(v == 0.0 for v in s.fit.x):
            continue
        train = fit.signal_change(ev, s.fit.ext, {}, s.fit.which, noise)
        if max(train.values()) < 1.0:
            continue
        held_change = fit.signal_change(ev, s.fit.ext, {}, "held", noise)
        strong = [k for k, v in held_change.items() if v >= 1.0]
        sparse = bool(strong) and all(k.startswith("pose_") for k in strong)
        # The held-out drive leans towards it (better by the window test's margin) but its
        # few windows cannot confirm it at alpha: more of the drive that excites it decides.
        # So does strong training evidence (ΔBIC at or below Options.strong_bic) that the
        # held-out drive does not contradict (better at all) but did not confirm.
        strong_bic = s.d_bic <= opts.strong_bic and s.gain > 0.0 and not s.significant
        leaning = (s.gain >= opts.min_gain and s.p >= opts.alpha) or strong_bic
        if strong and not sparse and not leaning:
            continue  # the held-out drive could judge it, and did
        if sparse:
            why = "only the 1 Hz pose carries it on the held-out drive"
        elif strong and s.gain >= opts.min_gain:
            why = (
                f"the held-out drive leans towards it ({100 * s.gain:.0f} % better) but cannot"
                f" confirm it (p {s.p:.2g} against {opts.alpha:g})"
            )
        elif strong:
            why = (
                f"the training drives support it strongly (dBIC {s.d_bic:+.1f}) and the"
                f" held-out drive is {100 * s.gain:.1f} % better, short of confirming it"
                f" (p {s.p:.2g})"
            )
        else:
            why = "the held-out drive does not excite it"
        drew = ask({"plan": evidence.evidence_plan(name)[0]}, held or {})  # a draw not held
        p = evidence.propose(
            base, name, s.fit.ext, noise, held_change, seed=drew["seed"], ground=ev.settings.terrain
        )
        p.update(drew, reason=why)
        out.append(p)
        say(
            f"evidence missing for {name} ({why}): propose a drive of plan {p['plan']!r}; in"
            f" simulation its replay moves {p['best_signal']} by {p['best_per_window']:.1f}x its"
            f" floor per window, {p['best_floor_units']:.1f}x over the drive (held-out drive:"
            f" {p['held_out_best_signal']} {p['held_out_floor_units']:.1f}x per window)"
        )
    return out


def untested_limit(d: Diagnosis) -> list[dict[str, Any]]:
    """The drive that asks the motors for their torque, when the logs never did.

    Proposed (at most one) when no torque limit is named or already given an evidence
    drive, and the torque limit's noise threshold on these drives (the smallest cut that
    moves a signal by one replay floor) exceeds :attr:`Options.limit_resolution`: the logs
    then reach the limit only for cuts beyond it. Simulated like an evidence drive, with a
    cut of that resolution. Kept apart from the evidence: it is about what these drives did
    not test, not about a candidate they support. Where the limit is above the tires'
    traction, the reason also says below which cut (``rotor_floor``,
    :func:`.rotor.rotor_floor`) a cut acts, wherever the limit binds, as the rotor inertia's
    tolerance (:attr:`Options.rotor_range`) does, and what reads it: the rotor's datasheet
    inertia.
    """
    res = d.opts.limit_resolution
    named = {c.name for s in d.chosen for c in s.fit.candidates}
    asked = {e["effect"] for e in d.evidence}
    tl = next((s for s in d.ranked if s.fit.name == "torque_limit"), None)
    if res <= 0 or tl is None or "torque_limit" in named | asked:
        return []
    if d.effort is not None and d.effort.get("level") is not None:
        return []  # the reported torque held at the limit: read (:mod:`.effort_stage`)
    thr = (tl.threshold or {}).get("-")
    if thr is not None and thr <= res:
        return []
    (c,) = tl.fit.candidates
    ext = c.to_ext(np.array([-res]))
    drew = ask({"plan": evidence.evidence_plan(c.name)[0]}, d.held_plans)  # a draw not held
    p = evidence.propose(
        d.base, c.name, ext, d.noise, {}, seed=drew["seed"], ground=d.ev.settings.terrain
    )
    p.update(drew)
    seen = (
        "no cut moved a signal by its floor"
        if thr is None
        else f"only cuts beyond {100 * thr:.0f} %"
    )
    det = (tl.detectable or {}).get("-")
    beside = (
        ""
        if det is None
        else f" (against what the model leaves on these logs, one shows only beyond {100 * det:.0f} %)"
    )
    p["reason"] = (
        f"these drives reach the motors' limit for {seen}{beside}; a cut of {100 * res:.0f} %"
        " needs a drive that asks for it"
    )
    floor = rotor_floor(d.base, d.opts.rotor_range)
    p["rotor_floor"] = floor
    if -floor > res:
        p["reason"] += (
            f"; but the tires pass at most {traction_torque(d.base):.2f} N m a wheel against"
            f" a limit of {d.base.motor.torque_limit:g} N m, so on any drive the limit binds"
            f" only while a wheel spins up or down, where a cut under {100 * -floor:.0f} % acts"
            f" as a rotor inertia within its tolerance (x{d.opts.rotor_range:g}) does: for"
            " smaller cuts give motor.armature from the drive's datasheet and a smaller"
            " --rotor-range"
        )
    if d.effort is None:
        p["reason"] += (
            "; or log the motors' torque (effort_* columns, a bag's JointState.effort): where"
            " it holds at the limit, the limit is read from it directly"
        )
    d.say(
        f"torque limit untested ({p['reason']}): propose a drive of plan {p['plan']!r}; in"
        f" simulation a cut of {100 * res:.0f} % moves {p['best_signal']} by"
        f" {p['best_floor_units']:.1f}x its floor over the drive"
    )
    return [p]
