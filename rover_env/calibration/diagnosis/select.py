"""Stage 5, select: which effects are named, and how sure.

Owns the decision after the single fits: the winner (of the candidates that passed the
held-out window test, the one with the most evidence over all windows whose interval, the
replay's bias in it, keeps clear of "off"), a tie with the runner-up and the
drive that separates them, forward selection of a second effect beside the winner, the
trade test (an effect that makes a signal it leaves above its floor worse is not named with
confidence) and the named effects' finished intervals (signal groups' disagreement, sensor
noise, the model's form: :func:`allow_form`). Why one stage: each step can undo the one
before (a second effect replaces the winner alone, a trade drops the second effect or names
nothing, and a torque limit the rotor inertia explains as well names nothing).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from rover_env.calibration import residuals as rs
from rover_env.calibration.candidates import (
    REPLACED_BY_SOIL,
    Candidate,
    merge,
)
from rover_env.calibration.diagnosis.fit_stage import (
    bias_correct,
    detection_limit,
    polish,
    weighed_by,
)
from rover_env.calibration.diagnosis.floor import model_floor
from rover_env.calibration.diagnosis.judge import (
    allowance_reaches_off,
    below_detection_limit,
    better_worse,
    fit_budget,
    fit_dict,
    floor_test,
    fmt_phys,
    interval_reaches_off,
    passes_window_test,
    pegged,
    plugin_capable,
    score,
    screened,
    trade_share,
    traded_signals,
    unexplained,
)
from rover_env.calibration.diagnosis.motion import MOTION_GROUP, from_motion
from rover_env.calibration.diagnosis.parallel import map_parallel
from rover_env.calibration.diagnosis.rotor import profile_rotor, rotor_test
from rover_env.calibration.diagnosis.shared import shared_partners, shared_refits
from rover_env.calibration.diagnosis.state import Diagnosis, Options, Scored
from rover_env.calibration.diagnosis.straight import SINKAGE_GROUP, from_straight
from rover_env.calibration.diagnosis.tie import reopen, tie
from rover_env.calibration.fit import Evaluator, carry_form_pad, fit, stack_fits, widen_by_groups
from rover_env.calibration.noise_interval import noise_se, widen_by_noise


def name_winner(d: Diagnosis) -> None:
    """Sets the winner: of the significant candidates, in order of
    :func:`all_windows_evidence` (with :attr:`~.state.Options.pegged_last`, fits that end
    at their range's far end after the others), the first whose interval, the replay's bias in
    it (and a torque limit's rotor inertia, :func:`.rotor.profile_rotor`), keeps clear of
    "off" (one that reaches it is not named with confidence)."""
    ev = d.ev

    def correct(s: Scored) -> None:
        bias_correct(
            ev if s.fit_scale is None else replace(ev, scale=s.fit_scale, replays=0, seconds=0.0),
            s,
            d.sensor_noise,
            d.st,
        )
        profile_rotor(d, s)

    d.winner = first_confident(
        naming_order(d.ranked, d.opts.pegged_last),
        correct,
        lambda s: None,
        d.say,
        detection_limits(d),
    )
    d.passed_over = passed_over(d.ranked, d.winner, d.opts.pegged_last)
    if d.passed_over is not None:
        d.say(
            f"{d.passed_over['effect']} ended at its range's far end"
            f" ({', '.join(d.passed_over['at_end'])}) and led the evidence; tried after the fits"
            f" inside their ranges: {d.passed_over['named_first']} named first"
        )


def passed_over(
    ranked: list[Scored], winner: Scored | None, pegged_last: bool
) -> dict[str, Any] | None:
    """The record of a pegged fit (:func:`.judge.pegged`) that had the most evidence of the
    significant candidates and was not the winner because ``pegged_last`` tried it after the
    fits inside their ranges; None otherwise (nothing passed over, or the option is off)."""
    sig = [s for s in ranked if s.significant or s is winner]
    if not pegged_last or winner is None or not sig:
        return None
    lead = min(sig, key=all_windows_evidence)
    at_end = pegged(lead.fit)
    if lead is winner or not at_end:
        return None
    return {
        "effect": lead.fit.name,
        "at_end": at_end,
        "value": fmt_phys(lead.fit),
        "named_first": winner.fit.name,
    }


def naming_order(ranked: list[Scored], pegged_last: bool) -> list[Scored]:
    """The significant candidates in the order they are tried for the name: by
    :func:`all_windows_evidence`; with ``pegged_last`` a fit that ends at its range's far
    end (:func:`.judge.pegged`) after every fit inside its range, never dropped."""
    return sorted(
        [s for s in ranked if s.significant],
        key=lambda s: (pegged_last and bool(pegged(s.fit)), all_windows_evidence(s)),
    )


def all_windows_evidence(s: Scored) -> float:
    """ΔBIC of ``s`` over every window, training and held-out (lower: more evidence): the
    order in which candidates that passed the window test are named.

    The held-out test guards against a fit that only fits its own windows; among fits that
    passed it, the choice is a comparison of models, which all the windows make better
    than the held-out drive's third alone. Why (stop 71): on the spent cases of blocks
    50800-51200 the held-out gain and the training ΔBIC chose different winners among
    significant candidates 7 times; the training ΔBIC chose the truth 6 times, the gain
    never (a 0.112 s delay, 50924: held-out 28.4 % better against the lag's 31.3 %,
    training ΔBIC -25.9 against -17.0; named the lag)."""
    n_held = len(s.held_losses)
    k = s.fit.k
    train = s.d_bic - k * math.log(max(s.n_train, 2))
    held = n_held * math.log(max(1.0 - s.gain, 1e-300))  # gain = 1 - exp(mean log ratio)
    return train + held + k * math.log(max(s.n_train + n_held, 2))


def select(d: Diagnosis) -> None:
    """After the winner: the tie, a second effect, the trade test, the finished intervals."""
    d.tie = tie(d)
    forward_selection(d)
    settle(d)
    rotor_check(d)
    finish_intervals(d)
    name_next(d)
    reopen(d)


def rotor_check(d: Diagnosis) -> None:
    """The rotor test (:func:`.rotor.rotor_test`): a named torque limit the rotor inertia
    in its place explains as well on the held-out windows is not named with confidence, nor
    is what was named with it (their fits were made beside it), unless that effect is named
    by itself (:func:`partner_alone`)."""
    if rotor_test(d):
        return
    assert d.rotor is not None
    names = [c.name for s in d.chosen for c in s.fit.candidates]
    d.rotor_withdrawn = {
        "effects": names,
        "fits": {s.fit.name: fit_dict(s) for s in d.chosen},
        "p_torque_better": d.rotor["p_torque_better"],
        "armature": d.rotor["armature"],
    }
    d.say(
        f"not named with confidence: {' + '.join(names)}; the rotor inertia"
        f" {d.rotor['armature']:.3g} kg m² in the torque limit's place does as well on the"
        f" held-out windows (p {d.rotor['p_torque_better']:.2g} that the limit is better)"
    )
    d.demoted, d.chosen = d.chosen, []
    d.trade_excused = None
    d.final_floor = d.noise
    kept = partner_alone(d, [n for n in names if n != "torque_limit"])
    if kept is not None:
        partner, d.final_floor = kept
        d.rotor_withdrawn["kept"] = partner.fit.name
        d.say(f"{partner.fit.name} stands alone (its own fit, without the limit): named")
        d.chosen = [partner]


def partner_alone(d: Diagnosis, partners: list[str]) -> tuple[Scored, dict[str, float]] | None:
    """After the rotor test withdrew a torque limit named beside another effect: that
    effect's own single fit and its model's floor, if it is named by itself (significant,
    its interval clear of "off" with the replay's bias in it, no signal traded), else None.
    Why (stop 63): withdrawing the whole choice lost a loose soil named beside the limit
    (case 50126), which the limit, not the soil, made doubtful."""
    if len(partners) != 1:
        return None
    singles = [s for s in d.ranked if [c.name for c in s.fit.candidates] == partners]
    if not singles or not singles[0].significant:
        return None
    floor = named_alone(d, singles[0])
    return None if floor is None else (singles[0], floor)


def named_alone(d: Diagnosis, s: Scored) -> dict[str, float] | None:
    """The floor of the model with ``s``'s single fit named by itself, or None when it is
    not: its interval, the replay's bias in it, must keep clear of "off", its magnitude
    reach its detection limit (:func:`first_confident`) and it must trade no signal."""

    def correct(x: Scored) -> None:
        if x is not d.winner:  # the winner's interval holds the bias already
            ev = d.ev if x.fit_scale is None else replace(d.ev, scale=x.fit_scale)
            bias_correct(ev, x, d.sensor_noise, d.st)

    if first_confident([s], correct, lambda x: None, d.say, detection_limits(d)) is None:
        return None
    worse, floor = trades(d, [s])
    if worse:
        d.say(f"{s.fit.name} alone trades {', '.join(worse)}: not named")
        return None
    return floor


def name_next(d: Diagnosis) -> None:
    """After the clean-fit allowance withdrew every name: the next significant candidates in
    the naming order, each by its own fit (:func:`named_alone`), finished and judged by its
    own allowance, until one is named (``next`` in ``allowance_withdrawn``; the others it
    withdraws join ``effects``) or none is left (:attr:`.state.Options.next_after_withdrawn`).
    A name under its detection limit lets the next candidate be tried
    (:func:`first_confident`); one the allowance withdrew had ended the naming. Not tried:
    a torque limit (its rotor test compares with the configured model, not alone) and the
    effects fitted beside a withdrawn pair (judged alone already: :func:`partner_alone`)."""
    w = d.allowance_withdrawn
    if not d.opts.next_after_withdrawn or w is None or d.chosen:
        return
    done = set(w["effects"]) | set(w.get("beside", [])) | {"torque_limit"}
    tried = {id(s) for s in d.demoted} | {id(d.winner)}
    for s in naming_order(d.ranked, d.opts.pegged_last):
        names = [c.name for c in s.fit.candidates]
        if id(s) in tried or done & set(names):
            continue
        floor = named_alone(d, s)
        if floor is None:
            continue
        d.chosen = [s]
        finish_chosen(d)
        off = effects_off(s, d.opts)
        if not off:
            w["next"], d.final_floor = s.fit.name, floor
            d.say(f"{s.fit.name}, next in the naming order: named {fmt_phys(s.fit)}")
            return
        s.test = withdrawn_test(off)
        d.say(f"{s.fit.name} {fmt_phys(s.fit)}, next in the naming order: {s.test}")
        w["effects"] = w["effects"] + names
        w["params"] = {**w["params"], **{n: fmt_phys(s.fit, {n}) for n in sorted(off)}}
        d.demoted, d.chosen = [*d.demoted, s], []
    d.final_floor = d.noise


def forward_selection(d: Diagnosis) -> None:
    """Sets the winner's floor, what it leaves above it, the partners and pairs tried, and
    the chosen effects: the winner, or the winner with a second effect."""
    winner, ev, opts = d.winner, d.ev, d.opts
    d.chosen = [winner] if winner is not None else []
    d.w_floor = d.noise
    if winner is None:
        return
    # Against the floor of the winner's own model (a tilted or slower model replays
    # its own twin less exactly than the nominal one).
    d.w_floor = model_floor(d, ev.config(winner.fit.ext))
    held_w = rs.table(rs.stack(ev.run(winner.fit.ext, "held"), d.prepared), d.w_floor)
    d.left = unexplained(held_w, d.w_floor)
    if not d.left:
        d.say("after the winner no held-out signal exceeds noise: no second effect sought")
        return
    d.say(f"still above noise after {winner.fit.name}: {', '.join(d.left)}; forward selection")
    if opts.blind_partners:
        d.tried = blind_partners(d)
        for s2 in d.tried:
            report_pair(d, s2)
    else:
        # The tie's runner-up is tried too: a tie says either effect explains the drives
        # alone, not that only one is there; the pair is named only if it beats the
        # winner alone by the same window test (stop 32: a foreign 7.3 deg slope tied
        # with a 0.44 s lag was never tried beside it).
        names = [c.name for c in winner.fit.candidates]
        allowed = {c.name for c in partner_pool(d.cands, names, opts.soil_alone)}
        others = [
            s
            for s in d.ranked
            if s is not winner and s.gain > 0.0 and {c.name for c in s.fit.candidates} <= allowed
        ][: opts.second]
        d.tried = map_parallel(
            lambda i: fit_pair(d, others[i]),
            lambda s2: report_pair(d, s2),
            len(others),
            lambda i: [*winner.fit.candidates, *others[i].fit.candidates],
            ev,
            opts,
        )
    if not any(s.significant for s in d.tried):
        for s2 in sorted(d.tried, key=lambda s: -s.gain):
            floor_test(d, s2, d.left, d.w_floor, winner.fit.ext)
    w_names = {c.name for c in winner.fit.candidates}
    pairs = sorted([s for s in d.tried if s.significant], key=lambda s: -s.gain)
    second = first_confident(
        pairs,
        lambda s: _bias_and_rotor(d, ev, s),
        lambda s: None if s.refit else {c.name for c in s.fit.candidates} - w_names,
        d.say,
        partner_limits(d, pairs),
    )
    if second is not None:
        d.chosen = [second]
        if d.tie is not None and set(d.tie["effects"]) <= {c.name for c in second.fit.candidates}:
            d.say(f"tie resolved: {' and '.join(d.tie['effects'])} are both named")
            d.tie_resolved, d.tie = d.tie, None


def partner_limits(d: Diagnosis, pairs: list[Scored]) -> dict[str, dict[str, float]] | None:
    """Each significant pair's partner's detection limit beside the winner (effect -> side
    -> magnitude; :attr:`~.state.Options.partner_limit`): the limit a second name must
    reach, as the winner's must reach its own. Measured with the winner held at its fit,
    so "now" is the model with the winner (the single fits' limits were measured against
    the model without it and overstate what a pair can show). Set in
    :attr:`Diagnosis.partner_limits`.

    Why (stop 90, exploratory seed 70500, a command lag of 0.30 s on one or two drives): a
    friction of -0.59 and -0.62 was named beside the right lag, 11.5 % better on the
    held-out drive, while its single fit's limit was -1.57 (beyond its range); with
    three drives no pair was named in 183 spent cases. Off by default: fresh study 71000
    found it changed no final name in 130 cases (docs/calibration/method.md)."""
    winner = d.winner
    if not (d.opts.partner_limit and d.opts.name_above_limit) or winner is None or not pairs:
        return None
    w_names = {c.name for c in winner.fit.candidates}
    out: dict[str, dict[str, float]] = {}
    for s in pairs:
        for c in s.fit.candidates:
            if c.name in w_names or c.name in out:
                continue
            plug = plugin_capable(c) and all(plugin_capable(w) for w in winner.fit.candidates)
            which = "train" if plug or c.discrete else "train_sub"
            out[c.name] = detection_limit(d.ev, c, which, d.noise, hold=winner.fit.ext)
            shown = ", ".join(f"{k} {v:.3g}" for k, v in out[c.name].items()) or "none"
            d.say(f"beside {winner.fit.name}: {c.name}'s detection limit {shown}")
    d.partner_limits = out
    return out


def _bias_and_rotor(d: Diagnosis, ev: Evaluator, s: Scored) -> None:
    """A partner's interval widened as the winner's: the replay's bias, the rotor inertia."""
    bias_correct(ev, s, d.sensor_noise, d.st)
    profile_rotor(d, s)


def blind_partners(d: Diagnosis) -> list[Scored]:
    """Sets :attr:`Diagnosis.partners`; the pairs to judge, each partner as fitted beside
    the winner (:attr:`Options.blind_partners`)."""
    winner, ev, opts = d.winner, d.ev, d.opts
    assert winner is not None
    w_cands = winner.fit.candidates
    # Each other effect's own magnitude-blind search with the winner held at its
    # fit (forward selection proper): an effect the winner hides, or one that alone
    # fits the drives worse than nothing, shows here (issue 16, stop 35: rolling
    # resistance 0.052 + load-dependent friction 0.108, the latter alone p = 1; a
    # soil + 2.2 deg slope, the slope alone fitted at heading -4 deg, truth 131).
    pool = partner_pool(d.cands, [w.name for w in w_cands], opts.soil_alone)
    # Stage two's fits weigh the training signals as stage one's did, with the winner as
    # the reference: each by its residual after the winner (or its floor). Weighed by
    # the residuals before it, the signals the winner fixed still set the scale, and
    # a partner's improvement where the winner leaves residual is diluted (15080:
    # wheel_3R scaled 0.124 against 0.015 left). Its BIC is in floor units, as every
    # BIC that names (:func:`.judge.training_criteria`).
    ev_w, _ = weighed_by(d, winner.fit.ext, "train")  # the cache is shared

    def fit_partner(i: int) -> Scored:
        c = pool[i]
        plug = plugin_capable(c) and all(plugin_capable(w) for w in w_cands)
        which = "train" if plug or c.discrete else "train_sub"

        def fit_at(w: str, coarse: bool) -> Scored:
            f = fit(
                ev_w, [c], w, max_nfev=fit_budget([c], opts), hold=winner.fit.ext, coarse=coarse
            )
            return score(d, f, winner.held_losses, winner.fit.ext)

        return screened(fit_at, which, c.discrete, opts)

    def report_partner(s: Scored) -> None:
        d.say(
            f"beside {winner.fit.name}: {s.fit.name:24s} {fmt_phys(s.fit)}"
            f"  held-out {better_worse(s.gain)} than the winner alone  p={s.p:.2g}"
        )

    order = sorted(range(len(pool)), key=lambda i: -max(1, len(pool[i].forms)))
    d.partners = map_parallel(
        fit_partner, report_partner, len(pool), lambda i: [pool[i]], ev_w, opts, order
    )
    ev.replays += ev_w.replays
    ev.seconds += ev_w.seconds
    # The partners that help the held-out drive most are judged as pairs, each as
    # fitted beside the winner (stage by stage; a joint refinement from there moved
    # both away from the truth on 15080 and lost the held-out test, 19.6 % better
    # p 0.0004 -> 16.3 % p 0.06).
    # A partner that shares the winner's response is judged fitted with it instead
    # (:mod:`.shared`: held at its fit, the winner has taken the partner's share).
    shared = shared_partners(d, pool)
    gone = {c.name for c in shared}
    best = sorted(
        [s for s in d.partners if s.gain > 0.0 and s.fit.name not in gone], key=lambda s: -s.gain
    )
    others = [replace(s, fit=stack_fits(winner.fit, s.fit)) for s in best[: opts.second]]
    for s in others:
        s.significant = passes_window_test(s, opts) and not s.screened
        s.test = "windows" if s.significant else ""
    return others + shared_refits(d, shared)


def partner_pool(cands: list[Candidate], winner: list[str], soil_alone: bool) -> list[Candidate]:
    """The candidates forward selection tries beside the ``winner``'s effects: every other,
    except (``soil_alone``) the tire's beside a lone loose soil (:data:`REPLACED_BY_SOIL`)."""
    gone = set(winner)
    if soil_alone and winner == ["loose_soil"]:
        gone |= REPLACED_BY_SOIL
    return [c for c in cands if c.name not in gone]


def fit_pair(d: Diagnosis, s: Scored) -> Scored:
    """The winner and ``s``'s candidates fitted together from their single fits, judged
    against the winner alone (forward selection without :attr:`Options.blind_partners`)."""
    winner, opts = d.winner, d.opts
    assert winner is not None
    both = [*winner.fit.candidates, *s.fit.candidates]
    which = "train" if all(plugin_capable(c) for c in both) else "train_sub"
    xs = np.concatenate([winner.fit.x, s.fit.x])
    x0 = xs if xs.size else None
    f2 = fit(d.ev, both, which, x_start=x0, max_nfev=max(3, opts.max_nfev - 2), probe=False)
    carry_form_pad(f2, [winner.fit, s.fit])
    s2 = score(d, f2, winner.held_losses, winner.fit.ext, k=s.fit.k)
    s2.significant = passes_window_test(s2, opts)
    s2.test = "windows" if s2.significant else ""
    return s2


def report_pair(d: Diagnosis, s2: Scored) -> None:
    """A pair's progress line."""
    d.say(
        f"second: {s2.fit.name:40s} {fmt_phys(s2.fit)}  held-out {better_worse(s2.gain)}"
        f" than the winner alone  p={s2.p:.2g}  dBIC={s2.d_bic:+.1f}"
    )


def trades(d: Diagnosis, ch: list[Scored]) -> tuple[dict[str, dict[str, float]], dict[str, float]]:
    """The signals ``ch`` trades (:func:`.judge.traded_signals`) and its model's floor."""
    ev = d.ev
    held_c = ev.run(merge(*(s.fit.ext for s in ch)), "held")
    floor = chosen_floor(d, ch)
    left_c = unexplained(rs.table(rs.stack(held_c, d.prepared), floor), floor)
    worse = traded_signals(d.base_held, held_c, left_c, d.opts.alpha, 1.0 + d.opts.min_gain)
    if worse:
        share = trade_share(d.base_held, held_c, worse, floor)
        for v in worse.values():
            v["share"] = share
        if share < d.opts.trade_share:
            names = " + ".join(s.fit.name for s in ch)
            d.say(
                f"{names} makes {', '.join(worse)} worse, but the traded signals lost"
                f" {share:.2g} of what the rest gained (under {d.opts.trade_share:g}):"
                " not a trade that refuses the naming"
            )
            d.trade_excused = {"effects": names, "worse": worse}
            return {}, floor
    d.trade_excused = None
    return worse, floor


def chosen_floor(d: Diagnosis, ch: list[Scored]) -> dict[str, float]:
    """The replay floor of the model with ``ch`` named (the winner's alone is known)."""
    if ch == [d.winner]:
        return d.w_floor
    return model_floor(d, d.ev.config(merge(*(s.fit.ext for s in ch))))


def settle(d: Diagnosis) -> None:
    """The trade test: sets the chosen effects, the second effect dropped, what is not
    named with confidence (and the effects it demoted), and the final model's floor.

    Named with confidence only if the effects do not trade one signal for another: a
    signal left above the model's floor that the fit made worse, window by window, is what
    a catalogue effect standing in for one outside it does (issue 16: a rover 20 % heavier
    was named "friction +15 %" in every matrix, theta_4 worse by 8-22 %, p<0.002)."""
    winner = d.winner
    chosen, worse, d.dropped, floor_c = settle_trades(d.chosen, winner, lambda ch: trades(d, ch))
    if d.dropped is not None:
        d.say(
            f"{d.dropped['effects']} makes {', '.join(d.dropped['worse'])} worse;"
            f" {winner.fit.name if winner else ''} alone does not: the second effect is dropped"
        )
    if worse:  # only ever non-empty for a non-empty choice
        names = [c.name for s in chosen for c in s.fit.candidates]
        d.traded = {
            "effects": names,
            "worse": worse,
            "fits": {s.fit.name: fit_dict(s) for s in chosen},
        }
        d.demoted = chosen
        d.say(
            f"not named with confidence: {' + '.join(names)} makes "
            + ", ".join(
                f"{k} worse ({v['rms_ratio']:.2f}x RMS, p {v['p']:.2g})" for k, v in worse.items()
            )
            + f" (lost {next(iter(worse.values()))['share']:.3g} of what the rest gained)"
            + ", left above its floor: an effect outside the catalogue may be standing"
            " behind it"
        )
        chosen = []
        # A tie stays: the drive that separates the two is still the evidence to get (a
        # 42 ms lag of the second generator, case 9094: the delay won, tied with the lag,
        # and traded theta_1).
    d.chosen = chosen
    # The updated model's own floor (an effect can make the replay itself less exact).
    d.final_floor = floor_c if chosen and floor_c is not None else d.noise


def finish_intervals(d: Diagnosis) -> None:
    """The named effects' intervals: a fit of several parameters finished first
    (:attr:`Options.polish`; its interval and the replay's bias in it are then the finished
    fit's), then widened by the signal groups' disagreement (model form) and to at least
    what the sensors' own noise puts on them (:attr:`Options.noise_draws`), last by the
    clean-fit allowance (:func:`allow_form`)."""
    finish_chosen(d)
    withdraw_within_allowance(d)


def finish_chosen(d: Diagnosis) -> None:
    """:func:`finish_intervals` but the withdrawal: polish, signal groups, sensor noise and
    the clean-fit allowance, on the chosen effects."""
    ev, opts = d.ev, d.opts
    for s in d.chosen:
        ev_s = ev if s.fit_scale is None else replace(ev, scale=s.fit_scale)
        if polish(ev_s, s, opts.polish):
            bias_correct(ev_s, s, d.sensor_noise, d.st)
            d.say(f"{s.fit.name}: finished from where its search stopped: {fmt_phys(s.fit)}")
    for s in d.chosen:
        read_soil(d, s)
        widen_by_groups(s.fit)
    widen_by_sensor_noise(d)
    allow_form(d)


def read_soil(d: Diagnosis, s: Scored) -> None:
    """A named soil's k_phi read from straight driving or the rover's motion, where the
    options ask (:mod:`.straight`, :mod:`.motion`); ``s.read_from`` records what it replaced
    (and, read from straight driving, each signal group's reading there)."""
    opts = d.opts
    if not (opts.soil_from_straight or opts.soil_from_motion):
        return
    before, was = fmt_phys(s.fit), s.fit.physical()
    ev_s = d.ev if s.fit_scale is None else replace(d.ev, scale=s.fit_scale)
    group = SINKAGE_GROUP if opts.soil_from_joints else MOTION_GROUP
    read = (
        from_straight(ev_s, s.fit, not opts.soft_end_unread, group)
        if opts.soil_from_straight
        else None
    )
    reads: dict[str, object] = {}
    if read is not None:  # every group's reading, moved or not
        c = s.fit.candidates[0]
        got = {g: None if u is None else _shown(c, u) for g, u in read.reads.items()}
        reads = {"group": read.group, "reads": got}
    if read is not None and read.replaced is not None:
        rule = "straight"
        how = f"straight driving (the {read.group} signals' own minimum on the windows without a turn)"
    elif opts.soil_from_motion and from_motion(s.fit) is not None:
        rule, how = "motion", "the rover's motion (the pose group's own minimum)"
    else:
        s.read_from = {"rule": None, **reads} if reads else None
        return
    s.read_from = {
        "rule": rule,
        "replaced": {e: {k: list(v) for k, v in p.items()} for e, p in was.items()},
        **reads,
    }
    d.say(f"{s.fit.name}: read from {how}: {fmt_phys(s.fit)} (over every signal: {before})")


def _shown(c: Candidate, x: float) -> float:
    """``c``'s one parameter at ``x`` in its effect's terms (the soil's k_phi for 1 / k_phi)."""
    return x if c.shown is None else c.shown(x, x, x, "")[1]


def widen_by_sensor_noise(d: Diagnosis) -> None:
    """Each named effect's interval, to at least what the sensors alone put on it
    (:attr:`.state.Options.noise_draws`; 0: none)."""
    if d.opts.noise_draws <= 0:
        return
    ev, opts = d.ev, d.opts
    for s in d.chosen:
        ev_s = ev if s.fit_scale is None else replace(ev, scale=s.fit_scale)
        nse = noise_se(ev_s, s.fit, d.sensor_noise, d.st, draws=opts.noise_draws)
        if nse is None:
            continue
        was = fmt_phys(s.fit)
        moved = widen_by_noise(s.fit, nse)
        d.say(
            f"{s.fit.name}: sensor noise alone (standard error "
            + ", ".join(f"{v:.3g}" for v in nse.se)
            + f", {nse.draws} simulated draws): "
            + (f"{was} widened to {fmt_phys(s.fit)}" if moved else "interval kept")
        )


def allow_form(d: Diagnosis) -> None:
    """Each named effect's interval for the truth, widened by the clean-fit allowance
    (:attr:`.state.Options.form_allowance`): the spread of what its fit finds on clean
    drives of another implementation, the model's form seen through it (each effect of a
    pair by its own), and its far end at least the table's reach beyond the fit
    (:func:`~rover_env.calibration.form_allowance.reach_floor`)."""
    table = d.allowance
    if table is None:
        return
    for s in d.chosen:
        pads = {c.name: table.pad(c.name) for c in s.fit.candidates if not c.discrete}
        mine = {k: v for k, v in pads.items() if v is not None and any(v)}
        reach = {c.name: table.reach(c.name) for c in s.fit.candidates if not c.discrete}
        reach = {k: v for k, v in reach.items() if v > 0.0}
        if not mine and not reach:
            continue
        was = fmt_phys(s.fit)
        s.fit.allowance = mine
        s.fit.reach = reach
        d.say(f"{s.fit.name}: the model's form (clean-fit allowance): {was} -> {fmt_phys(s.fit)}")


def withdraw_within_allowance(d: Diagnosis) -> None:
    """A named effect whose finished interval, the clean-fit allowance in it, reaches "off"
    is not named (:attr:`.state.Options.name_beyond_allowance`): the model's form alone
    gives as much on clean drives. Each effect of a pair is judged by its own allowance;
    the other effect of a pair that loses one was fitted beside it, so it is named only by
    itself, as the rotor test does (:func:`partner_alone`, then finished and judged the
    same way). Other named fits stay as they are; the final floor is the kept effects'."""
    if not d.opts.name_beyond_allowance:
        return
    out = [(s, effects_off(s, d.opts)) for s in d.chosen]
    gone = [(s, off) for s, off in out if off]
    if not gone:
        return
    names = [c.name for s, off in gone for c in s.fit.candidates if c.name in off]
    beside = [c.name for s, off in gone for c in s.fit.candidates if c.name not in off]
    w: dict[str, Any] = {
        "effects": names,
        "params": {n: fmt_phys(s.fit, {n}) for s, off in gone for n in sorted(off)},
    }
    d.allowance_withdrawn = w
    for s, off in gone:
        s.test = withdrawn_test(off)
        d.say(f"{s.fit.name} {fmt_phys(s.fit)}: {s.test} (the model's form gives as much)")
    withdraw(d, [s for s, _ in gone], beside, w)


def withdraw(d: Diagnosis, gone: list[Scored], beside: list[str], w: dict[str, Any]) -> None:
    """Demote the named fits ``gone`` (their withdrawal recorded in ``w``); the final floor
    is what stays named's. If nothing stays, the one effect fitted ``beside`` what was
    withdrawn is named by its own fit (:func:`partner_alone`), finished as the pair was and
    judged by its own allowance (``kept`` in ``w``); else ``beside`` in ``w``, not named."""
    d.demoted = d.demoted + gone
    d.chosen = [s for s in d.chosen if s not in gone]
    d.final_floor = chosen_floor(d, d.chosen) if d.chosen else d.noise
    alone = partner_alone(d, beside) if beside and not d.chosen else None
    if alone is not None:
        partner, floor = alone
        d.chosen = [partner]
        finish_chosen(d)
        if allowance_reaches_off(partner.fit, not d.opts.presence_on_windows):
            d.say(f"{partner.fit.name} alone {fmt_phys(partner.fit)}: within its allowance too")
            d.chosen, alone = [], None
        else:
            w["kept"], d.final_floor = partner.fit.name, floor
            d.say(f"{partner.fit.name} stands alone (its own fit): named {fmt_phys(partner.fit)}")
    if beside and alone is None:
        w["beside"] = beside  # not named: fitted beside what was withdrawn


def effects_off(s: Scored, opts: Options) -> set[str]:
    """The effects of ``s`` whose interval, the clean-fit allowance in it, reaches "off"
    (:attr:`.state.Options.presence_on_windows`: the windows' interval)."""
    return {n.split(".")[0] for n in allowance_reaches_off(s.fit, not opts.presence_on_windows)}


def withdrawn_test(off: set[str]) -> str:
    """Why effects ``off`` (:func:`effects_off`) are not named."""
    what = ", ".join(sorted(off))
    return f"not named: the interval of {what} with the clean-fit allowance reaches off"


def first_confident(
    candidates: list[Scored],
    correct: Callable[[Scored], None],
    judged: Callable[[Scored], set[str] | None],
    say: Callable[[str], None],
    limits: dict[str, dict[str, float]] | None = None,
) -> Scored | None:
    """The first of ``candidates`` (best first) whose interval keeps clear of "off" and,
    given ``limits`` (:func:`detection_limits`), whose magnitude reaches its detection limit
    (:func:`.judge.below_detection_limit`).

    Each is first widened by ``correct`` (the replay's bias); ``judged`` picks the effects
    whose interval and limit count (a pair's new partner, not the winner it was fitted
    beside). One that fails loses its significance and says why in ``test``.
    """
    for s in candidates:
        correct(s)
        say(f"{s.fit.name} with the replay's bias in its interval: {fmt_phys(s.fit)}")
        off = interval_reaches_off(s.fit, judged(s))
        below = [] if limits is None else below_detection_limit(s.fit, limits, judged(s))
        if not off and not below:
            return s
        s.significant = False
        s.test = (
            f"not named: the 95 % interval of {', '.join(off)} reaches off"
            if off
            else f"not named: {'; '.join(below)}"
        )
        say(f"{s.fit.name}: {s.test}")
    return None


def detection_limits(d: Diagnosis) -> dict[str, dict[str, float]] | None:
    """Each candidate's detection limit on these logs, from its single fit (effect -> side
    -> magnitude), when a name must reach it (:attr:`~.state.Options.name_above_limit`).
    Not for a partner fitted beside the winner: its limit was measured against a model that
    leaves the winner's effect in the residual, so it overstates what the pair can show (a
    load-dependent friction hidden beside a rolling resistance was lost to it)."""
    if not d.opts.name_above_limit:
        return None
    return {s.fit.name: s.detectable for s in d.ranked if len(s.fit.candidates) == 1}


def settle_trades(
    chosen: list[Scored],
    winner: Scored | None,
    trades: Callable[[list[Scored]], tuple[dict[str, Any], dict[str, float]]],
) -> tuple[list[Scored], dict[str, Any], dict[str, Any] | None, dict[str, float] | None]:
    """The effects to name after the trade test: (chosen, what they trade, the second effect
    dropped, their model's floor). ``trades(ch)`` gives the signals ``ch`` trades
    (:func:`traded_signals`) and its floor. A pair that trades while its winner alone does
    not loses the partner: the partner, not the winner, stood in for something outside the
    catalogue. What still trades is returned for the caller to leave unnamed."""
    if not chosen:
        return chosen, {}, None, None
    worse, floor = trades(chosen)
    if worse and winner is not None and chosen != [winner]:
        alone, w_floor = trades([winner])
        if not alone:
            return [winner], {}, {"effects": chosen[0].fit.name, "worse": worse}, w_floor
    return chosen, worse, None, floor
