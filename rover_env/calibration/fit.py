"""Fitting candidate effects: bounded least squares on the replay residuals, with intervals.

Why ``scipy.optimize.least_squares`` (trust-region reflective, bounds, finite-difference
Jacobian) rather than ``mujoco.minimize``: the residual is a black box through the whole
replay (a Python tire layer, re-compiled models for configuration-level parameters), with
one to three parameters, so the optimiser's own cost is nil and what matters is a small,
controllable number of replays (``max_nfev``, ``diff_step`` per parameter, a cache of every
evaluated point) and mature bound handling. ``mujoco.minimize`` offers the same
Gauss–Newton idea but expects its Jacobian from MuJoCo-level finite differences of a
residual it owns, and gives no extra accuracy here.

Start (issue 16): no fit starts from an example magnitude. A one-parameter effect is
searched blind to its magnitude: "off" and a log-spaced ladder over the parameter's
physical range (:func:`rover_env.calibration.candidates.magnitude_ladder`), then a
bounded Brent search between the best rung's neighbours (in log-magnitude where the
bracket keeps one sign). Several parameters (a slope's tilt vector, a pair of effects)
start from the best ladder point (or the single fits) and are refined by least squares.

Intervals: the residuals inside a window are strongly correlated (one initial-state error
shifts all of them), so windows are the independent units. One parameter: block bootstrap
over training windows (windows resampled with replacement, the minimiser of the resampled
loss found on the per-window loss curves already evaluated, refined by a parabola), so no
replay is added. Several: the cluster-robust (sandwich) covariance with windows as
clusters and Student's t with (windows - 1) degrees of freedom. Either way an interval is
one-sided where the estimate sits at a bound ("c_rr < 0.004, 95 %"), and never narrower
than the search's own resolution: an interval of zero width would claim certainty.

Model form in the interval (stop 31): a one-parameter fit also finds the estimate each
signal group alone would give (driven wheels, free wheels, joints, pose; no extra replay).
On logs of another implementation they disagree beyond their noise (its joints put a lag
20 % lower than its driven wheels do), a bias the window bootstrap cannot see; their
between-group standard deviation (:func:`between_group_sd`) is added to the interval of
a named effect (:func:`widen_by_groups`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, stats

from rover_env.calibration.bootstrap import bootstrap_interval, bootstrap_over_forms, parabola_min
from rover_env.calibration.candidates import Candidate, Extensions, merge
from rover_env.calibration.evaluator import Evaluator
from rover_env.calibration.form_allowance import reach_floor, widen
from rover_env.calibration.replay import (
    JOINT_SIGNALS,
    POSE_SIGNALS,
    SIGNALS,
    WHEEL_SIGNALS,
    WindowResult,
)
from rover_env.calibration.residuals import window_slices
from rover_env.effects import CATALOGUE, EffectError
from rover_env.sim.simulator import SimulationError

Array = NDArray[np.float64]


@dataclass
class Fit:
    candidates: list[Candidate]
    x: Array
    ci_lo: Array
    ci_hi: Array
    se: Array
    cost: float
    """Sum of squared scaled residuals on the fitting windows."""
    nfev: int
    ext: Extensions
    seconds: float
    which: str
    bias: Array | None = None
    """Replay bias estimated on the model's own twins (diagnose), added to the interval."""
    sided: tuple[str, ...] = ()
    """Per free variable: "" two-sided, "upper" (estimate at the lower bound: only an upper
    95 % bound is known) or "lower"."""
    method: str = ""
    """How the intervals were found: "bootstrap" (windows) or "sandwich"."""
    tq: float = 1.96
    """Two-sided 95 % quantile the sandwich intervals used (Student's t, windows - 1)."""
    groups: dict[str, float] | None = None
    """One parameter: the estimate each signal group alone gives (:data:`SIGNAL_GROUPS`)."""
    between: float = 0.0
    """One parameter: the between-group standard deviation of those estimates beyond their
    own noise (random effects, DerSimonian-Laird), added to the interval (0: they agree)."""
    curve: tuple[Array, Array] | None = None
    """One parameter: the evaluated values and their per-window losses (values, windows)."""
    windows_ci: tuple[Array, Array] | None = None
    """One parameter: the interval before :attr:`between` widened it (sensor noise in it;
    None: nothing widened it): what ``diagnose --presence-on-windows`` judges "off" on."""
    form_pad: tuple[float, float] = (0.0, 0.0)
    """One parameter: how far forms moved the interval beyond the chosen form's own (below,
    above): the candidate's own forms the windows cannot reject, and the model's forms
    (:func:`~rover_env.calibration.diagnosis.form_judge.join_form_interval`); carried by fits that keep the forms."""
    noise_se: Array | None = None
    """Per free variable: the uncertainty the sensor noise alone puts on it, scatter and
    bias in quadrature, from simulated noise draws
    (:mod:`rover_env.calibration.noise_interval`; named effects only)."""
    allowance: dict[str, tuple[float, float]] = field(default_factory=dict)
    """Effect -> how far below and above its reported interval (its first parameter) the
    truth may sit for the model's form, each effect of a pair by its own
    (:mod:`rover_env.calibration.form_allowance`; named effects only)."""
    reach: dict[str, float] = field(default_factory=dict)
    """Effect -> how far beyond its value, away from "off", the truth may sit: the floor of
    the reported interval's far end (:func:`~rover_env.calibration.form_allowance.reach_floor`;
    named effects only)."""
    heading_known: bool = True
    """A slope's heading: False where the balance read it in frames fitted or left unread
    (``diagnose --frames fit``): the heading is then in the first log's frame, and which
    way the ground rises there is not known (block 54000)."""

    @property
    def name(self) -> str:
        return " + ".join(c.name for c in self.candidates)

    @property
    def k(self) -> int:
        return sum(c.k for c in self.candidates)

    def physical(
        self, allow: bool = True, groups: bool = True
    ) -> dict[str, dict[str, tuple[float, float, float]]]:
        """Effect -> parameter -> (value, 95 % low, 95 % high) in the effect's own terms
        (with the :attr:`allowance`, unless ``allow`` is False; without the signal groups'
        widening, :attr:`windows_ci`, if ``groups`` is False)."""
        out: dict[str, dict[str, tuple[float, float, float]]] = {}
        ci_lo, ci_hi = (
            self.windows_ci if not groups and self.windows_ci else (self.ci_lo, self.ci_hi)
        )
        i = 0
        for c in self.candidates:
            n = len(c.labels)
            x, lo, hi = self.x[i : i + n], ci_lo[i : i + n], ci_hi[i : i + n]
            if c.discrete:
                out[c.name] = {k: (v, v, v) for k, v in c.reported(x).items()}
            elif c.name == "slope":
                deg = math.hypot(x[0], x[1])
                se = self.se[i : i + n]
                g = np.array([x[0], x[1]]) / deg if deg > 0 else np.array([1.0, 0.0])
                s = float(math.sqrt(float(np.sum((g * se) ** 2))))
                head = c.reported(x)["heading_deg"]
                low = deg - self.tq * s
                out[c.name] = {
                    # A tilt cannot be negative: at zero only an upper bound is known.
                    "deg": (deg, max(0.0, low), deg + self.tq * s),
                    "heading_deg": (head, math.nan, math.nan),
                }
            elif c.shown is not None:
                k, v, a, b, _ = c.shown(float(x[0]), float(lo[0]), float(hi[0]), "")
                out[c.name] = {k: (v, a, b)}
            else:
                out[c.name] = {c.labels[0]: (float(x[0]), float(lo[0]), float(hi[0]))}
            i += n
        for c in self.candidates if allow else []:
            pad = self.allowance.get(c.name, (0.0, 0.0))
            reach = self.reach.get(c.name, 0.0)
            if (any(pad) or reach > 0.0) and not c.discrete:
                k, (v, a, b) = next(iter(out[c.name].items()))
                bounds = (0.0, math.inf) if c.name == "slope" else (c.lo[0], c.hi[0])
                a, b = widen(c.name, a, b, pad, (c.lo[0], c.hi[0])) if any(pad) else (a, b)
                off = CATALOGUE[c.name].params[0].off
                out[c.name][k] = (v, *reach_floor(v, a, b, reach, off, bounds))
        return out

    def sides(self) -> dict[str, dict[str, str]]:
        """Effect -> parameter -> "", "upper" or "lower" (see :attr:`sided`)."""
        out: dict[str, dict[str, str]] = {}
        i = 0
        for c in self.candidates:
            n = len(c.labels)
            sd = list(self.sided[i : i + n]) if len(self.sided) >= i + n else [""] * n
            if c.name == "slope":
                se = self.se[i : i + n]
                deg = math.hypot(self.x[i], self.x[i + 1])
                at0 = deg - self.tq * float(np.max(se)) <= 0.0
                out[c.name] = {"deg": "upper" if at0 else "", "heading_deg": ""}
            elif n and c.shown is not None:
                k, _, _, _, side = c.shown(self.x[i], self.ci_lo[i], self.ci_hi[i], sd[0])
                out[c.name] = {k: side}
            elif n:
                out[c.name] = {c.labels[0]: sd[0]}
            i += n
        return out


def read_fit(
    c: Candidate,
    value: tuple[float, float, float],
    seconds: float,
    method: str,
    nfev: int = 1,
) -> Fit:
    """A one-parameter fit of ``c`` read from a direct measurement (value, interval low,
    high), not optimised over windows: dead reckoning's radius, the reported torque's limit;
    ``nfev`` the evaluations it took."""
    x, lo, hi = value
    return Fit(
        candidates=[c],
        x=np.array([x]),
        ci_lo=np.array([lo]),
        ci_hi=np.array([hi]),
        se=np.array([(hi - lo) / 3.92]),
        cost=float("nan"),
        nfev=nfev,
        ext=to_ext([c], np.array([x])),
        seconds=seconds,
        which="train",
        method=method,
    )


def to_ext(cands: list[Candidate], x: Array) -> Extensions:
    """The extensions of candidates ``cands`` at their variables ``x`` (concatenated)."""
    parts, i = [], 0
    for c in cands:
        n = len(c.labels)
        parts.append(c.to_ext(x[i : i + n]))
        i += n
    return merge(*parts)


def _diff_step(c: Candidate, x0: Array, rel: float = 0.1) -> list[float]:
    """Finite-difference steps from where the fit starts and the range, not from examples:
    ``rel`` of the value (at least 0.2 % of the range)."""
    out = []
    for i, (lab, lo, hi) in enumerate(zip(c.labels, c.lo, c.hi, strict=True)):
        if lab == "delay":
            out.append(max(0.02, rel * abs(float(x0[i]))))  # the delay is quantised to 1 ms
        else:
            out.append(max(rel * abs(float(x0[i])), (hi - lo) * 0.002))
    return out


SIGNAL_GROUPS: dict[str, tuple[str, ...]] = {
    "driven wheels": WHEEL_SIGNALS[:4],
    "free wheels": WHEEL_SIGNALS[4:],
    "joints": JOINT_SIGNALS,
    "pose": POSE_SIGNALS,
}
"""Signals that see an effect through different parts of the model: the motors and their
wheels, the free wheels' rolling, the suspension's joints, the body's pose."""


_GROUP_COLUMNS = [[SIGNALS.index(s) for s in sigs] for sigs in SIGNAL_GROUPS.values()]


def group_losses(results: list[WindowResult], scale: dict[str, float]) -> Array:
    """Sum of squared scaled residuals per window and signal group, (windows, groups); a
    window's row sums to its :func:`~.residuals.window_losses` value."""
    sw = np.array([scale[s] for s in SIGNALS[:11]])
    sp = np.array([scale[s] for s in SIGNALS[11:]])
    out = np.zeros((len(results), len(SIGNAL_GROUPS)))
    for i, r in enumerate(results):
        per = np.concatenate(
            [np.sum((r.resid / sw) ** 2, axis=0), np.sum((r.pose_resid / sp) ** 2, axis=0)]
        )
        out[i] = [per[cols].sum() for cols in _GROUP_COLUMNS]
    return out


def between_group_sd(
    xs: Array,
    losses: Array,
    bracket: tuple[float, float] | None = None,
    n_boot: int = 200,
    seed: int = 0,
) -> tuple[dict[str, float], float]:
    """Per signal group: its own estimate; and the between-group standard deviation.

    ``losses[i, w, g]``: window w's loss in group g at ``xs[i]``. Each group's estimate is
    the minimiser of its own loss curve (parabola-refined), its standard error from a block
    bootstrap over windows. Groups that agree within their noise give 0; groups that pull
    the parameter apart (a model whose form differs from the logs' implementation: stop 31,
    the second generator's joints put a 0.19 s lag at 0.15 s while its driven wheels put it
    at 0.19 s) give the DerSimonian-Laird between-group standard deviation, a model-form
    term the window bootstrap cannot see. A group whose minimiser sits at the end of the
    evaluated points (it does not constrain the parameter there) is left out, and none is
    taken as more precise than the spacing of the points around its minimum. With
    ``bracket`` (the search's refined interval: the best ladder rung's neighbours) a group
    whose minimiser falls outside it is reported but not pooled: only the ladder's coarse
    rungs, a factor 3 apart, place it there (stop 31: on this project's own soil logs the
    free wheels' minimum fell 4.5 x from the others', between two rungs).
    """
    order = np.argsort(xs)
    x, L = np.asarray(xs, dtype=float)[order], np.asarray(losses, dtype=float)[order]
    rng = np.random.default_rng(seed)
    nw = L.shape[1]
    w = rng.multinomial(nw, np.full(nw, 1.0 / nw), size=n_boot).astype(float)
    est: dict[str, float] = {}
    var: list[float] = []
    vals: list[float] = []
    for g, name in enumerate(SIGNAL_GROUPS):
        curve = L[:, :, g].sum(axis=1)
        j = int(np.argmin(curve))
        if not np.any(curve > 0) or j in (0, len(x) - 1):
            continue
        e = parabola_min(x, curve, j)
        tb = w @ L[:, :, g].T
        xb = np.array([parabola_min(x, tb[b], int(np.argmin(tb[b]))) for b in range(n_boot)])
        # The minimiser is not located finer than the points around it (a group whose
        # minimum falls between two rungs of the ladder, a factor 3 apart, is not precise
        # however the windows are resampled).
        v = max(float(np.var(xb)), ((x[j + 1] - x[j - 1]) / 4) ** 2)
        est[name] = e
        if bracket is not None and not bracket[0] <= e <= bracket[1]:
            continue
        if v > 0:
            vals.append(e)
            var.append(v)
    if len(vals) < 2:
        return est, 0.0
    y, wi = np.array(vals), 1.0 / np.array(var)
    mean = float(np.sum(wi * y) / wi.sum())
    q = float(np.sum(wi * (y - mean) ** 2))
    c = float(wi.sum() - np.sum(wi**2) / wi.sum())
    tau2 = max(0.0, (q - (len(y) - 1)) / c) if c > 0 else 0.0
    return est, math.sqrt(tau2)


def widen_by_groups(f: Fit) -> None:
    """Add the between-group spread (:attr:`Fit.between`) to a one-parameter interval, in
    quadrature on each side as a one-sigma term (a one-sided interval keeps its bound).

    Diagnose applies it to the effects it names, after naming: whether an effect is there
    is judged on the windows (the groups can disagree on its size and all agree it is
    there); how large it is carries the model-form term.
    """
    if f.between <= 0 or f.x.size != 1 or (f.sided and f.sided[0]):
        return
    c = f.candidates[0]
    est = float(f.x[0])
    if f.windows_ci is None:
        f.windows_ci = (f.ci_lo.copy(), f.ci_hi.copy())
    f.ci_lo = np.array([max(c.lo[0], est - math.hypot(est - f.ci_lo[0], 1.96 * f.between))])
    f.ci_hi = np.array([min(c.hi[0], est + math.hypot(f.ci_hi[0] - est, 1.96 * f.between))])
    f.se = np.sqrt(f.se**2 + f.between**2)


STENCIL = 0.04
"""Relative step (in magnitude) of the two points a 1-D fit adds beside its best one."""


def _fit_1d(
    ev: Evaluator, c: Candidate, which: str, fixed: Extensions, refine: int, t0: float
) -> Fit:
    """Magnitude-blind search of one parameter: "off", the ladder, a bounded Brent search
    between the best rung's neighbours; intervals by block bootstrap over windows."""
    lo, hi, off = c.lo[0], c.hi[0], c.off[0]
    seen: dict[float, Array] = {}
    by_group: dict[float, Array] = {}
    size = 0

    def losses(v: float) -> Array:
        nonlocal size
        v = float(np.clip(v, lo, hi))
        if v not in seen:
            ext = merge(fixed, c.to_ext(np.array([v])))
            try:
                res = ev.run(ext, which)
                by_group[v] = group_losses(res, ev.scale)
                seen[v] = by_group[v].sum(axis=1)
                size = len(res)
            except (EffectError, SimulationError) as exc:
                ev.log(f"  {c.name}={v:.4g}: {exc}; treated as a very poor fit")
                seen[v] = np.full(size or len(ev.sets[which]), np.inf)
        return seen[v]

    def cost(v: float) -> float:
        return float(np.sum(losses(v)))

    pts = sorted({off, *(float(p[0]) for p in (c.ladder or ()))})
    for v in pts:
        cost(v)
    j = int(np.argmin([cost(v) for v in pts]))
    a = pts[j - 1] if j > 0 else pts[j]
    b = pts[j + 1] if j < len(pts) - 1 else pts[j]
    if refine > 0 and b > a:
        one_sign = (a - off) * (b - off) > 0
        if one_sign:  # in log-magnitude: the rungs are a factor 3 apart
            sgn = 1.0 if a > off else -1.0
            ua, ub = sorted((math.log(abs(a - off)), math.log(abs(b - off))))
            optimize.fminbound(
                lambda u: cost(off + sgn * math.exp(u)),
                ua,
                ub,
                xtol=0.02,
                maxfun=refine,
                disp=0,
            )
        else:
            optimize.fminbound(cost, a, b, xtol=0.002 * (hi - lo), maxfun=refine, disp=0)
        # Two points beside the best one (STENCIL in magnitude, or of the range across
        # zero): each signal group's own minimum is then located to a few per cent, so
        # groups that disagree (a model whose form differs from the logs') show as a
        # between-group spread instead of hiding under the search's coarse spacing (stop 37:
        # a second-generator delay, groups at 0.200-0.240 s with points 0.19, 0.21, 0.26).
        best = min((v for v in seen if np.all(np.isfinite(seen[v]))), key=cost, default=off)
        if best != off:
            if one_sign:
                for f in (math.exp(-STENCIL), math.exp(STENCIL)):
                    cost(off + (best - off) * f)
            else:
                for d in (-STENCIL, STENCIL):
                    cost(best + d * 0.05 * (hi - lo))
    xs = np.array(sorted(seen))
    L = np.array([seen[v] for v in xs])
    finite = np.all(np.isfinite(L), axis=1)
    xs, L = xs[finite], L[finite]
    est, ci_lo, ci_hi, side = bootstrap_interval(xs, L, lo, hi, off)
    gx = np.array([v for v in xs if v in by_group])
    groups, between = between_group_sd(gx, np.array([by_group[v] for v in gx]), (a, b))
    # The reported value is an evaluated point when the parabola adds nothing.
    x = np.array([est])
    ext = merge(fixed, c.to_ext(x))
    r = ev.vector(ext, which)
    se = np.array([(ci_hi - ci_lo) / (2 * 1.96)])
    return Fit(
        [c],
        x,
        np.array([ci_lo]),
        np.array([ci_hi]),
        se,
        float(r @ r),
        len(seen) + 1,
        ext,
        time.perf_counter() - t0,
        which,
        sided=(side,),
        method="bootstrap",
        groups=groups,
        between=between,
        curve=(xs, L),
    )


def stack_fits(held: Fit, added: Fit) -> Fit:
    """One fit of ``held``'s and ``added``'s candidates, ``added`` fitted with ``held`` held
    at its values (``fit(..., hold=held.ext)``): forward selection stage by stage. Each
    keeps its own interval (already widened for its forms, so nothing is carried); the cost
    and replays are ``added``'s (its ``ext`` has both)."""

    def sides(f: Fit) -> tuple[str, ...]:
        n = int(f.x.size)
        return f.sided if len(f.sided) == n else ("",) * n

    return Fit(
        [*held.candidates, *added.candidates],
        np.concatenate([held.x, added.x]),
        np.concatenate([held.ci_lo, added.ci_lo]),
        np.concatenate([held.ci_hi, added.ci_hi]),
        np.concatenate([held.se, added.se]),
        added.cost,
        added.nfev,
        added.ext,
        added.seconds,
        added.which,
        sided=sides(held) + sides(added),
        method=added.method,
        tq=max(held.tq, added.tq),
    )


def carry_form_pad(f: Fit, singles: list[Fit]) -> None:
    """Widen ``f``'s interval of each variable of a candidate whose single fit (one of
    ``singles``) was widened for a form (its own soil form, or the model's forms:
    :func:`~rover_env.calibration.diagnosis.form_judge.join_form_interval`) by that fit's :attr:`Fit.form_pad`: a fit with more effects
    keeps the forms, and knows them no better than the single fit did."""
    i = 0
    for c in f.candidates:
        n = len(c.labels)
        src = next((s for s in singles if [d.name for d in s.candidates] == [c.name]), None)
        if src is not None and n == 1 and any(src.form_pad):
            f.ci_lo[i] = max(c.lo[0], f.ci_lo[i] - src.form_pad[0])
            f.ci_hi[i] = min(c.hi[0], f.ci_hi[i] + src.form_pad[1])
            f.se[i] = max(f.se[i], (f.ci_hi[i] - f.ci_lo[i]) / (2 * f.tq))
        i += n


FORMS_FITTED = 2
"""Forms of a candidate searched in full: the best by the screen (:func:`_fit_forms`)."""


def _curve_cost(f: Fit, x: float) -> float | None:
    """The summed loss of ``f``'s search at ``x``, if it evaluated that point."""
    if f.curve is None:
        return None
    xs, L = f.curve
    hit = np.flatnonzero(xs == x)
    return float(L[hit[0]].sum()) if hit.size else None


def _screen_forms(
    ev: Evaluator, c: Candidate, which: str, fixed: Extensions, first: Fit
) -> tuple[dict[str, float], float, float | None]:
    """Every form of ``c`` at the first form's best point and at the ladder's middle rung,
    each form's lower cost of the two (one rung when they coincide, or when the first form is
    best at "off"). Returns the forms' costs, the first rung, and the cost at "off" (None when
    the first form's search did not reach it).

    Why the middle rung too (stop 133): a form's basin can lie far from the first form's.
    Dry sand 54917 (k_phi 2.1e6): on the training drives the mars-sand forms were best near
    1/k_phi 0.03 and the regolith constants, screened there, came third and fourth and were
    never searched; on the screen's half of the windows they were best at 1.1-1.8, a quarter
    lower in cost, and a slope was named instead of the soil."""
    xs0, l0 = first.curve if first.curve is not None else (np.zeros(0), np.zeros((0, 0)))
    ladder = [float(p[0]) for p in (c.ladder or ())]
    best = float(xs0[int(np.argmin(l0.sum(axis=1)))]) if xs0.size else c.off[0]
    mid = ladder[len(ladder) // 2] if ladder else best
    rung = mid if best == c.off[0] else best
    rungs = [rung, mid] if ev.screen_middle and mid != rung else [rung]
    out: dict[str, float] = {}
    for label, _ in c.forms:
        costs = []
        for x in rungs:
            if label == c.forms[0][0]:
                v = _curve_cost(first, x)
                costs.append(math.inf if v is None else v)
                continue
            try:
                res = ev.run(merge(fixed, c.with_form(label).to_ext(np.array([x]))), which)
                costs.append(float(group_losses(res, ev.scale).sum()))
            except (EffectError, SimulationError) as exc:
                ev.log(f"  {c.name} ({label}) at {x:.4g}: {exc}; screened out")
                costs.append(math.inf)
        out[label] = min(costs)
    return out, rung, _curve_cost(first, c.off[0])


def _fit_forms(
    ev: Evaluator, c: Candidate, which: str, fixed: Extensions, refine: int, t0: float
) -> Fit:
    """:func:`_fit_1d` in the first of ``c``'s forms (:attr:`Candidate.forms`), every other
    form screened at two rungs (:func:`_screen_forms`), and the :data:`FORMS_FITTED` best by
    the screen searched in full; the form whose refined minimum fits best is kept. Its
    interval is its own block bootstrap joined with the bootstrap over the searched forms
    (:func:`bootstrap_over_forms`); how far the latter reaches beyond the former is kept as
    :attr:`Fit.form_pad`. The choice costs the fit one parameter (:attr:`Candidate.k`).

    Until stop 33 the form was chosen by its best ladder rung, before any refinement: the
    rungs are a factor 3 apart, so a flat form beat a sharp one whose minimum fell between
    rungs (own soil, k_phi 4.4e6: the truth's form reaches 4119 at 4e6, the short-relaxation
    form 4732; by rungs the latter won, and k_phi was fitted at 2.4e6 [1.5e6, 2.8e6]).
    Until stop 55 a first form best at "off" ended the search (hard ground: every form is
    the same model there), and every form was otherwise searched in full (4 soil forms, 48
    replays on a clean case). With the soil's constants among the forms, the first form can
    be best at "off" where another is not (the independent generator's regolith under the
    mars-sand constants), and a full search of seven forms would cost 7 x."""
    first = _fit_1d(ev, c.with_form(c.forms[0][0]), which, fixed, refine, t0)
    screen, rung, off_cost = _screen_forms(ev, c, which, fixed, first)
    order = sorted(screen, key=lambda lab: screen[lab])
    shown = ", ".join(f"{lab} {screen[lab]:.4g}" for lab in order)
    if off_cost is not None and screen[order[0]] >= off_cost:
        # Screened: no form beats "off" at the rung where the first form does best.
        ev.log(f"  {c.name}: best at off ({off_cost:.4g}) in every form at {rung:.3g} ({shown})")
        return first
    keep = order[:FORMS_FITTED]
    fits = [
        first if lab == c.forms[0][0] else _fit_1d(ev, c.with_form(lab), which, fixed, refine, t0)
        for lab in keep
    ]
    curves = [f.curve for f in fits if f.curve is not None]
    if len(curves) != len(fits):
        return min(fits, key=lambda f: f.cost)
    _, lo, hi, side, best = bootstrap_over_forms(curves, c.lo[0], c.hi[0], c.off[0])
    f = fits[best]
    # The chosen form's own interval, widened to where the other forms take the resamples
    # they win: a resample's best form need not contain the chosen form's tails (stop 31's
    # own soil 12009, 5.56e6: 4.7e6 [4.0e6, 9.9e6] in one form; over the forms alone the
    # upper bound fell to 5.39e6, the forms that win those resamples put the soil softer).
    lo, hi = min(lo, float(f.ci_lo[0])), max(hi, float(f.ci_hi[0]))
    if side != (f.sided[0] if f.sided else ""):
        side = ""  # a bound reached in one view only: the widened interval is two-sided
    f.form_pad = (max(float(f.ci_lo[0]) - lo, 0.0), max(hi - float(f.ci_hi[0]), 0.0))
    ev.log(
        f"  {c.name}: form {keep[best]!r} (screened at {rung:.3g}: {shown}; searched: "
        + ", ".join(
            f"{lab} {min(fi.curve[1].sum(axis=1)):.4g}"
            for lab, fi in zip(keep, fits, strict=True)
            if fi.curve is not None
        )
        + ")"
    )
    # The best form's own fit already sits at ``est`` (the same curve, the same parabola).
    f.ci_lo, f.ci_hi = np.array([lo]), np.array([hi])
    f.se = np.array([(hi - lo) / (2 * 1.96)])
    f.sided = (side,)
    f.nfev = sum(fi.nfev for fi in fits) + len(screen) - 1
    f.seconds = time.perf_counter() - t0
    return f


def fit(
    ev: Evaluator,
    cands: list[Candidate],
    which: str,
    x_start: Array | None = None,
    max_nfev: int = 6,
    probe: bool = True,
    hold: Extensions | None = None,
    central: bool = False,
    coarse: bool = False,
) -> Fit:
    """Bounded least squares of the candidates' variables on window set ``which``.

    ``hold``: effects kept as they are beside the candidates (an effect already chosen); the
    fit's ``ext`` includes them, its variables do not. ``central``: the Jacobian by central
    differences 2 % of the value wide (twice the replays), for finishing a fit: the search's
    forward differences, 10 % of the value, put the fixed point of the iteration half a
    step off where the residuals' curvature is large (a slope's tilt: 0.3 deg low at 7 deg).
    ``coarse``: a screen's search (:attr:`~.diagnosis.state.Options.screen_coarse`): one
    parameter is searched on its ladder alone, its estimate the parabola through the best
    rungs (no Brent search, no stencil); several parameters take half ``max_nfev``."""
    t0 = time.perf_counter()
    held = hold or {}
    if all(c.discrete for c in cands):
        ext = merge(held, to_ext(cands, np.zeros(0)))
        r = ev.vector(ext, which)
        z = np.zeros(0)
        return Fit(cands, z, z, z, z, float(r @ r), 1, ext, time.perf_counter() - t0, which)
    free = [c for c in cands if not c.discrete]
    fixed = merge(held, *[c.to_ext(np.zeros(0)) for c in cands if c.discrete])
    lo = np.concatenate([c.lo for c in free])
    hi = np.concatenate([c.hi for c in free])
    x0 = np.concatenate([c.off for c in free]) if x_start is None else np.array(x_start)
    nfev = 0
    size = 0

    def fun(x: Array) -> Array:
        nonlocal nfev, size
        nfev += 1
        try:
            r = ev.vector(merge(fixed, to_ext(free, x)), which)
        except (EffectError, SimulationError) as exc:
            # A value the model cannot take (or that makes it unstable): a wall, not a crash.
            ev.log(f"  {to_ext(free, x)}: {exc}; treated as a very poor fit")
            return np.full(size or ev.vector(fixed, which).size, 1e3)
        size = r.size
        return r

    if probe and x_start is None and len(free) == 1 and len(free[0].labels) == 1:
        refine = 0 if coarse else max(2, max_nfev + 1)
        if free[0].forms:
            return _fit_forms(ev, free[0], which, fixed, refine, t0)
        return _fit_1d(ev, free[0], which, fixed, refine=refine, t0=t0)
    if probe and x_start is None and len(free) == 1 and free[0].ladder:
        # Several parameters of one effect (a slope's tilt vector): the best of "off" and
        # the magnitude-blind ladder starts the local fit.
        best = fun(x0)
        best_cost = float(best @ best)
        for trial in free[0].ladder:
            xt = np.clip(np.array(trial, dtype=float), lo, hi)
            r1 = fun(xt)
            if float(r1 @ r1) < best_cost:
                best_cost, x0 = float(r1 @ r1), xt
    x0 = np.clip(x0, lo, hi)
    steps: list[float] = []
    i = 0
    for c in free:
        steps += _diff_step(c, x0[i : i + len(c.labels)], 0.02 if central else 0.1)
        i += len(c.labels)
    diff = np.array(steps)
    # least_squares' step is diff_step * max(1, |x|): the absolute steps above, made
    # relative. (Until stop 38 they were passed as they are, so a slope's tilt of 6.7 deg
    # was differenced over 4.4 deg and its fit stopped 0.6 deg short of the minimum.)
    res = optimize.least_squares(
        fun,
        x0,
        bounds=(lo, hi),
        jac="3-point" if central else "2-point",
        diff_step=diff / np.maximum(1.0, np.abs(x0)),
        x_scale=diff * (50 if central else 10),
        max_nfev=max(1, max_nfev // 2) if coarse else max_nfev,
        method="trf",
    )
    x = res.x
    r = res.fun
    results = ev.run(merge(fixed, to_ext(free, x)), which)
    offs = np.concatenate([c.off for c in free])
    ci_lo, ci_hi, se, sided, tq = _sandwich_interval(x, r, res.jac, results, lo, hi, offs)
    # Pad the free-variable arrays with the discrete candidates' (empty) slots in order.
    xs, los, his, ses = [], [], [], []
    i = 0
    for c in cands:
        n = len(c.labels)
        xs.append(x[i : i + n])
        los.append(ci_lo[i : i + n])
        his.append(ci_hi[i : i + n])
        ses.append(se[i : i + n])
        i += n
    return Fit(
        cands,
        np.concatenate(xs),
        np.concatenate(los),
        np.concatenate(his),
        np.concatenate(ses),
        float(r @ r),
        nfev,
        merge(fixed, to_ext(free, x)),
        time.perf_counter() - t0,
        which,
        sided=tuple(sided),
        method="sandwich",
        tq=tq,
    )


def _sandwich_interval(
    x: Array,
    r: Array,
    jac: Array,
    results: list[WindowResult],
    lo: Array,
    hi: Array,
    offs: Array,
) -> tuple[Array, Array, Array, list[str], float]:
    """(95 % low, high, standard error, side, t quantile) of a least-squares fit at ``x``:
    the cluster-robust sandwich covariance with windows as clusters and Student's t, never
    narrower than the search's resolution, one-sided where ``x`` sits at a bound."""
    slices = window_slices(results)
    g = len(slices)
    bread = np.linalg.pinv(jac.T @ jac)
    meat = np.zeros((len(x), len(x)))
    for s in slices:
        u = jac[s].T @ r[s]
        meat += np.outer(u, u)
    cov = bread @ meat @ bread * (g / max(g - 1, 1))
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    tq = float(stats.t.ppf(0.975, max(g - 1, 1)))
    res_ = np.maximum(0.02 * np.abs(x - offs), 0.002 * (hi - lo))
    se = np.maximum(se, res_ / tq)  # never narrower than the search's resolution
    ci_lo, ci_hi = x - tq * se, x + tq * se
    sided = []
    for k in range(len(x)):
        t1 = float(stats.t.ppf(0.95, max(g - 1, 1)))
        if x[k] <= lo[k] + res_[k] or (offs[k] == lo[k] and x[k] <= offs[k] + res_[k]):
            ci_lo[k], ci_hi[k] = lo[k], max(x[k] + t1 * se[k], x[k] + res_[k])
            sided.append("upper")
        elif x[k] >= hi[k] - res_[k] or (offs[k] == hi[k] and x[k] >= offs[k] - res_[k]):
            ci_lo[k], ci_hi[k] = min(x[k] - t1 * se[k], x[k] - res_[k]), hi[k]
            sided.append("lower")
        else:
            sided.append("")
    return ci_lo, ci_hi, se, sided, tq


def information_criteria(sum_log_ratio: float, n: int, k: int) -> tuple[float, float]:
    """(delta AIC, delta BIC) against the reference model, windows as the n observations.

    ``sum_log_ratio`` is the sum over windows of log(loss / reference loss): the change of
    -2 log likelihood when each window has its own Gaussian error scale (profiled out).
    """
    return sum_log_ratio + 2 * k, sum_log_ratio + k * math.log(max(n, 2))


def signal_change(
    ev: Evaluator, ext_a: Extensions, ext_b: Extensions, which: str, floor: dict[str, float]
) -> dict[str, float]:
    """Per signal: RMS of the change of the replayed signal between two models, in units of
    that signal's replay floor (each signal weighed by its own noise)."""
    ra, rb = ev.run(ext_a, which), ev.run(ext_b, which)
    d_w = np.concatenate([a.resid - b.resid for a, b in zip(ra, rb, strict=True)])
    d_p = np.concatenate([a.pose_resid - b.pose_resid for a, b in zip(ra, rb, strict=True)])
    out = {}
    for j, s in enumerate(SIGNALS):
        col = d_w[:, j] if j < 11 else d_p[:, j - 11]
        col = col[np.isfinite(col)]
        out[s] = float(np.sqrt(np.mean(col**2)) / floor[s]) if col.size else 0.0
    return out
