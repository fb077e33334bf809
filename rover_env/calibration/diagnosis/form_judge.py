"""The model form re-judged beside the effects (:attr:`Options.rejudge_form`), and a form's
fit joined into a named effect's interval (:func:`join_form_interval`).

Why apart from :mod:`.form`: that stage fits the forms before any effect; this one asks,
once effects are fitted, whether the forms took what an effect explains better.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from rover_env.calibration import residuals as rs
from rover_env.calibration.candidates import Extensions
from rover_env.calibration.diagnosis.judge import (
    better_worse,
    comparable_held,
    fit_budget,
    fit_dict,
    fmt_phys,
    gain,
    interval_reaches_off,
    log_ratios,
    p_improved,
    passes_window_test,
)
from rover_env.calibration.diagnosis.parallel import map_parallel
from rover_env.calibration.diagnosis.state import FormFit, Options, Scored
from rover_env.calibration.fit import Evaluator, Fit, fit, information_criteria


def form_rejudgement(
    ev: Evaluator,
    ev0: Evaluator,
    winner: Scored,
    ranked: list[Scored],
    adopted: list[FormFit],
    noise: dict[str, float],
    opts: Options,
    say: Callable[[str], None],
) -> dict[str, Any]:
    """Judge the adopted model forms again, beside the effects (:attr:`Options.rejudge_form`).

    ``ev`` replays under the adopted forms, ``ev0`` under the nominal ones (same windows,
    same signal scale). The significant candidates (best held-out gain first, at most
    ``opts.rejudge_form``) are refitted under the nominal form. Every model is compared on
    the same training windows against the nominal model without effects, by BIC with
    windows as observations: the winner with the forms counts one parameter per adopted
    form. The forms are reverted (``revert``) only when a nominal-form fit has the lower
    BIC and also passes the held-out window test against the nominal model; the reason is in
    ``text``. Nothing is named here: a reverted diagnosis judges every candidate again.
    When the forms are kept, the winner's interval is joined with its own fit's under the
    nominal form (:func:`join_form_interval`) if that fit's
    interval keeps clear of "off" (:func:`join_if_seen`).
    """
    pool = [s for s in ranked if s.significant][: opts.rejudge_form]
    if winner not in pool:
        pool = [winner, *pool[: max(opts.rejudge_form - 1, 0)]]
    # Compare on the windows every fit used: the numpy-only candidates' subset if any did.
    which = "train_sub" if any(s.fit.which == "train_sub" for s in pool) else "train"
    n = len(ev0.sets[which])
    t_nom = rs.window_losses(ev0.run({}, which), ev0.scale)
    h_nom = rs.window_losses(ev0.run({}, "held"), noise)

    def d_bic(e: Evaluator, ext: Extensions, k: int) -> float:
        tl = rs.window_losses(e.run(ext, which), ev0.scale)
        return information_criteria(float(np.sum(log_ratios(t_nom, tl))), n, k)[1]

    with_form_bic = d_bic(ev, winner.fit.ext, winner.fit.k + len(adopted))

    def refit(i: int) -> Scored:
        cands = pool[i].fit.candidates
        c_which = pool[i].fit.which
        f = fit(ev0, cands, c_which, max_nfev=fit_budget(cands, opts))
        hl = rs.window_losses(ev0.run(f.ext, "held"), noise)
        h0 = comparable_held(ev0, f.ext, {}, h_nom, noise)
        s = Scored(f, float(hl.sum()), hl, gain(h0, hl), p_improved(h0, hl), 0.0, 0.0, n)
        s.d_bic = d_bic(ev0, f.ext, f.k)
        s.significant = passes_window_test(s, opts)
        return s

    def report(s: Scored) -> None:
        say(
            f"  nominal form: {s.fit.name:22s} {fmt_phys(s.fit)}  held-out"
            f" {better_worse(s.gain)}  p={s.p:.2g}  dBIC={s.d_bic:+.1f}"
        )

    nominal = map_parallel(refit, report, len(pool), lambda i: pool[i].fit.candidates, ev0, opts)
    best = min((s for s in nominal if s.significant), key=lambda s: s.d_bic, default=None)
    forms = ", ".join(f"{f.name} {f.text(f.value)}" for f in adopted)
    text = f"{winner.fit.name} with {forms}: dBIC {with_form_bic:+.1f} against the nominal model"
    revert = best is not None and best.d_bic < with_form_bic
    if best is not None:
        text += f"; {best.fit.name} under the nominal form: dBIC {best.d_bic:+.1f}"
    else:
        text += "; no candidate passes the held-out test under the nominal form"
    same = next((s for s in nominal if s.fit.name == winner.fit.name), None)
    if not revert and same is not None and join_if_seen(winner.fit, same, with_form_bic):
        text += (
            f"; {winner.fit.name}'s interval joined with its fit under the nominal form"
            f" ({fmt_phys(same.fit)})"
        )
    return {
        "revert": bool(revert),
        "text": text,
        "forms": {f.name: f.as_json() for f in adopted},
        "with_forms": {"effect": winner.fit.name, "d_bic": with_form_bic},
        "nominal": {s.fit.name: {**fit_dict(s), "d_bic_vs_nominal": s.d_bic} for s in nominal},
        "windows": which,
    }


FORM_JOIN_BIC = 10.0
"""A nominal-form refit whose training BIC is worse than the adopted forms' fit by more
than this (strong evidence, Kass and Raftery) is not joined into the named interval."""


def join_if_seen(f: Fit, nominal: Scored, with_forms_bic: float | None = None) -> bool:
    """Join ``f``'s interval with ``nominal``'s (the same effect refitted under the nominal
    model form: :func:`join_form_interval`) if the nominal form
    sees the effect (its refit's interval keeps clear of "off") and the windows do not
    reject it (its training BIC within :data:`FORM_JOIN_BIC` of ``with_forms_bic``, the
    named fit's under the adopted forms, both against the nominal model); whether it joined.

    A refit whose interval reaches off does not exclude the effect's absence, and joined, it
    would make the named interval reach off after the winner was judged clear of it (second
    generator 14113: torque limit -0.244 [-0.283, -0.201]; under the nominal form 0.040
    [-0.152, 1]; joined [-0.283, 1]). A refit clear of off is joined even if it fails the
    held-out test (second generator lag 15094, 16.6 ms: 13.0 ms [8.9, 17.1] alone, joined
    with the nominal form's [8.9, 24.7]). A form the windows reject is not (stop 38, second
    generator 17093: torque limit -0.147 [-0.185, -0.113] with the forms, dBIC -43.8; under
    the nominal form -0.332 [-0.433, -0.044], dBIC +2.9, no better than no effect at all)."""
    if interval_reaches_off(nominal.fit):
        return False
    if with_forms_bic is not None and nominal.d_bic - with_forms_bic > FORM_JOIN_BIC:
        return False
    join_form_interval(f, nominal.fit)
    return True


def join_form_interval(f: Fit, other: Fit) -> None:
    """Widen ``f``'s interval of each one-variable candidate to cover ``other``'s, the same
    candidates fitted under another model form; the widening goes to :attr:`Fit.form_pad`,
    so a fit with more effects carries it (:func:`carry_form_pad`).

    Why (issue 16, stop 34): the model forms are implementation choices (the speed loop's
    anti-windup, the tire's relaxation and slip floor) chosen by the windows among a few; a
    log from another implementation matches none of them exactly, and the estimate moves
    with the choice. On the second generator's logs a 0.191 s lag was fitted 0.169 [0.144,
    0.182] under the adopted forms and 0.177 [0.157, 0.192] under the nominal ones; its lags
    were fitted low in 7 of 7 matrix cases.
    """
    if [c.name for c in f.candidates] != [c.name for c in other.candidates]:
        raise ValueError(f"{other.name} is not a refit of {f.name}")
    i = 0
    for c in f.candidates:
        n = len(c.labels)
        if n == 1 and np.isfinite(other.ci_lo[i]) and np.isfinite(other.ci_hi[i]):
            lo = min(float(f.ci_lo[i]), float(other.ci_lo[i]), float(other.x[i]))
            hi = max(float(f.ci_hi[i]), float(other.ci_hi[i]), float(other.x[i]))
            pad = (float(f.ci_lo[i]) - lo, hi - float(f.ci_hi[i]))
            if len(f.candidates) == 1:
                f.form_pad = (f.form_pad[0] + pad[0], f.form_pad[1] + pad[1])
            f.ci_lo[i], f.ci_hi[i] = lo, hi
            f.se[i] = max(f.se[i], (hi - lo) / (2 * f.tq))
        i += n
