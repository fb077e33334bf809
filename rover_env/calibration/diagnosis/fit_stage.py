"""Stage 4, fit: every candidate effect of the catalogue fitted on the training windows and
scored on the held-out ones; and the fits that finish a named effect's interval.

Owns a candidate's fit from search to score: the magnitude-blind fit
(:mod:`rover_env.calibration.fit`), the reweighed refits (:attr:`Options.reweigh`), its noise
threshold (:func:`noise_threshold`), the held-out window test and, when no candidate passes
it, the noise-floor test; for the effects the selection names, the replay's bias in the
interval (:func:`bias_correct`) and the finished fit of several parameters (:func:`polish`).
Why here: each is a fit of one candidate set on one window set.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import optimize

from rover_env.calibration import residuals as rs
from rover_env.calibration.candidates import (
    Candidate,
    Extensions,
    catalogue,
    merge,
    with_torque_forms,
)
from rover_env.calibration.diagnosis.judge import (
    better_worse,
    fit_budget,
    floor_test,
    fmt_phys,
    magnitude,
    passes_window_test,
    plugin_capable,
    score,
    screened,
    slope_axis,
    unexplained,
)
from rover_env.calibration.diagnosis.parallel import map_candidates
from rover_env.calibration.diagnosis.state import Diagnosis, Scored
from rover_env.calibration.fit import Evaluator, fit, signal_change
from rover_env.calibration.form_allowance import naming_bar
from rover_env.calibration.replay import ReplaySettings, WindowResult, prepare
from rover_env.effects import EffectError
from rover_env.sim.simulator import SimulationError


def fit_candidates(d: Diagnosis) -> None:
    """Sets the candidates, the baseline's held-out losses and the ranked scored fits."""
    d.cands = [c for c in catalogue(d.opts.candidates) if c.name not in d.base.extensions]
    if d.opts.torque_forms:
        d.cands = [with_torque_forms(c) for c in d.cands]
    d.held0 = rs.window_losses(d.base_held, d.noise)  # held-out: in units of the replay floor
    scored = map_candidates(lambda c: fit_one(d, c), lambda s: report(d, s), d.cands, d.ev, d.opts)
    d.ranked = sorted(scored, key=lambda s: -s.gain)
    base_left = unexplained(d.table_held_before, d.noise)
    if not any(s.significant for s in d.ranked) and base_left:
        d.say(
            f"no candidate passes the window test; held-out above the floor: {', '.join(base_left)}"
        )
        for s in d.ranked:
            floor_test(d, s, base_left, d.noise, {})


def fit_one(d: Diagnosis, c: Candidate) -> Scored:
    """One candidate fitted alone, scored against the model without effects."""
    opts = d.opts
    # Numpy-only effects cost ~20x a plugin replay: a continuous one is fitted on a
    # subset of the training windows; a switch needs one replay, on all of them. The
    # others are screened on that subset first (Options.screen).
    which = "train" if plugin_capable(c) or c.discrete else "train_sub"

    def fit_at(w: str, coarse: bool) -> Scored:
        f = fit(d.ev, [c], w, max_nfev=fit_budget([c], opts), coarse=coarse)
        s = score(d, f, d.held0, {})
        s.threshold = noise_threshold(d.ev, c, w, d.noise)
        s.detectable = detection_limit(d.ev, c, w, d.noise)
        s.nameable = naming_bar(c.name, s.detectable, d.allowance)
        return s

    s = screened(fit_at, which, c.discrete, opts)
    if opts.reweigh > 0 and s.fit.x.size and s.d_bic < 0 and not s.screened:
        s = reweighed(d, s, opts.reweigh)  # training only: not held-out
    s.significant = passes_window_test(s, opts) and not s.screened
    s.test = "windows" if s.significant else ""
    return s


def weighed_by(d: Diagnosis, ext: Extensions, which: str) -> tuple[Evaluator, dict[str, float]]:
    """An evaluator sharing ``d.ev``'s cache, each signal weighed by its residual on window
    set ``which`` under ``ext`` (at least its floor), with its own replay count; and that
    scale. What a refit weighed by what a model leaves fits with (:attr:`Options.reweigh`,
    forward selection's partners, :mod:`.shared`)."""
    sc = rs.signal_scale(rs.stack(d.ev.run(ext, which), d.prepared), d.noise)
    return replace(d.ev, scale=sc, replays=0, seconds=0.0), sc


def reweighed(d: Diagnosis, w: Scored, passes: int) -> Scored:
    """``w`` refitted (magnitude-blind, as before) with each training signal weighed by
    its residual under the last fit (:attr:`Options.reweigh`), then judged again by the
    same held-out tests. Stops once the value moves less than 5 % of its interval."""
    before = {e: {k: list(v) for k, v in p.items()} for e, p in w.fit.physical().items()}
    cur = w
    for _ in range(passes):
        ev_r, sc = weighed_by(d, cur.fit.ext, cur.fit.which)
        cands_r = cur.fit.candidates
        f = fit(ev_r, cands_r, cur.fit.which, max_nfev=fit_budget(cands_r, d.opts))
        ns = score(d, f, d.held0, {})
        ns.fit_scale, ns.threshold, ns.reweighed_from = sc, cur.threshold, before
        ns.detectable = cur.detectable  # a property of the drives and the model, not the fit
        ns.nameable = cur.nameable
        width = np.maximum(np.abs(cur.fit.ci_hi - cur.fit.ci_lo), 1e-12)
        moved = float((np.abs(ns.fit.x - cur.fit.x) / width).max())
        d.say(
            f"{w.fit.name}: refitted with the signals weighed by its residuals:"
            f" {fmt_phys(ns.fit)} (moved {moved:.2f} of its interval)"
        )
        cur = ns
        if moved < 0.05:
            break
    return cur


def report(d: Diagnosis, s: Scored) -> None:
    """One candidate's progress line."""
    f = s.fit
    d.say(
        f"{f.name:24s} {fmt_phys(f)}  held-out {better_worse(s.gain)}  p={s.p:.2g}"
        f"  dBIC={s.d_bic:+.1f}  ({f.nfev} replays, {f.seconds:.1f}s)"
    )


def polish(ev: Evaluator, s: Scored, max_nfev: int) -> bool:
    """Finish ``s``'s fit when it is one effect of several parameters (a slope's tilt
    vector): bounded least squares from where its search stopped, up to ``max_nfev``
    evaluations, in ``ev``'s scale (the one it was fitted with). Kept only if it lowers the
    training cost; True if it did. Diagnose applies it to the named effects: whether an
    effect is there was judged on the search's fit; how large it is, on the finished one."""
    f = s.fit
    free = [c for c in f.candidates if not c.discrete]
    if max_nfev <= 0 or len(free) != 1 or len(free[0].labels) < 2 or f.x.size == 0:
        return False
    nf = fit(ev, f.candidates, f.which, x_start=f.x, max_nfev=max_nfev, probe=False, central=True)
    if not nf.cost < f.cost:
        return False
    nf.seconds += f.seconds
    nf.nfev += f.nfev
    s.fit = nf
    return True


def bias_correct(
    ev: Evaluator, s: Scored, sensor_noise: dict[str, float], st: ReplaySettings
) -> None:
    """Widen the intervals by the bias the replay itself may put on the fitted values.

    The window initialisation is not exact (e.g. segment 3's speed from its free wheels
    assumes no slip), which can pull a fit a few per cent off. The fitted model's own twins
    of the training drives (same commands, same sensor noise) are fitted the same way; the
    difference from the value they were made with estimates that bias. It is *not*
    subtracted: learnt on this project's own replays it moved estimates from logs of another
    implementation away from their truth (issue 16); it widens the interval instead (added
    in quadrature to each side's half-width, as a one-sigma term).
    """
    f = s.fit
    if f.x.size == 0:
        return
    which = f.which
    cfg = ev.config(f.ext)
    used = {w.log_index for w in ev.sets[which]}
    rng = np.random.default_rng(1)
    res = rs.resolutions(ev.logs)
    states = rs.twins_of(ev.logs, cfg, used)
    twins = [
        prepare(rs.twin_sensed(p, states[i], sensor_noise, res, rng), ev.base, p.name + " twin", st)
        if i in used
        else p
        for i, p in enumerate(ev.logs)
    ]
    tev = Evaluator(
        ev.base, st, twins, {which: ev.sets[which]}, scale=ev.scale, screen_middle=ev.screen_middle
    )
    ft = fit(tev, f.candidates, which, x_start=f.x, max_nfev=3, probe=False)
    ev.replays += tev.replays
    ev.seconds += tev.seconds
    bias = ft.x - f.x
    free = [c for c in f.candidates if not c.discrete]
    lo = np.concatenate([c.lo for c in free])
    hi = np.concatenate([c.hi for c in free])
    extra = 1.96 * np.abs(bias)
    h_lo = np.sqrt((f.x - f.ci_lo) ** 2 + extra**2)
    h_hi = np.sqrt((f.ci_hi - f.x) ** 2 + extra**2)
    sided = f.sided or ("",) * f.x.size
    f.bias = bias
    f.se = np.sqrt(f.se**2 + bias**2)
    f.ci_lo = np.where([sd == "upper" for sd in sided], f.ci_lo, np.maximum(f.x - h_lo, lo))
    f.ci_hi = np.where([sd == "lower" for sd in sided], f.ci_hi, np.minimum(f.x + h_hi, hi))


def _ladder_magnitudes(c: Candidate) -> list[tuple[np.ndarray, str, float]]:
    """Each ladder rung of ``c`` with its side of "off" ("+", "-"; a slope: "deg") and its
    magnitude (distance from "off"; a slope's tilt in degrees)."""
    return [(x, *magnitude(c, x)) for x in (np.array(p, dtype=float) for p in c.ladder or ())]


def _window_change(a: WindowResult, b: WindowResult, scale: dict[str, float]) -> float:
    """One window's squared change between two replays, in the signal scale ``scale``."""
    return float(np.sum((rs.residual_vector([a], scale) - rs.residual_vector([b], scale)) ** 2))


def _price_gap(f: float, q: np.ndarray, price: float) -> float:
    return float(np.sum(np.log1p(f * q))) - price


def detection_limit(
    ev: Evaluator,
    c: Candidate,
    which: str,
    scale: dict[str, float],
    hold: Extensions | None = None,
) -> dict[str, float]:
    """Per side of "off": the smallest magnitude of the effect that, were it in the logs,
    would pay its training BIC price against the residual the logs leave now, the losses
    in ``scale``, the units the BIC is judged in (:func:`.judge.training_criteria`).

    From the ladder's replays (in the cache after the fit): at rung m the effect changes
    window w's replay by E_w (its loss in ``scale``); on logs that hold it, the
    fitted effect would take the window's loss from about R_w + E_w to R_w, R_w the model's
    loss on that window now (the form it lacks, the noise). The BIC falls once
    sum_w log(1 + E_w / R_w) exceeds k ln n; E grows as m^2 near "off", so each rung's E,
    scaled by the factor f that makes that sum the price, gives m sqrt(f), and the rung
    whose sum is nearest the price decides (a slope: "deg", the median over its directions,
    and each direction alone, "x+", "x-", "y+", "y-", for :func:`.judge.limit_at`).
    Why (stop 59): the noise threshold measures an effect against the replay floor, what a
    perfect model leaves; against another implementation's
    logs the model leaves 4-20 x that, and an effect 3 x its noise threshold can be
    invisible (block 47700's torque cut of -0.61, case 47721: threshold 0.18, the cut
    itself bettering the training windows by 0.1 in sum of log ratios, against a price of
    3.5). A name must reach it (:attr:`.state.Options.name_above_limit`, stop 73).

    ``hold``: effects kept beside ``c`` (a winner a partner is sought beside), so that
    "now" is the model with them: the limit of a second effect (:func:`.select.partner_limits`).
    """
    if c.discrete or not c.ladder:
        return {}
    held = hold or {}
    ref = ev.run(merge(held, c.to_ext(np.array(c.off))), which)
    r_ref = rs.window_losses(ref, scale)
    r_ref = np.maximum(r_ref, 1e-12 * max(float(np.mean(r_ref)), 1e-300))
    price = len(c.labels) * math.log(max(len(ref), 2))
    groups: dict[str, list[tuple[float, float, float]]] = {}
    paid: dict[str, list[tuple[float, float]]] = {}  # (rung, its sum over the price)
    for x, key, mag in _ladder_magnitudes(c):
        try:
            res = ev.run(merge(held, c.to_ext(x)), which)
        except (EffectError, SimulationError):
            continue
        e = np.array([_window_change(a, b, scale) for a, b in zip(res, ref, strict=True)])
        q = np.nan_to_num(e) / r_ref
        d = float(np.sum(np.log1p(q)))
        keys = [key, slope_axis(x)] if c.name == "slope" else [key]
        for k in keys:
            paid.setdefault(k, []).append((mag, d / price))
        if d > 0:
            # E_w scales as m^2: the factor on this rung's E whose sum pays the price exactly
            if _price_gap(1e12, q, price) <= 0:  # a change too small to ever pay the price
                continue
            f = optimize.brentq(_price_gap, 1e-12, 1e12, args=(q, price))
            for k in keys:
                groups.setdefault(k, []).append((mag, mag * math.sqrt(f), abs(math.log(d / price))))
    out = {}
    for key, pts in groups.items():
        # Kept between the rungs that bracket the price (an effect that acts only past a
        # point, as a torque limit: :func:`crossing`); a slope's four directions per rung
        # are not one response ("deg": their median), each axis ("x+" ...) is.
        mag0 = min(pts, key=lambda q: q[2])[0]  # the rung nearest the price
        est = float(np.median([est for mag, est, _ in pts if mag == mag0]))
        out[key] = est if key == "deg" else within_bracket(est, paid[key])
    return out


def noise_threshold(
    ev: Evaluator, c: Candidate, which: str, floor: dict[str, float]
) -> dict[str, float]:
    """Magnitude at which the effect moves its most sensitive signal by one replay floor.

    Per side of "off" ("+": above, "-": below; a slope: "deg"), from the ladder's replays
    (already in the cache after the fit): each rung k gives m_k / S_k, S_k the largest
    per-signal RMS change against "off" in floor units; the rung whose S_k is nearest 1
    decides (linear response near the threshold), kept between the two rungs that bracket
    S = 1 (:func:`crossing`). An effect must exceed this to be visible at all on these
    drives; the benchmark's detection curves are drawn against it.
    """
    if c.discrete or not c.ladder:
        return {}
    off = c.to_ext(np.array(c.off))
    groups: dict[str, list[tuple[float, float]]] = {}
    for x, key, mag in _ladder_magnitudes(c):
        try:
            s = max(signal_change(ev, c.to_ext(x), off, which, floor).values())
        except (EffectError, SimulationError):
            continue
        groups.setdefault(key, []).append((mag, s))
    out = {}
    for key, pts in groups.items():
        moved = [q for q in pts if q[1] > 0]
        if not moved:
            continue
        if c.name == "slope":  # four directions per magnitude: the median of their estimates
            mag, _ = min(moved, key=lambda q: abs(math.log(q[1])))
            out[key] = float(np.median([m / v for m, v in moved if m == mag]))
        else:
            out[key] = crossing(pts)
    return out


def crossing(pts: list[tuple[float, float]]) -> float:
    """The magnitude m at which a response S(m) reaches 1, from rungs ``(m, S)`` (S >= 0, at
    least one > 0): ``m / S`` at the rung whose S is nearest 1 (a response linear near the
    crossing), kept within the rungs that bracket the crossing (:func:`within_bracket`).

    Why the bracket (stop 71): a torque limit moves nothing until the drive reaches it,
    then much; the rung nearest S = 1 can be the first past the limit, and m / S from it put
    the threshold below rungs that moved nothing (spent case 51221: threshold 0.056 while a
    cut of 0.27 moved no signal by more than 0.03 floor).
    """
    mag, s = min((q for q in pts if q[1] > 0), key=lambda q: abs(math.log(q[1])))
    return within_bracket(mag / s, pts)


def within_bracket(est: float, pts: list[tuple[float, float]]) -> float:
    """``est`` if it lies between the smallest rung with S >= 1 and the largest rung below
    it (or no two rungs bracket S = 1), else the crossing interpolated between them
    (log-log, exact for a power law; linear in m when the lower rung did not move at all).
    An estimate outside its bracket contradicts a rung that was replayed."""
    visible = sorted(q for q in pts if q[1] >= 1.0)
    below = [q for q in pts if visible and q[0] < visible[0][0] and q[1] < 1.0]
    if not below:
        return est
    (mb, sb), (ma, sa) = visible[0], max(below)
    if ma <= est <= mb:
        return est
    if sa > 0:
        u = -math.log(sa) / (math.log(sb) - math.log(sa))
        return math.exp(math.log(ma) + u * (math.log(mb) - math.log(ma)))
    return ma + (mb - ma) * (1.0 - sa) / (sb - sa)
