"""The sensor noise's share of a fitted value's uncertainty, from simulated noise draws.

Both interval methods of :mod:`rover_env.calibration.fit` resample *windows* (block
bootstrap, or the cluster sandwich of the multi-parameter fits). That is right when many
windows carry the effect; when one or two do (a torque limit reached in one hard
acceleration), the resampled windows agree with themselves and the interval shrinks to the
spacing of the search, while that window's own sensor noise (an encoder's quantisation
error at the event, ±half a count) moves the estimate by more. On this project's own logs
(issue 16, stop 38) a torque limit of -0.09 was fitted -0.0968 [-0.150, -0.0932]: one window
of 32 carried it, its minimum at -0.096.

So the model's own twins of the fitted drives (:func:`rover_env.calibration.residuals.twin_sensed`)
are read through the logs' sensors several times, each time with a fresh encoder phase and
fresh joint and pose noise, and replayed under the fitted model: each replay's residual is
one draw ``n`` of what the sensors alone leave. With ``J`` the residuals' Jacobian in the
fitted parameters, a draw moves a least-squares estimate by ``-(J'J)^-1 J'n`` to first
order; windows are independent, so the covariance is ``B M B`` with ``B = (J'J)^-1`` and
``M`` the sum over windows of the draws' scatter of ``J_w'n_w``, and the draws' mean moves
it by the replay's own bias. Diagnose widens each named effect's interval to at least
1.96 times both in quadrature on each side (never narrows it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rover_env.calibration import residuals as rs
from rover_env.calibration.candidates import merge
from rover_env.calibration.fit import Evaluator, Fit, to_ext
from rover_env.calibration.replay import PreparedLog, Replayer, ReplaySettings, prepare
from rover_env.calibration.residuals import residual_vector, window_slices

Array = NDArray[np.float64]

DRAWS = 6
"""Noise draws per named effect: each costs one replay of the fit's windows."""

STEP = 0.04
"""Relative step (of the value's distance from "off") of the central differences."""


@dataclass
class NoiseSE:
    se: Array
    """Per free variable: the standard error the sensor noise puts on it (the draws'
    scatter)."""
    bias: Array
    """Per free variable: where the draws' mean residual moves it (the replay's own bias:
    a window started from noisy samples)."""
    draws: int
    windows: int

    @property
    def total(self) -> Array:
        """One-sigma uncertainty from the sensors: scatter and bias in quadrature."""
        return np.asarray(np.hypot(self.se, self.bias), dtype=np.float64)


def draw_moments(jac: Array, slices: list[slice], draws: list[Array]) -> tuple[Array, Array]:
    """(covariance, bias) of a least-squares estimate under the residual draws.

    ``jac`` (n, k): the residuals' Jacobian in the fitted variables; ``slices``: each
    window's rows; ``draws``: residual vectors (n,) left by noise alone. The estimate moves
    by ``-B J'n`` (``B = (J'J)^-1``); windows are independent, so the covariance sums each
    window's own scatter of ``J_w'n_w`` over the draws, and the bias is the move of the
    draws' mean residual. One draw: no scatter, its move is the bias."""
    bread = np.linalg.pinv(jac.T @ jac)
    k = jac.shape[1]
    g = np.array([[jac[s].T @ n[s] for s in slices] for n in draws])  # (draws, windows, k)
    mean = g.mean(axis=0)
    meat = np.zeros((k, k))
    if len(draws) > 1:
        dev = g - mean
        meat = np.einsum("dwi,dwj->ij", dev, dev) / (len(draws) - 1)
    return bread @ meat @ bread, -(bread @ mean.sum(axis=0))


def noise_draws(
    ev: Evaluator,
    f: Fit,
    sensor_noise: dict[str, float],
    st: ReplaySettings,
    draws: int = DRAWS,
    seed: int = 2,
) -> list[list[PreparedLog]]:
    """``draws`` sets of the fitted model's twins of the drives ``f`` was fitted on, each
    read through the sensors with its own encoder phase and noise (other logs as they are)."""
    cfg = ev.config(f.ext)
    used = sorted({w.log_index for w in ev.sets[f.which]})
    res = rs.resolutions(ev.logs)
    rng = np.random.default_rng(seed)
    states = rs.twins_of(ev.logs, cfg, set(used))
    out = []
    for _ in range(draws):
        logs = list(ev.logs)
        for i in used:
            p = ev.logs[i]
            phase = rng.uniform(0.0, 1.0, 6)
            twin = rs.twin_sensed(p, states[i], sensor_noise, res, rng, encoder_phase=phase)
            logs[i] = prepare(twin, ev.base, p.name + " twin", st)
        out.append(logs)
    return out


def _steps(f: Fit) -> tuple[Array, Array]:
    """(below, above) the fitted values for the central differences, inside the bounds."""
    free = [c for c in f.candidates if not c.discrete]
    lo = np.concatenate([c.lo for c in free])
    hi = np.concatenate([c.hi for c in free])
    off = np.concatenate([c.off for c in free])
    h = np.maximum(STEP * np.abs(f.x - off), 0.002 * (hi - lo))
    return np.maximum(f.x - h, lo), np.minimum(f.x + h, hi)


def noise_se(
    ev: Evaluator,
    f: Fit,
    sensor_noise: dict[str, float],
    st: ReplaySettings,
    draws: int = DRAWS,
    seed: int = 2,
) -> NoiseSE | None:
    """The sensor noise's standard error on ``f``'s free variables (module docstring);
    None for a fit without free variables."""
    free = [c for c in f.candidates if not c.discrete]
    if f.x.size == 0 or f.x.size != sum(len(c.labels) for c in free):
        return None
    which = f.which
    windows = ev.sets[which]
    below, above = _steps(f)
    cols = []
    for i in range(f.x.size):
        xa, xb = f.x.copy(), f.x.copy()
        xa[i], xb[i] = below[i], above[i]
        ra = ev.vector(merge(f.ext, to_ext(free, xa)), which)
        rb = ev.vector(merge(f.ext, to_ext(free, xb)), which)
        cols.append((rb - ra) / (xb[i] - xa[i]))
    jac = np.stack(cols, axis=1)
    slices = window_slices(ev.run(f.ext, which))
    cfg = ev.config(f.ext)
    vecs = []
    for logs in noise_draws(ev, f, sensor_noise, st, draws, seed):
        vecs.append(residual_vector(Replayer(cfg, st, backend="auto").run(logs, windows), ev.scale))
        ev.replays += 1
    cov, bias = draw_moments(jac, slices, vecs)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return NoiseSE(se, bias, draws, len(slices))


def widen_by_noise(f: Fit, se: NoiseSE, z: float = 1.96) -> bool:
    """Widen ``f``'s interval of each free variable to at least ``z`` noise standard
    errors on each open side (a one-sided interval keeps its bound); True if it moved."""
    free = [c for c in f.candidates if not c.discrete]
    lo = np.concatenate([c.lo for c in free])
    hi = np.concatenate([c.hi for c in free])
    sided = f.sided or ("",) * f.x.size
    moved = False
    total = se.total
    for i in range(f.x.size):
        half = z * float(total[i])
        new_lo = max(float(lo[i]), float(f.x[i]) - half)
        new_hi = min(float(hi[i]), float(f.x[i]) + half)
        if sided[i] != "upper" and new_lo < f.ci_lo[i]:
            f.ci_lo[i], moved = new_lo, True
        if sided[i] != "lower" and new_hi > f.ci_hi[i]:
            f.ci_hi[i], moved = new_hi, True
        if f.windows_ci is not None:  # the interval the groups did not widen, the same way
            w_lo, w_hi = f.windows_ci
            w_lo[i] = min(w_lo[i], new_lo) if sided[i] != "upper" else w_lo[i]
            w_hi[i] = max(w_hi[i], new_hi) if sided[i] != "lower" else w_hi[i]
        f.se[i] = max(float(f.se[i]), float(total[i]))
    f.noise_se = total
    return moved
