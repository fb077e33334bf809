"""The numpy slip estimator for many rovers: ``SlipEstimator.update`` with a leading rover axis.

The reference of the compiled :class:`~rover_env.estimation.fast.FastSlipEstimator` (same
interface); the envs' numpy sample loop runs it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rover_env.config import RoverConfig
from rover_env.estimation.estimator import (
    FLAG_WARMUP,
    WINDOW_SLACK,
    EstimatorConfig,
    SlipEstimate,
    SlipEstimator,
    kinematic_part,
    lsq_slope,
    odometry_increments,
)

__all__ = ["BatchSlipEstimator"]


class BatchSlipEstimator:
    """``SlipEstimator.update`` for ``n`` rovers at once, each estimate computed on demand.

    :meth:`push` takes one sample per listed rover (what ``update`` stores: the rate
    window, the dead-reckoned pose); :meth:`estimate` returns what ``update`` would have
    returned for each rover's newest sample, with the estimator's own functions
    (``lsq_slope``, ``kinematic_part``) on arrays with a leading rover axis, bit for bit
    (rovers whose windows hold the same number of samples share a call). Rate samples the
    env never looks at are therefore never evaluated. Least-squares rates only.
    """

    def __init__(self, rover_cfg: RoverConfig, n: int, est_cfg: EstimatorConfig | None = None):
        one = SlipEstimator(rover_cfg, est_cfg)
        if one.est_cfg.rate_method != "lsq":
            raise NotImplementedError("BatchSlipEstimator implements rate_method='lsq' only")
        self.est_cfg = one.est_cfg
        self.chain = one.chain
        self.v_eps = one.v_eps
        self.n = int(n)
        self._limit = self.est_cfg.rate_window * (1 + WINDOW_SLACK)
        cap = 8
        self._t = np.zeros((n, cap))
        self._y = np.zeros((n, cap, 11))
        self._count = np.zeros(n, dtype=np.int64)
        self._started = np.zeros(n, dtype=bool)
        self._t0 = np.zeros(n)
        self._last_theta = np.zeros((n, 5))
        self._pose = np.zeros((n, 3))
        self._arange = np.arange(1024)

    def reset(self, ids: ArrayLike | None = None) -> None:
        """Forget rovers ``ids`` (default all): their next sample starts a new drive."""
        sel = slice(None) if ids is None else np.asarray(ids, dtype=np.int64).reshape(-1)
        self._count[sel] = 0
        self._started[sel] = False
        self._pose[sel] = 0.0

    def _grow(self) -> None:
        n, cap = self._t.shape
        self._t = np.concatenate([np.zeros((n, cap)), self._t], axis=1)
        self._y = np.concatenate([np.zeros((n, cap, 11)), self._y], axis=1)

    def _rows(self, ids: ArrayLike | None) -> tuple[NDArray[np.int64] | slice, int]:
        if ids is None:
            return slice(None), self.n
        sel = np.asarray(ids, dtype=np.int64).reshape(-1)
        return sel, sel.size

    def push(self, ids: ArrayLike | None, t: ArrayLike, phi: ArrayLike, theta: ArrayLike) -> None:
        """One sample for each rover of ``ids`` (None: all): times (k,), wheel angles
        (k, 6), joint angles (k, 5)."""
        sel, k = self._rows(ids)
        if k == 0:
            return
        t_a = np.array(t, dtype=np.float64).reshape(k)
        y = np.empty((k, 11))
        y[:, :6] = np.reshape(phi, (k, 6))
        y[:, 6:] = np.reshape(theta, (k, 5))
        if not (np.isfinite(y).all() and np.isfinite(t_a).all()):
            raise ValueError("wheel and joint angles and time must be finite")
        tb, yb, count = self._t, self._y, self._count
        started = self._started[sel]
        prev_t = tb[sel, -1]
        back = started & (t_a <= prev_t)
        if back.any():
            i = int(np.flatnonzero(back)[0])
            raise ValueError(f"time must increase: {prev_t[i]!r} then {t_a[i]!r}")
        cnt = count[sel] + 1
        cap = tb.shape[1]
        if cnt.max() >= cap:
            self._grow()
            tb, yb, cap = self._t, self._y, 2 * cap
        tb[sel, :-1] = tb[sel, 1:]
        tb[sel, -1] = t_a
        yb[sel, :-1] = yb[sel, 1:]
        yb[sel, -1] = y
        # The streaming window: the newest samples no older than the window (a suffix).
        inside = (self._arange[:cap] >= cap - cnt[:, None]) & ~(
            t_a[:, None] - tb[sel] > self._limit
        )
        count[sel] = inside.sum(axis=1)
        # Dead reckoning from the free wheels' angle increments, as SlipEstimator.update.
        if started.all():
            rows: Any = sel
            ds, dpsi = odometry_increments(y[:, 4:6] - yb[sel, -2, 4:6], self.chain)
        else:
            idx = np.arange(self.n)[sel]
            self._t0[idx[~started]] = t_a[~started]
            rows = idx[started]
            ds, dpsi = odometry_increments(y[started, 4:6] - yb[rows, -2, 4:6], self.chain)
        if ds.size:
            pose = self._pose[rows]
            heading = pose[:, 2] + dpsi / 2.0
            step = np.empty_like(pose)
            step[:, 0] = ds * np.array([math.cos(h) for h in heading.tolist()])
            step[:, 1] = ds * np.array([math.sin(h) for h in heading.tolist()])
            step[:, 2] = dpsi
            self._pose[rows] = pose + step
        self._last_theta[sel] = y[:, 6:]
        self._started[sel] = True

    def estimate(self, ids: ArrayLike | None = None) -> list[SlipEstimate]:
        """The estimate at each listed rover's newest sample (as ``SlipEstimator.update``)."""
        sel = np.arange(self.n) if ids is None else np.asarray(ids, dtype=np.int64).reshape(-1)
        if not self._started[sel].all():
            raise RuntimeError("estimate() needs at least one sample since reset")
        cap = self._t.shape[1]
        cnt = self._count[sel]
        t = self._t[sel, -1]
        y = self._y[sel, -1]
        rates = np.empty((sel.size, 11))
        for c in np.unique(cnt).tolist():
            g = np.flatnonzero(cnt == c)
            rows = sel[g]
            tau = self._t[rows, cap - c :] - t[g, None]
            z = self._y[rows, cap - c :] - y[g, None, :]
            rates[g] = lsq_slope(tau, z, np.ones(tau.shape, dtype=bool))
        part = kinematic_part(rates, self._last_theta[sel], self.chain, self.est_cfg, self.v_eps)
        warm = (t - self._t0[sel]) < self.est_cfg.rate_window
        part["flags"] = np.where(warm[:, None], part["flags"] | FLAG_WARMUP, part["flags"])
        return [
            SlipEstimate(
                t=np.array(t[j]),
                pose=self._pose[i].copy(),
                **{name: v[j] for name, v in part.items()},
            )
            for j, i in enumerate(sel.tolist())
        ]
