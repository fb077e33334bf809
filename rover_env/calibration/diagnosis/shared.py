"""Forward selection's pairs whose effects share a response, fitted together.

A command lag of tau and a delay of d both shift the wheels' response, by about tau + d.
The first named alone takes both shares, so beside it held at its fit the second fits near
"off" and is never named. Why (stop 102, spent study 72800 cases 72818 and 72819): a lag
of 0.380 s with a delay of 0.101 s was named a lag of 0.49 s, a delay of 0.22 s with a lag
of 0.38 s a delay of 0.56 s; the pair replays far better than either (held out 98.1 %
against 92.5 % better than nominal), and fitted together from the named value split three
ways both cases landed in one place from every start (0.409 and 0.068 s; 0.426 and
0.196 s). Fresh studies 72900 (fitted once) and 73000 (then reweighed): 18 and 20 of 20
pair effects named, no single lag or delay gaining a partner.
"""

from __future__ import annotations

import numpy as np

from rover_env.calibration.candidates import Candidate, shares_response
from rover_env.calibration.diagnosis.fit_stage import weighed_by
from rover_env.calibration.diagnosis.judge import (
    passes_window_test,
    plugin_capable,
    promising,
    score,
)
from rover_env.calibration.diagnosis.state import Diagnosis, Scored
from rover_env.calibration.fit import Fit, fit

REFIT_NFEV = 8
"""``least_squares`` evaluations for a shared pair's fit (each costs two more replays for
the Jacobian): the spent cases' fits from three starts had settled within it."""


def shared_partners(d: Diagnosis, pool: list[Candidate]) -> list[Candidate]:
    """The candidates of ``pool`` that share the winner's response
    (:func:`~rover_env.calibration.candidates.shares_response`), where
    :attr:`~.state.Options.shared_refit` asks and the winner is one such effect."""
    w = d.winner
    if not d.opts.shared_refit or w is None or len(w.fit.candidates) != 1:
        return []
    name = w.fit.candidates[0].name
    return [c for c in pool if shares_response(name, c.name)]


def shared_refits(d: Diagnosis, partners: list[Candidate]) -> list[Scored]:
    """Each of ``partners`` fitted with the winner, both free, from the winner's value split
    half and half between them (the pair moves the response by about the sum), then
    refitted with the signals weighed by what it leaves (:func:`reweighed`), judged against
    the winner alone by the held-out window test, as every pair is. Where
    :attr:`~.state.Options.screen` and :attr:`~.state.Options.screen_shared` ask, the pair
    is first fitted once on the screening subset with half the evaluations, and fitted as
    above only if that is :func:`~.judge.promising`, as a partner is (:func:`shared_screen`)."""
    winner = d.winner
    assert winner is not None
    w = winner.fit.candidates[0]
    out = []
    for c in partners:
        both = [w, c]
        which = "train" if all(plugin_capable(x) for x in both) else "train_sub"
        half = np.asarray(winner.fit.x, dtype=float) / 2.0
        x0 = np.clip(np.concatenate([half, half]), [*w.lo, *c.lo], [*w.hi, *c.hi])
        s_sub = shared_screen(d, both, which, x0)
        if s_sub is not None:
            out.append(s_sub)
            continue
        f2 = fit(d.ev, both, which, x_start=x0, max_nfev=REFIT_NFEV, probe=False)
        f2, scale = reweighed(d, f2)
        s2 = score(d, f2, winner.held_losses, winner.fit.ext, k=c.k)
        s2.fit_scale = scale
        s2.significant = passes_window_test(s2, d.opts)
        s2.test = "windows" if s2.significant else ""
        s2.refit = True
        out.append(s2)
    return out


def shared_screen(d: Diagnosis, both: list[Candidate], which: str, x0: np.ndarray) -> Scored | None:
    """The pair's screen: fitted once from ``x0`` on the screening subset with half of
    :data:`REFIT_NFEV`, not reweighed, scored against the winner alone. None where it is
    :func:`~.judge.promising` (or no screen is asked or possible): then the pair is fitted
    in full. Else the screen, marked screened (never named).

    Why (stop 107): the pair's fit and its two reweighed refits on every training window
    cost a lag case 9 of its 78 s, and a single lag or delay gained no partner in 12 of 12
    fresh cases (studies 72900, 73000): beside a lone lag of 0.2 s (exploratory case
    74014) the pair settled 3.4 % worse than the lag alone on the held-out drive."""
    opts = d.opts
    if not (opts.screen and opts.screen_shared) or which != "train" or d.winner is None:
        return None
    f = fit(d.ev, both, "train_sub", x_start=x0, max_nfev=REFIT_NFEV // 2, probe=False)
    s = score(d, f, d.winner.held_losses, d.winner.fit.ext, k=both[1].k)
    if promising(s, opts):
        return None
    s.screened = True
    s.significant = False
    s.refit = True
    return s


def reweighed(d: Diagnosis, f: Fit) -> tuple[Fit, dict[str, float] | None]:
    """``f`` refitted from where it stopped with each training signal weighed by its
    residual under the last fit, up to :attr:`~.state.Options.reweigh` times, as a single
    fit is (:func:`.fit_stage.reweighed`); stops once no value moves 5 % of its interval.
    Returns the fit and the scale it was made with (None: the stage's own).

    Why (stop 103, spent study 72900 case 72907, a lag of 0.316 s with a delay of 0.176 s):
    weighed by the residuals before any effect, the signals the pair fixes best weigh
    least, and the fit stopped at lag 0.457 s and delay 0.077 s from three starts, where
    the replay floor's units put the loss at about 3 x the truth's."""
    ev = d.ev
    scale = None
    for _ in range(d.opts.reweigh):
        ev_r, sc = weighed_by(d, f.ext, f.which)
        nf = fit(ev_r, f.candidates, f.which, x_start=f.x, max_nfev=REFIT_NFEV, probe=False)
        ev.replays += ev_r.replays
        ev.seconds += ev_r.seconds
        width = np.maximum(np.abs(f.ci_hi - f.ci_lo), 1e-12)
        moved = float((np.abs(nf.x - f.x) / width).max())
        d.say(
            f"{f.name}: fitted together again with the signals weighed by its residuals:"
            f" {', '.join(f'{x:.4g}' for x in nf.x)} (moved {moved:.2f} of its interval)"
        )
        f, scale = nf, sc
        if moved < 0.05:
            break
    return f, scale
