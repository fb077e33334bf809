"""Stage 6, evidence: the drives the logs lack.

Owns the candidates the training drives support but the held-out drive cannot confirm (not
excited, seen in the 1 Hz pose only, or leaning towards it at a p its few windows cannot
bring under alpha): for each, the drive that would decide is proposed and simulated
(:func:`rover_env.calibration.evidence.propose`). Why a stage of its own: it names nothing;
it says what to drive next.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from rover_env.calibration import evidence, fit
from rover_env.calibration.candidates import Extensions, merge
from rover_env.calibration.diagnosis.judge import (
    fit_budget,
    fmt_phys,
    passes_window_test,
    scored_beside,
)
from rover_env.calibration.diagnosis.rotor import rotor_floor, traction_torque
from rover_env.calibration.diagnosis.state import Diagnosis, Options, Scored
from rover_env.calibration.fit import Evaluator
from rover_env.calibration.form_allowance import FormAllowance
from rover_env.calibration.plans_held import HeldPlans, ask
from rover_env.config import RoverConfig
from rover_env.effects import CATALOGUE

Beside = Callable[[Scored], Scored]
"""A candidate's single fit, refitted and judged beside the named effects."""


def seek_evidence(d: Diagnosis) -> None:
    """Sets :attr:`Diagnosis.evidence`."""
    read = {"slope"} if balance_settled(d) else set()
    beside = (lambda s: beside_named(d, s)) if d.chosen else None
    ctx = Asking(d.held_plans, held_out_logs(d), beside, d.allowance, max_draws=d.opts.max_draws)
    d.evidence = missing_evidence(
        d.ev, d.ranked, d.chosen, d.noise, d.base, d.opts, d.say, frozenset(read), ctx
    )
    d.evidence_judged = ctx.judged
    d.untested = untested_limit(d)


def held_out_logs(d: Diagnosis) -> tuple[str, ...]:
    """The held-out drives' file names, where whole logs are held out (none with one log
    or ``--interleave``)."""
    if len(d.files) < 2 or d.opts.interleave:
        return ()
    return tuple(sorted({d.files[w.log_index].name for w in d.held_w}))


def named_ext(chosen: list[Scored]) -> Extensions:
    """The named effects' extensions, as the configuration gets them."""
    return merge(*(s.fit.ext for s in chosen))


def beside_named(d: Diagnosis, s: Scored) -> Scored:
    """``s``'s candidates refitted with the named effects held as named (from its single
    fit), judged against the named model: what the candidate adds to them. Why (stop 129):
    fitted alone, a candidate can also take what a named effect explains, and its lead
    then asks for a drive that decides nothing. (Block 54400's `accel` asked beside named
    slopes was not that: on spent case 54412 the cut's training dBIC went from -19.4 alone
    to -17.9 beside the slope; :func:`within_allowance` is what stops it.)"""
    ref = named_ext(d.chosen)
    cands = s.fit.candidates
    f = fit.fit(
        d.ev, cands, s.fit.which, x_start=s.fit.x, max_nfev=fit_budget(cands, d.opts),
        probe=False, hold=ref,
    )  # fmt: skip
    b, _ = scored_beside(d, f, ref, k=s.fit.k)
    b.significant = passes_window_test(b, d.opts)
    return b


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


@dataclass
class Asking:
    """What decides whether a drive is worth asking for (stop 129)."""

    held: HeldPlans = field(default_factory=dict)
    """The plans' draws the logs hold (:mod:`~rover_env.calibration.plans_held`)."""
    held_out: tuple[str, ...] = ()
    """The held-out drives' file names, where whole logs are held out."""
    beside: Beside | None = None
    """With effects named: a candidate refitted and judged beside them (:func:`beside_named`)."""
    allowance: FormAllowance | None = None
    """The clean-fit allowance (:attr:`Diagnosis.allowance`)."""
    judged: list[dict[str, Any]] = field(default_factory=list)
    """Candidates asked for nothing, and why (``result.json``'s ``evidence_judged``)."""
    max_draws: int = 0
    """:attr:`Options.max_draws` (0: no cap)."""


READ_APART = frozenset({"slope", "rolling_radius"})
"""Effects a reading of their own names (the balance, dead reckoning), not the windows:
the windows' allowance does not bound what their drives can show."""


def within_allowance(s: Scored, allowance: FormAllowance | None) -> float | None:
    """The clean-fit allowance's edge (:meth:`FormAllowance.edge`) where the whole of
    ``s``'s 95 % interval lies within it, else None: confirmed by any drive, the fit would
    still be withdrawn (what a clean build of another implementation fits reaches as far).
    One continuous parameter, not :data:`READ_APART`."""
    if allowance is None or len(s.fit.candidates) != 1:
        return None
    (c,) = s.fit.candidates
    if c.discrete or c.name in READ_APART or len(c.labels) != 1:
        return None
    v, lo, hi = next(iter(s.fit.physical(allow=False)[c.name].values()))
    off = CATALOGUE[c.name].params[0].off
    side = "+" if v > off else "-"
    edge = allowance.edge(c.name, side)
    far = hi - off if side == "+" else off - lo
    return edge if edge > 0.0 and far <= edge else None


def not_worth_asking(
    s: Scored, plan: str, lean: bool, sparse: bool, ctx: Asking, say: Any
) -> dict[str, Any] | None:
    """Why no drive is asked for ``s`` (a record for :attr:`Asking.judged`), or None.

    Its interval lies within the clean-fit allowance (:func:`within_allowance`): no drive
    can make it nameable. Or the held-out drive is a draw of its deciding ``plan`` and does
    not lean towards it (better by the window test's margin): that drive judged it, and
    another draw of it would not. Or the logs hold :attr:`Asking.max_draws` draws of that
    plan already: a user's patience, not a test. Block 54400 asked ``accel`` for torque
    cuts of about 50 % (what clean builds fit) 21 times, 5 of them after a draw of it was
    driven."""
    name = s.fit.name
    edge = within_allowance(s, ctx.allowance)
    if edge is not None:
        say(
            f"evidence: {name} {fmt_phys(s.fit)} lies within the clean-fit allowance"
            f" ({edge:.3g}): no drive could make it nameable, none asked"
        )
        return {"effect": name, "plan": plan, "why": "allowance", "edge": edge,
                "fit": fmt_phys(s.fit)}  # fmt: skip
    drawn = ctx.held.get(plan, [])
    if 0 < ctx.max_draws <= len(drawn):
        say(
            f"evidence: the logs hold {len(drawn)} draws of {name}'s deciding drive {plan!r}"
            f" and leave it unconfirmed ({100 * s.gain:.1f} % better at p {s.p:.2g} held"
            f" out): no other draw asked (at most {ctx.max_draws})"
        )
        return {"effect": name, "plan": plan, "why": "draws", "draws": len(drawn),
                "gain": s.gain, "p": s.p}  # fmt: skip
    mine = [h for h in drawn if h["log"] in ctx.held_out]
    if sparse or lean or not mine:
        return None
    say(
        f"evidence: {name}'s deciding drive {plan!r} ({mine[0]['log']}, held out) is"
        f" {100 * s.gain:.1f} % better at p {s.p:.2g}, short of the lean another draw would"
        " need: not asked again"
    )
    return {"effect": name, "plan": plan, "why": "held_out", **mine[0], "gain": s.gain, "p": s.p}


def missing_evidence(
    ev: Evaluator,
    ranked: list[Scored],
    chosen: list[Scored],
    noise: dict[str, float],
    base: RoverConfig,
    opts: Options,
    say: Any,
    read: frozenset[str] = frozenset(),
    ctx: Asking | None = None,
) -> list[dict[str, Any]]:
    """Candidates the training drives support but the held-out drive cannot confirm (none
    of ``read``: effects a direct reading settled); each drive a draw the logs do not hold
    (:attr:`Asking.held`). With effects named, each candidate is judged by what it adds
    beside them (:attr:`Asking.beside`), not by its fit alone; one no drive could decide
    is recorded in :attr:`Asking.judged` instead (:func:`not_worth_asking`).

    A candidate qualifies when it is not named, lowers the training BIC, moves some training
    signal by at least one replay floor, and on the held-out drive either moves no signal
    by a floor (not excited), or only the 1 Hz pose (a sparse signal), or improves it by the
    window test's margin at a p the held-out windows cannot bring under alpha (leaning), or
    improves it at all while not significant and its training ΔBIC is "strong"
    (:attr:`Options.strong_bic`).
    For each (at most ``opts.evidence``, best training BIC first) the drive that would
    decide is proposed and simulated (:func:`rover_env.calibration.evidence.propose`).
    """
    ctx = ctx or Asking()
    named = {c.name for s in chosen for c in s.fit.candidates}
    ref = named_ext(chosen)
    out: list[dict[str, Any]] = []
    for s in sorted(ranked, key=lambda s: s.d_bic):
        if len(out) >= opts.evidence:
            break
        name = s.fit.name
        if name in named or name in read or s.d_bic >= 0 or s.fit.x.size == 0:
            continue
        if ctx.beside is not None:
            s = ctx.beside(s)
            if s.d_bic >= 0:
                say(f"evidence: {name} adds nothing beside {', '.join(sorted(named))}"
                    f" (dBIC {s.d_bic:+.1f})")  # fmt: skip
                continue
        if all(v == 0.0 for v in s.fit.x):
            continue
        train = fit.signal_change(ev, s.fit.ext, ref, s.fit.which, noise)
        if max(train.values()) < 1.0:
            continue
        held_change = fit.signal_change(ev, s.fit.ext, ref, "held", noise)
        strong = [k for k, v in held_change.items() if v >= 1.0]
        sparse = bool(strong) and all(k.startswith("pose_") for k in strong)
        # The held-out drive leans towards it (better by the window test's margin) but its
        # few windows cannot confirm it at alpha: more of the drive that excites it decides.
        # So does strong training evidence (ΔBIC at or below Options.strong_bic) that the
        # held-out drive does not contradict (better at all) but did not confirm.
        strong_bic = s.d_bic <= opts.strong_bic and s.gain > 0.0 and not s.significant
        lean = s.gain >= opts.min_gain and s.p >= opts.alpha
        if strong and not sparse and not (lean or strong_bic):
            continue  # the held-out drive could judge it, and did
        plan = evidence.evidence_plan(name)[0]
        rec = not_worth_asking(s, plan, lean, sparse, ctx, say)
        if rec is not None:
            ctx.judged.append(rec)
            continue
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
        drew = ask({"plan": plan}, ctx.held)  # a draw not held
        own = {k: v for k, v in s.fit.ext.items() if k not in ref}  # the named are in the base
        base_named = replace(base, extensions=merge(base.extensions, ref))
        p = evidence.propose(
            base_named, name, own, noise, held_change, seed=drew["seed"], ground=ev.settings.terrain
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
    cut of that resolution. Not when the logs hold a draw of that plan (stop 129): the
    threshold is read on the training drives, and a draw held is the held-out drive or
    among them, so the limit was asked for; another draw tests no more (block 54400 asked
    it again in 9 of 24 cases). Nor, without the motors' torque logged, when the drives
    reach every cut beyond the clean-fit allowance's edge: a cut under it is not named from
    the wheel angles whatever the drive (block 54400: 17 of 24 first diagnoses asked, each
    reaching cuts beyond 6-52 % against an edge of 62 %). Kept apart from the evidence: it
    is about what these drives did not test, not about a candidate they support. Where the limit is above the tires'
    traction, the reason also says below which cut (``rotor_floor``,
    :func:`.rotor.rotor_floor`) a cut acts, wherever the limit binds, as the rotor inertia's
    tolerance (:attr:`Options.rotor_range`) does, and what reads it: the rotor's datasheet
    inertia.
    """
    res = d.opts.limit_resolution
    named = {c.name for s in d.chosen for c in s.fit.candidates}
    asked = {e["effect"] for e in [*d.evidence, *d.evidence_judged]}  # or judged not worth it
    tl = next((s for s in d.ranked if s.fit.name == "torque_limit"), None)
    if res <= 0 or tl is None or "torque_limit" in named | asked:
        return []
    if d.effort is not None and d.effort.get("level") is not None:
        return []  # the reported torque held at the limit: read (:mod:`.effort_stage`)
    thr = (tl.threshold or {}).get("-")
    if thr is not None and thr <= res:
        return []
    edge = d.allowance.edge("torque_limit", "-") if d.allowance is not None else 0.0
    if d.effort is None and thr is not None and thr <= edge:
        d.say(
            f"torque limit: these drives reach every cut beyond {100 * thr:.0f} %, and the wheel"
            f" angles name none under the clean-fit allowance's {100 * edge:.0f} % whatever the"
            " drive: none asked (the rotor's datasheet inertia or the motors' logged torque"
            " reads smaller cuts)"
        )
        d.evidence_judged.append({"effect": "torque_limit", "plan": "accel",
                                  "why": "untested_allowance", "threshold": thr, "edge": edge})  # fmt: skip
        return []
    (c,) = tl.fit.candidates
    plan = evidence.evidence_plan(c.name)[0]
    if d.held_plans.get(plan):
        logs = ", ".join(h["log"] for h in d.held_plans[plan])
        d.say(
            f"torque limit: the logs hold the drive that asks the motors for it ({plan!r}:"
            f" {logs}); what it leaves unread another draw leaves too (the rotor's datasheet"
            " inertia or the motors' logged torque reads it)"
        )
        d.evidence_judged.append({"effect": "torque_limit", "plan": plan, "why": "untested_held",
                                  "logs": [h["log"] for h in d.held_plans[plan]]})  # fmt: skip
        return []
    ext = c.to_ext(np.array([-res]))
    drew = ask({"plan": plan}, d.held_plans)  # nothing held: its first draw
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
