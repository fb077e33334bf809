"""After the first pass, whether to run the diagnosis again: under the model's forms fitted
again beside the named effect (:attr:`~.state.Options.forms_beside_winner`) or, with none named,
beside the leading candidate (:attr:`~.state.Options.forms_beside_leader`), or without adopted
forms that the re-judgement beside the effects reverts (:mod:`.form_judge`)."""

from __future__ import annotations

from dataclasses import replace

from rover_env.calibration.candidates import merge
from rover_env.calibration.diagnosis import form_judge
from rover_env.calibration.diagnosis.form import (
    ZERO_PREFIX,
    fit_forms,
    form_changes,
    form_text,
    reprepare,
    with_form,
)
from rover_env.calibration.diagnosis.judge import plugin_capable
from rover_env.calibration.diagnosis.state import LEADING, Diagnosis, Options, Scored
from rover_env.calibration.fit import Evaluator

LEADER_GAIN = 0.10
"""A candidate leads when nothing is named if it lowers the training BIC or improves the
held-out drive by this share (the naming rule's own 10 %; :attr:`Options.forms_beside_leader`)."""


def leader(d: Diagnosis) -> Scored | None:
    """The leading candidate when nothing is named: fully fitted (not screened out), replayed
    by the plugin, lowering the training BIC or improving the held-out drive by
    :data:`LEADER_GAIN`; the lowest training BIC among those."""
    leading = [
        s
        for s in d.ranked
        if not s.screened
        and all(plugin_capable(c) for c in s.fit.candidates)
        and (s.d_bic < 0 or s.gain >= LEADER_GAIN)
    ]
    return min(leading, key=lambda s: s.d_bic, default=None)


RIVAL = " (the training windows' favourite, not named)"
"""How the progress lines name the rival beside which the forms are fitted again."""


def rival(d: Diagnosis, winner: Scored) -> Scored | None:
    """The candidate the training windows favour over the named ``winner``: fully fitted,
    replayed by the plugin, its training BIC below the winner's and below nominal's; the
    lowest such (:attr:`Options.forms_beside_rival`)."""
    w_names = {c.name for c in winner.fit.candidates}
    rivals = [
        s
        for s in d.ranked
        if s is not winner
        and not s.screened
        and not {c.name for c in s.fit.candidates} & w_names
        and all(plugin_capable(c) for c in s.fit.candidates)
        and s.d_bic < min(winner.d_bic, 0.0)
    ]
    return min(rivals, key=lambda s: s.d_bic, default=None)


def forms_beside(d: Diagnosis, s: Scored, role: str) -> Options | None:
    """The options of a second pass under the forms fitted again beside ``s``'s effect, or
    None when they come out as before."""
    beside_cfg = replace(d.base0, extensions=merge(d.base0.extensions, s.fit.ext))
    again, _, _ = fit_forms(
        beside_cfg,
        reprepare(d.prepared0, beside_cfg, d.st),
        d.train_w,
        d.st,
        d.sensor_noise,
        d.opts,
        lambda f: d.say(form_text(f) + f" (beside {s.fit.name}{role})"),
    )
    # none: the forms do not differ (forms_differ)
    changes = form_changes(d.forms, again, d.opts.weak_adoption_stands)
    weak = [c for c in form_changes(d.forms, again) if c not in changes]
    if weak:
        d.forms_weak = {"beside": s.fit.name + role, "changes": weak}
        d.say(
            f"model form fitted again beside {s.fit.name}{role}: adopted on weak evidence only"
            f" ({'; '.join(weak)}); the first choice stands"
        )
    if not changes:
        return None
    d.say(
        f"model form fitted again beside {s.fit.name}{role} comes out otherwise"
        f" ({'; '.join(changes)}); the diagnosis runs again under it"
    )
    return replace(
        d.opts, forms_given=again, forms_beside=s.fit.name + role, forms_changed=tuple(changes)
    )


def judge_again(d: Diagnosis) -> Options | None:
    """After the first pass: the options of a diagnosis to run again, or None.

    The forms fitted again beside the winner (:attr:`Options.forms_beside_winner`) or, with
    none named, beside the leading candidate (:attr:`Options.forms_beside_leader`, :func:`leader`)
    that come out otherwise are given to a second pass; adopted forms that the re-judgement
    (:attr:`Options.rejudge_form`) reverts are dropped for one."""
    opts, winner = d.opts, d.winner
    if not opts.model_form:
        return None
    first = opts.forms_given is None
    if winner is None:
        lead = leader(d) if first and opts.forms_beside_leader else None
        return None if lead is None else forms_beside(d, lead, LEADING)
    # A numpy-only effect would cost ~20 x per form replay: not refitted.
    if first and opts.forms_beside_winner and all(plugin_capable(c) for c in winner.fit.candidates):
        again = forms_beside(d, winner, "")
        if again is not None:
            return again
    rv = rival(d, winner) if first and opts.forms_beside_rival else None
    if rv is not None:
        again = forms_beside(d, rv, RIVAL)
        if again is not None:
            return again
    # The joint zeros are profiled out of every fit (Evaluator.profile_zeros), the nominal
    # form's too: they are no form to re-judge, and a revert keeps them.
    adopted = [f for f in d.forms if f.adopted and not f.name.startswith(ZERO_PREFIX)]
    zeros = [f for f in d.forms if f.name.startswith(ZERO_PREFIX)]
    if adopted and opts.rejudge_form > 0:
        base0 = d.base0
        for z in zeros:  # the nominal form starts its windows from the same zeros
            base0 = with_form(base0, z) if z.adopted else base0
        ev0 = Evaluator(
            base0,
            d.st,
            d.prepared0,
            d.sets,
            scale=d.scale,
            profile_zeros=d.ev.profile_zeros,
            profile_free_gain=d.ev.profile_free_gain,
            free_common_max=d.ev.free_common_max,
            screen_middle=d.ev.screen_middle,
        )
        verdict = form_judge.form_rejudgement(
            d.ev, ev0, winner, d.ranked, adopted, d.noise, opts, d.say
        )
        if verdict["revert"]:
            d.say(
                "model form re-judged beside the effects: "
                + verdict["text"]
                + "; the forms are reverted and the diagnosis runs again without them"
            )
            if zeros:
                return replace(opts, forms_given=zeros, forms_reverted=verdict)
            return replace(opts, model_form=False, forms_reverted=verdict)
        d.say("model form re-judged beside the effects: " + verdict["text"] + "; kept")
    return None
