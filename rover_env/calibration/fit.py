"""Fitting candidate effects: bounded least squares on the replay residuals, with intervals.

Why ``scipy.optimize.least_squares`` (trust-region reflective, bounds, finite-difference
Jacobian) rather than ``mujoco.minimize``: the residual is a black box through the whole
replay (a Python tire layer, re-compiled models for configuration-level parameters), with
one to three parameters, so the optimiser's own cost is nil and what matters is a small,
controllable number of replays (``max_nfev``, ``diff_step`` per parameter, a cache of every
evaluated point) and mature bound handling. ``mujoco.minimize`` offers the same
Gauss–Newton idea but expects its Jacobian from MuJoCo-level finite differences of a
residual it owns, and gives no extra accuracy here.

Intervals: the residuals inside a window are strongly correlated (one initial-state error
shifts all of them), so the naive ``s^2 (J^T J)^-1`` is far too narrow. The covariance is
the cluster-robust (sandwich) estimate with windows as clusters, and intervals use
Student's t with (windows - 1) degrees of freedom.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, stats

from rover_env.calibration.candidates import Candidate, Extensions, merge
from rover_env.calibration.replay import (
    PreparedLog,
    Replayer,
    ReplaySettings,
    Window,
    WindowResult,
)
from rover_env.calibration.residuals import residual_vector, window_slices
from rover_env.config import RoverConfig
from rover_env.effects import EffectError
from rover_env.sim.simulator import SimulationError

Array = NDArray[np.float64]


@dataclass
class Evaluator:
    """Replays window sets under extension sets, with a cache and a cost account."""

    base: RoverConfig
    settings: ReplaySettings
    logs: list[PreparedLog]
    sets: dict[str, list[Window]]
    scale: dict[str, float] = field(default_factory=dict)
    log: Callable[[str], None] = print
    cache: dict[tuple[str, str], list[WindowResult]] = field(default_factory=dict)
    replays: int = 0
    seconds: float = 0.0

    def config(self, ext: Extensions) -> RoverConfig:
        from dataclasses import replace

        return replace(self.base, extensions=merge(self.base.extensions, ext))

    def run(self, ext: Extensions, which: str) -> list[WindowResult]:
        key = (json.dumps(ext, sort_keys=True), which)
        if key not in self.cache:
            t0 = time.perf_counter()
            rp = Replayer(self.config(ext), self.settings, backend="auto")
            self.cache[key] = rp.run(self.logs, self.sets[which])
            self.replays += 1
            self.seconds += time.perf_counter() - t0
        return self.cache[key]

    def vector(self, ext: Extensions, which: str) -> Array:
        return residual_vector(self.run(ext, which), self.scale)


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
    """Replay bias removed from x (diagnose's bias correction), if estimated."""

    @property
    def name(self) -> str:
        return " + ".join(c.name for c in self.candidates)

    @property
    def k(self) -> int:
        return sum(c.k for c in self.candidates)

    def physical(self) -> dict[str, dict[str, tuple[float, float, float]]]:
        """Effect -> parameter -> (value, 95 % low, 95 % high) in the effect's own terms."""
        out: dict[str, dict[str, tuple[float, float, float]]] = {}
        i = 0
        for c in self.candidates:
            n = len(c.labels)
            x, lo, hi = self.x[i : i + n], self.ci_lo[i : i + n], self.ci_hi[i : i + n]
            if c.discrete:
                out[c.name] = {k: (v, v, v) for k, v in c.reported(x).items()}
            elif c.name == "slope":
                deg = math.hypot(x[0], x[1])
                se = self.se[i : i + n]
                g = np.array([x[0], x[1]]) / deg if deg > 0 else np.array([1.0, 0.0])
                s = float(math.sqrt(float(np.sum((g * se) ** 2))))
                tq = (hi[0] - x[0]) / se[0] if se[0] > 0 else 1.96
                head = c.reported(x)["heading_deg"]
                out[c.name] = {
                    "deg": (deg, max(0.0, deg - tq * s), deg + tq * s),
                    "heading_deg": (head, math.nan, math.nan),
                }
            else:
                out[c.name] = {c.labels[0]: (float(x[0]), float(lo[0]), float(hi[0]))}
            i += n
        return out


def _to_ext(cands: list[Candidate], x: Array) -> Extensions:
    parts, i = [], 0
    for c in cands:
        n = len(c.labels)
        parts.append(c.to_ext(x[i : i + n]))
        i += n
    return merge(*parts)


def _diff_step(c: Candidate) -> list[float]:
    out = []
    scale = np.max(np.abs(np.array(c.probe)), axis=0) if c.probe else None
    for i, (lab, lo, hi) in enumerate(zip(c.labels, c.lo, c.hi, strict=True)):
        if lab == "delay":
            out.append(0.02)  # 20 substeps: the delay is quantised to the physics step
        elif scale is not None and scale[i] > 0:
            out.append(float(scale[i]) * 0.1)
        else:
            out.append((hi - lo) * 0.01)
    return out


def fit(
    ev: Evaluator,
    cands: list[Candidate],
    which: str,
    x_start: Array | None = None,
    max_nfev: int = 6,
    probe: bool = True,
) -> Fit:
    """Bounded least squares of the candidates' variables on window set ``which``."""
    t0 = time.perf_counter()
    if all(c.discrete for c in cands):
        ext = _to_ext(cands, np.zeros(0))
        r = ev.vector(ext, which)
        z = np.zeros(0)
        return Fit(cands, z, z, z, z, float(r @ r), 1, ext, time.perf_counter() - t0, which)
    free = [c for c in cands if not c.discrete]
    fixed = merge(*[c.to_ext(np.zeros(0)) for c in cands if c.discrete])
    lo = np.concatenate([c.lo for c in free])
    hi = np.concatenate([c.hi for c in free])
    x0 = np.concatenate([c.off for c in free]) if x_start is None else np.array(x_start)
    nfev = 0
    size = 0

    def fun(x: Array) -> Array:
        nonlocal nfev, size
        nfev += 1
        try:
            r = ev.vector(merge(fixed, _to_ext(free, x)), which)
        except (EffectError, SimulationError) as exc:
            # A value the model cannot take (or that makes it unstable): a wall, not a crash.
            ev.log(f"  {_to_ext(free, x)}: {exc}; treated as a very poor fit")
            return np.full(size or ev.vector(fixed, which).size, 1e3)
        size = r.size
        return r

    if probe and x_start is None and len(free) == 1 and free[0].probe:
        # Effects with no gradient at "off" (a torque limit never reached) or a strongly
        # nonlinear response (a slope's direction) need a start where they act: try the
        # clearly-present values too and start from the best.
        best = fun(x0)
        best_cost = float(best @ best)
        for trial in free[0].probe:
            r1 = fun(np.clip(np.array(trial, dtype=float), lo, hi))
            if float(r1 @ r1) < best_cost:
                best_cost, x0 = float(r1 @ r1), np.clip(np.array(trial, dtype=float), lo, hi)
    x0 = np.clip(x0, lo, hi)
    diff = np.concatenate([_diff_step(c) for c in free])
    # least_squares' 2-point step is diff_step * max(1, |x|): give it absolute steps.
    res = optimize.least_squares(
        fun,
        x0,
        bounds=(lo, hi),
        jac="2-point",
        diff_step=diff,
        x_scale=diff * 10,
        max_nfev=max_nfev,
        method="trf",
    )
    x = res.x
    r = res.fun
    jac = res.jac
    results = ev.run(merge(fixed, _to_ext(free, x)), which)
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
    ci_lo, ci_hi = x - tq * se, x + tq * se
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
        merge(fixed, _to_ext(free, x)),
        time.perf_counter() - t0,
        which,
    )


def information_criteria(sum_log_ratio: float, n: int, k: int) -> tuple[float, float]:
    """(delta AIC, delta BIC) against the reference model, windows as the n observations.

    ``sum_log_ratio`` is the sum over windows of log(loss / reference loss): the change of
    -2 log likelihood when each window has its own Gaussian error scale (profiled out).
    """
    return sum_log_ratio + 2 * k, sum_log_ratio + k * math.log(max(n, 2))
