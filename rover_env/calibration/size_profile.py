"""The tilt's size where each log's frame is turned on its own (``diagnose --frames fit``):
the runs' misfit profiled over the size, each log's turn and the resistance fitted again at
every size.

Why: with each log's frame free, a log whose steady straight runs lie along one line reads
only the tilt's part along that line, and two turns (a mirror pair) read it alike; where
every log is so, the size is bounded below and barely above. The curvature about one fit
(each turn moved alone) cannot see that valley, and a turn search log by log can stop in
it: block 54000's 54008 (0.65°, registered, spent) read 3.44° [2.21, 4.68] in turns 129°
and 160° off, where the balance now reads 0.68° [0.51, 3.66] (exploratory, after the
look). The profile's interval is the likelihood ratio's: every size whose best misfit stays
within an F quantile of the best.

The model per run ``j`` of log ``k``: ``force_j = A cos(yaw_j + beta_k) + R direction_j``
with ``A = m g sin(size)``: each log's ``beta_k`` (its turn less the tilt's heading) is free.
At a given ``A`` and ``R`` each log's best ``beta_k`` is a one-dimensional search over a
grid (its misfit is a quadratic form in ``cos beta_k`` and ``sin beta_k``), and ``R`` is a
weighted mean; the two alternate. numpy only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats

Array = NDArray[np.float64]

CAP_DEG = 20.0
"""Degrees: the largest size profiled. A size still inside the interval there leaves the
interval open above (infinite): the runs bound the tilt below only."""
SIZES = np.concatenate([np.arange(0.0, 5.0, 0.02), np.arange(5.0, CAP_DEG + 1e-9, 0.25)])
"""The sizes profiled (degrees): 0.02° steps to 5°, a tenth of the narrowest intervals read
on block 54000, then 0.25°."""
GRID_STEP = math.radians(1.0)
ANGLES = np.arange(0.0, 2.0 * math.pi, GRID_STEP)
"""Each log's ``beta`` grid (radians): 1° steps, each best refined (:func:`_angle`)."""
COS, SIN = np.cos(ANGLES), np.sin(ANGLES)
ROUNDS = 6
"""Alternations of the logs' angles and the resistance at each size (the misfit falls each
round; the resistance moves by under 0.1 % of its own after four on block 54000's logs)."""


@dataclass(frozen=True)
class SizeProfile:
    """The profile's best and its 95 % interval (degrees)."""

    deg: float
    lo: float
    hi: float
    """``inf`` where sizes up to :data:`CAP_DEG` stay inside."""
    rss: float
    """The best weighted misfit."""
    angles: dict[int, float]
    """Per log with runs, its ``beta`` (radians) at the best size."""


@dataclass(frozen=True)
class _Log:
    """One log's runs (``m``: its rows) and the sums of its misfit's quadratic part."""

    m: Array
    wc: Array
    """Each run's weight squared times its heading's cosine, and :attr:`ws` its sine."""
    ws: Array
    cc: float
    cs: float
    ss: float


def _logs(X: Array, w2: Array, logs: Array) -> list[tuple[int, _Log]]:
    """Per log with runs, what :func:`_angle` needs that does not change with the size."""
    out = []
    for k in np.unique(logs):
        m = logs == k
        c, s, ww = X[m, 0], X[m, 1], w2[m]
        sums = (float(np.sum(ww * c * c)), float(np.sum(ww * c * s)), float(np.sum(ww * s * s)))
        out.append((int(k), _Log(m, ww * c, ww * s, *sums)))
    return out


def _angle(a: float, lg: _Log, u: Array) -> float:
    """The log's best ``beta`` at tilt force ``a`` (targets ``u``): its misfit ``f(beta)``
    is a quadratic form in ``cos beta`` and ``sin beta`` over five sums; the grid's best,
    then Newton's steps on ``f'`` (the grid alone moves a large tilt's part by more than
    the runs' noise)."""
    S, T, cc, cs, ss = float(lg.wc @ u), float(lg.ws @ u), lg.cc, lg.cs, lg.ss
    cb, sb = COS, SIN
    f = -2.0 * a * (S * cb - T * sb) + a * a * (cc * cb**2 - 2.0 * cs * sb * cb + ss * sb**2)
    b = float(ANGLES[int(np.argmin(f))])
    for _ in range(3):
        d1 = 2.0 * a * (S * math.sin(b) + T * math.cos(b)) + a * a * (
            (ss - cc) * math.sin(2 * b) - 2.0 * cs * math.cos(2 * b)
        )
        d2 = 2.0 * a * (S * math.cos(b) - T * math.sin(b)) + a * a * (
            2.0 * (ss - cc) * math.cos(2 * b) + 4.0 * cs * math.sin(2 * b)
        )
        if d2 <= 0.0:
            break
        b -= max(-GRID_STEP, min(GRID_STEP, d1 / d2))
    return b


def _at(
    a: float, X: Array, y: Array, w2: Array, each: list[tuple[int, _Log]], r: float
) -> tuple[float, float, dict[int, float]]:
    """At tilt force ``a``: the misfit, the resistance and each log's angle, alternated
    from the resistance ``r``."""
    g = np.zeros(len(y))
    beta: dict[int, float] = {}
    wd = w2 * X[:, 2]
    for _ in range(ROUNDS):
        for k, lg in each:
            m = lg.m
            beta[k] = _angle(a, lg, y[m] - r * X[m, 2])
            g[m] = a * (X[m, 0] * math.cos(beta[k]) - X[m, 1] * math.sin(beta[k]))
        r = float(np.sum(wd * (y - g)) / np.sum(wd * X[:, 2]))
    res = y - g - r * X[:, 2]
    return float(np.sum(w2 * res**2)), r, beta


def profile(X: Array, y: Array, w: Array, logs: Array, weight: float, floor: bool) -> SizeProfile:
    """The size's profile over runs ``X`` (per run: cos and sin of its heading in its log's
    frame, its direction), ``y`` (the traction, N), weights ``w`` (1 over each run's known
    noise, or ones), ``logs`` (each run's log), ``weight`` (``m g``, N). ``floor``: the
    scatter counts only where it is larger than the known noise (the slip's runs, as
    :func:`rover_env.calibration.balance._solve`). Interval: sizes whose best misfit is
    within ``s^2 F(1, dof)`` of the best, ``dof`` the runs less the resistance, the size
    and each log's angle; (0, inf) where that leaves none. From zero where level is not
    rejected with the size and every log's angle counted (``s^2 (1 + k) F(1 + k, dof)``,
    ``k`` the logs: under level the angles mean nothing, and a test of one degree of
    freedom would find a tilt in noise that each log's free angle points its way)."""
    w2 = w**2
    each = _logs(X, w2, logs)
    out, res, r = [], [], 0.0
    for deg in SIZES:  # each size starts from the last one's resistance
        rss, r, _ = _at(weight * math.sin(math.radians(deg)), X, y, w2, each, r)
        out.append(rss)
        res.append(r)
    P = np.asarray(out)
    best = int(np.argmin(P))
    a = weight * math.sin(math.radians(SIZES[best]))
    _, _, beta = _at(a, X, y, w2, each, res[best])
    dof = len(y) - 2 - len(each)
    if dof <= 0:
        return SizeProfile(float(SIZES[best]), 0.0, math.inf, float(P[best]), beta)
    s2 = float(P[best]) / dof
    s2 = max(s2, 1.0) if floor else s2
    inside = SIZES[P <= P[best] + s2 * float(stats.f.ppf(0.95, 1, dof))]
    hi = float(inside.max())
    k = 1 + len(each)
    level = P[0] <= P[best] + s2 * k * float(stats.f.ppf(0.95, k, dof))
    return SizeProfile(
        deg=float(SIZES[best]),
        lo=0.0 if level else float(inside.min()),
        hi=math.inf if hi >= CAP_DEG else hi,
        rss=float(P[best]),
        angles=beta,
    )
