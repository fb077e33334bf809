"""The slip estimator for many rovers, compiled: ``rover_env.sim.fast``'s ``env_core.c``.

:class:`FastSlipEstimator` has the interface of the numpy
``rover_env.estimation.batch.BatchSlipEstimator`` (push one sample per listed rover,
estimate on demand) and returns what :class:`~rover_env.estimation.estimator.SlipEstimator`
returns to rounding (the C code sums the least-squares window in another order; tests hold
it to 1e-12). Why: the numpy estimator, called on single samples, cost more than the
physics it estimates (``docs/speed.md``). The numpy forms stay the reference.
"""

from __future__ import annotations

import ctypes

import numpy as np
import numpy.typing as npt

from rover_env.config import RoverConfig
from rover_env.estimation.estimator import (
    WINDOW_SLACK,
    EstimatorConfig,
    SlipEstimate,
    SlipEstimator,
)
from rover_env.sim.fast.build import load_core

__all__ = ["NOUT", "FastSlipEstimator", "estimate_from_row"]

NOUT = 56
"""Numbers per estimate in ``env_core.c``'s output row (layout: :func:`estimate_from_row`)."""

_P = ctypes.c_void_p


_typed: set[int] = set()


def _lib() -> ctypes.CDLL:
    lib = load_core()
    if id(lib) not in _typed:
        lib.est_new.restype = _P
        lib.est_new.argtypes = [ctypes.c_int, _P]
        lib.est_free.restype = None
        lib.est_free.argtypes = [_P]
        lib.est_reset.restype = None
        lib.est_reset.argtypes = [_P, ctypes.c_int]
        lib.est_push.restype = ctypes.c_int
        lib.est_push.argtypes = [_P, ctypes.c_int, ctypes.c_double, _P]
        lib.est_estimate.restype = ctypes.c_int
        lib.est_estimate.argtypes = [_P, ctypes.c_int, _P]
        _typed.add(id(lib))
    return lib


def estimate_from_row(row: npt.NDArray[np.float64]) -> SlipEstimate:
    """A :class:`SlipEstimate` viewing one output row of ``est_estimate`` (NOUT numbers)."""
    return SlipEstimate(
        t=row[52].copy(),
        phi_rate=row[0:6],
        theta_rate=row[6:11],
        nominal_rate=row[11:15],
        actual_rate=row[15:19],
        slippage=row[19:23],
        slip_ratio=row[23:27],
        seg_velocity=row[27:36].reshape(3, 3),
        seg_omega=row[36:45].reshape(3, 3),
        seg_yaw_rate=row[45:48],
        pose=row[53:56],
        flags=row[48:52].astype(np.int64),
    )


class FastSlipEstimator:
    """``n`` streaming slip estimators (rate_method ``"lsq"``) in C; see the module docstring."""

    def __init__(
        self, rover_cfg: RoverConfig, n: int, est_cfg: EstimatorConfig | None = None
    ) -> None:
        one = SlipEstimator(rover_cfg, est_cfg)
        if one.est_cfg.rate_method != "lsq":
            raise NotImplementedError("FastSlipEstimator implements rate_method='lsq' only")
        self.est_cfg = est = one.est_cfg
        self.chain = one.chain
        self.v_eps = one.v_eps
        self.n = int(n)
        cfg = np.array(
            [
                est.rate_window * (1 + WINDOW_SLACK),
                est.rate_window,
                *self.chain.wheel_radii,
                self.chain.half_track,
                *self.chain.link_a,
                *self.chain.joint_anchor,
                self.v_eps,
                est.min_speed,
                est.max_free_wheel_ratio,
                est.max_side_slip,
            ]
        )
        self._lib = _lib()
        handle = self._lib.est_new(self.n, cfg.ctypes.data)
        if not handle:
            raise MemoryError("FastSlipEstimator: out of memory")
        self.handle: int = handle
        self._y = np.empty(11)
        self._y_ptr = self._y.ctypes.data
        self._last_t = np.zeros(self.n)
        """Each rover's newest sample time (for the error message of a sample out of order)."""

    def __reduce__(self) -> tuple[object, ...]:
        # The C state is not copied: a copy sharing the handle would free it twice.
        raise TypeError("FastSlipEstimator holds C memory: it cannot be pickled or copied")

    def __del__(self) -> None:
        lib, h = getattr(self, "_lib", None), getattr(self, "handle", None)
        if lib is not None and h:
            lib.est_free(h)
            self.handle = 0

    def _ids(self, ids: npt.ArrayLike | None) -> list[int]:
        if ids is None:
            return list(range(self.n))
        return [int(i) for i in np.asarray(ids, dtype=np.int64).reshape(-1)]

    def reset(self, ids: npt.ArrayLike | None = None) -> None:
        """Forget rovers ``ids`` (default all): their next sample starts a new drive."""
        for i in self._ids(ids):
            self._lib.est_reset(self.handle, i)

    def push(
        self, ids: npt.ArrayLike | None, t: npt.ArrayLike, phi: npt.ArrayLike, theta: npt.ArrayLike
    ) -> None:
        """One sample for each rover of ``ids`` (None: all): times (k,), wheel angles
        (k, 6), joint angles (k, 5)."""
        rows = self._ids(ids)
        k = len(rows)
        if k == 0:
            return
        t_a = np.array(t, dtype=np.float64).reshape(k)
        phi_a = np.reshape(np.asarray(phi, dtype=np.float64), (k, 6))
        theta_a = np.reshape(np.asarray(theta, dtype=np.float64), (k, 5))
        y, push, h = self._y, self._lib.est_push, self.handle
        for j, i in enumerate(rows):
            y[:6] = phi_a[j]
            y[6:] = theta_a[j]
            self._check(push(h, i, t_a[j], self._y_ptr), i, float(t_a[j]))

    def _check(self, err: int, i: int, t: float) -> None:
        if err == 0:
            self._last_t[i] = t
        elif err == -1:
            raise ValueError(f"time must increase: {float(self._last_t[i])!r} then {t!r}")
        elif err == -2:
            raise ValueError("wheel and joint angles and time must be finite")
        else:
            raise MemoryError("FastSlipEstimator: out of memory")

    def estimate(self, ids: npt.ArrayLike | None = None) -> list[SlipEstimate]:
        """The estimate at each listed rover's newest sample (as ``SlipEstimator.update``)."""
        return [self.estimate_one(i) for i in self._ids(ids)]

    def estimate_one(self, i: int) -> SlipEstimate:
        """The estimate at rover ``i``'s newest sample."""
        row = np.empty(NOUT)
        if self._lib.est_estimate(self.handle, i, row.ctypes.data):
            raise RuntimeError("estimate() needs at least one sample since reset")
        return estimate_from_row(row)
