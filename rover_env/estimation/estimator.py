"""Kinematic slip estimation from wheel and joint angles only (SPEC §2, paper eqs. 1–10).

The real rover has encoders and potentiometers, no speed sensors: every rate here comes from
differentiating measured angles. Two forms give the same numbers (to rounding) on the same
samples: :class:`SlipEstimator` for a running rover, one sample at a time, and
:func:`estimate_log` for a whole log at once.

Differentiation (``EstimatorConfig.rate_method``):

* ``"lsq"`` (default): the slope of a least-squares line through the samples of the last
  ``rate_window`` seconds, on their actual time stamps. It is a causal FIR filter, so the
  two forms are the same arithmetic on the same samples (no recursive state that could
  drift apart); it is exact for constant rates (no steady-state bias), tolerates irregular
  sampling, and delays every channel by the same ``rate_window / 2``: nominal and measured
  wheel rates stay aligned in time, which matters because slip is their small difference.
  Its noise gain is the lowest of any unbiased linear slope estimator over the window.
* ``"lowpass"``: backward differences through a first-order low-pass of time constant
  ``rate_window`` (exact discretisation for each interval). Cheaper but noisier for the
  same lag: its output keeps the newest sample's full noise divided by the time constant.

Reliability (``SlipEstimate.flags``, a bit mask per driven wheel; ``reliable`` = no bit):

* ``FLAG_WARMUP``: less than ``rate_window`` of data since the first sample.
* ``FLAG_STANDSTILL``: segment 3 (free wheels) moves slower than ``min_speed``: eq. (10)
  divides by a speed, so near standstill resolution and noise dominate.
* ``FLAG_FREE_WHEELS``: the free wheels contradict the chain's motion, as when one is lifted
  (stops) or slides: either their speed difference implies a turn tighter than
  ``max_free_wheel_ratio`` (|v_R - v_L| / |v_R + v_L| = r |w3| / |v3|, 1 when one wheel stands
  still while the other rolls), or carrying segment 3's motion through the measured joint
  rates gives segment 1 or 2 a side-slip angle above ``max_side_slip``: each segment rides
  on one axle, so its velocity must lie close to its own x axis.
* ``FLAG_SLOW_WHEEL``: this wheel's hub and tread both move slower than ``min_speed`` (the
  inner wheel of a tight turn): its slip ratio is ill-conditioned.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np
import numpy.typing as npt

from rover_env import kinematics as kin
from rover_env.config import ConfigError, RoverConfig, load_rover

__all__ = [
    "FLAG_FREE_WHEELS",
    "FLAG_SLOW_WHEEL",
    "FLAG_STANDSTILL",
    "FLAG_WARMUP",
    "WINDOW_SLACK",
    "EstimatorConfig",
    "SlipEstimate",
    "SlipEstimator",
    "axle_load_radii",
    "estimate_log",
    "kinematic_part",
    "lsq_slope",
    "odometry_increments",
    "static_rolling_radius",
]

Array = npt.NDArray[np.float64]
GRAVITY = 9.81

FLAG_WARMUP = 1
FLAG_STANDSTILL = 2
FLAG_FREE_WHEELS = 4
FLAG_SLOW_WHEEL = 8

# Relative slack on the window length so that a sample exactly rate_window old on a uniform
# grid is kept whatever the rounding of the time stamps (both forms use the same test).
WINDOW_SLACK = 1e-9
# Rows per block in the batch least-squares filter: bounds memory on long, fast logs.
_BLOCK = 4096


def static_rolling_radius(cfg: RoverConfig) -> float:
    """The rolling radius d - k_re * delta with the weight shared equally by the six wheels.

    The simulator rolls each wheel on r_e = d - k_re * delta (``TireParams.k_re``); this is
    the one radius that fits all wheels at rest on average (the static deflection of
    ``rover_env.sim.model.static_deflection``, restated so the estimator needs no simulator).
    """
    delta = cfg.masses.total * GRAVITY / 6 / cfg.tire.C_z
    return cfg.geometry.wheel_radius - cfg.tire.k_re * delta


def axle_load_radii(cfg: RoverConfig) -> tuple[float, ...]:
    """Rolling radius of each wheel (WHEELS order) with each segment's weight on its own axle.

    The segments' masses differ (motors on 1 and 2, batteries on 2 and 3), so at rest the
    axles carry different loads and, with the soft tire (C_z), roll on radii a few per cent
    apart: one common radius then reads as a steady slip of that size. Assumes each
    segment's centre of mass lies over its axle and the pitch joint theta_4 passes no
    moment, as in the project's rover model; a real rover would calibrate these instead.
    """
    out: list[float] = []
    for seg in (1, 2, 3):
        load = (cfg.masses.segment_mass(seg) + 2 * cfg.masses.wheel) * GRAVITY / 2
        out += [cfg.geometry.wheel_radius - cfg.tire.k_re * load / cfg.tire.C_z] * 2
    return tuple(out)


@dataclass(frozen=True)
class EstimatorConfig:
    """Settings of the slip estimator; validated on construction (ConfigError)."""

    rolling_radius: float | tuple[float, ...] | None = None
    """Effective rolling radius (m): one for all wheels, six (WHEELS order), or None for
    d - static deflection (:func:`static_rolling_radius`). See :func:`axle_load_radii`."""
    rate_method: Literal["lsq", "lowpass"] = "lsq"
    """How angles are differentiated (module docstring)."""
    rate_window: float = 0.5
    """Window (lsq) or time constant (lowpass) of the differentiator (s)."""
    min_speed: float = 0.02
    """Speed (m/s) below which segment 3 counts as standing and a wheel as too slow."""
    max_free_wheel_ratio: float = 0.5
    """Largest |v_R - v_L| / |v_R + v_L| of the free wheels before they count as lifted or
    sliding (0.5: a turn of radius 2 r about segment 3's axle centre)."""
    max_side_slip: float = 0.35
    """Largest side-slip angle (rad) of segments 1 and 2 implied by the chain (20 deg)."""
    v_eps: float | None = None
    """Regularisation speed of eq. (10); None takes the rover's tire ``v_eps``."""

    def __post_init__(self) -> None:
        r = self.rolling_radius
        if r is not None:
            values = (r,) if isinstance(r, int | float) else tuple(r)
            if len(values) not in (1, 6):
                raise ConfigError(
                    f"estimator.rolling_radius: give one radius or six, got {len(values)}"
                )
            for v in values:
                if isinstance(v, bool) or not (math.isfinite(v) and v > 0):
                    raise ConfigError(f"estimator.rolling_radius must be > 0, got {v!r}")
            if not isinstance(r, int | float):
                object.__setattr__(self, "rolling_radius", tuple(float(v) for v in values))
        if self.rate_method not in ("lsq", "lowpass"):
            raise ConfigError(
                f"estimator.rate_method must be 'lsq' or 'lowpass', got {self.rate_method!r}"
            )
        for name in ("rate_window", "min_speed", "max_free_wheel_ratio", "max_side_slip"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (math.isfinite(v) and v > 0):
                raise ConfigError(f"estimator.{name} must be a finite number > 0, got {v!r}")
        if self.max_side_slip >= math.pi / 2:
            raise ConfigError("estimator.max_side_slip must be below pi/2")
        if self.v_eps is not None and not (math.isfinite(self.v_eps) and self.v_eps > 0):
            raise ConfigError(f"estimator.v_eps must be > 0, got {self.v_eps!r}")

    def radii(self, cfg: RoverConfig) -> Array:
        """The six effective rolling radii (m) this configuration gives for ``cfg``."""
        r = static_rolling_radius(cfg) if self.rolling_radius is None else self.rolling_radius
        out = np.broadcast_to(np.asarray(r, dtype=np.float64), (6,)).copy()
        if not np.all(out > 0):
            raise ConfigError(f"rolling radius must be > 0 (static deflection too large?): {out}")
        return out


@dataclass(frozen=True)
class SlipEstimate:
    """Estimates at one sample (shapes below) or, from :func:`estimate_log`, with a
    leading sample axis N on every field."""

    t: Array
    phi_rate: Array
    """(6,) filtered wheel rates (rad/s), WHEELS order."""
    theta_rate: Array
    """(5,) filtered joint rates (rad/s)."""
    nominal_rate: Array
    """(4,) no-slip rates of 1L 1R 2L 2R, eqs. (7), (8)."""
    actual_rate: Array
    """(4,) measured rates of the driven wheels."""
    slippage: Array
    """(4,) actual - nominal (rad/s), eq. (9)."""
    slip_ratio: Array
    """(4,) eq. (10), SPEC §3 sign: < 0 spinning, > 0 skidding."""
    seg_velocity: Array
    """(3, 3) velocity of each segment's centre in its own axes (m/s) [segment, xyz]."""
    seg_omega: Array
    """(3, 3) angular velocity of each segment in its own axes (rad/s)."""
    seg_yaw_rate: Array
    """(3,) yaw rate of each segment about its own z axis (rad/s)."""
    pose: Array
    """(3,) x, y, yaw of segment 3, dead-reckoned from its free wheels, frame of t = 0."""
    flags: npt.NDArray[np.int64]
    """(4,) FLAG_* bits per driven wheel; 0 is reliable."""

    @property
    def reliable(self) -> npt.NDArray[np.bool_]:
        """(4,) True where no flag is set."""
        return np.asarray(self.flags == 0)


# --------------------------------------------------------------------------- rate filters


def lsq_slope(tau: Array, z: Array, valid: npt.NDArray[np.bool_]) -> Array:
    """Least-squares slope over the last axis but one; tau, z relative to the newest sample.

    tau (..., M), z (..., M, C), valid (..., M). Fewer than two samples give 0.
    """
    tau = np.where(valid, tau, 0.0)
    z = np.where(valid[..., None], z, 0.0)
    n = valid.sum(axis=-1).astype(np.float64)
    s_t = tau.sum(axis=-1)
    s_tt = (tau * tau).sum(axis=-1)
    s_z = z.sum(axis=-2)
    s_tz = (tau[..., None] * z).sum(axis=-2)
    den = n * s_tt - s_t * s_t
    ok = (n >= 2) & (den > 0)
    safe = np.where(ok, den, 1.0)
    slope = (n[..., None] * s_tz - s_t[..., None] * s_z) / safe[..., None]
    return np.asarray(np.where(ok[..., None], slope, 0.0), dtype=np.float64)


def _lsq_rates_batch(t: Array, y: Array, window: float) -> Array:
    """Causal windowed least-squares slopes of every column of ``y`` (N, C) at every sample."""
    n_samples = t.shape[0]
    limit = window * (1 + WINDOW_SLACK)
    # A superset of each window (the exact test below decides), to size the index matrix.
    start = np.searchsorted(t, t - 2 * limit, side="left")
    m = int(min(n_samples, np.max(np.arange(n_samples) - start) + 2))
    out = np.zeros_like(y)
    offsets = np.arange(m)
    for b0 in range(0, n_samples, _BLOCK):
        k = np.arange(b0, min(n_samples, b0 + _BLOCK))
        idx = k[:, None] - offsets[None, :]
        inside = idx >= 0
        idx = np.where(inside, idx, 0)
        tk = t[k][:, None]
        valid = inside & (tk - t[idx] <= limit)
        tau = t[idx] - tk
        z = y[idx] - y[k][:, None, :]
        out[k] = lsq_slope(tau, z, valid)
    return out


def _lowpass_rates_batch(t: Array, y: Array, tau_c: float) -> Array:
    """Backward differences through a first-order low-pass (the recursion is sequential)."""
    out = np.zeros_like(y)
    if t.shape[0] < 2:
        return out
    dt = np.diff(t)
    raw = np.diff(y, axis=0) / dt[:, None]
    alpha = np.exp(-dt / tau_c)
    state = raw[0].copy()
    out[1] = state
    for k in range(2, t.shape[0]):
        state = alpha[k - 1] * state + (1.0 - alpha[k - 1]) * raw[k - 1]
        out[k] = state
    return out


# --------------------------------------------------------------------------- kinematics


def kinematic_part(
    rates: Array,
    theta: Array,
    chain: kin.ChainGeometry,
    est: EstimatorConfig,
    v_eps: float,
) -> dict[str, Any]:
    """Everything that follows from the rates and joint angles, vectorised over samples.

    rates (..., 11): wheel rates then joint rates. Shared by both forms, so they agree.
    """
    phi_rate, theta_rate = rates[..., :6], rates[..., 6:]
    radii = np.asarray(chain.wheel_radii)
    w3, v3 = kin.segment3_twist(phi_rate[..., 4:], chain)
    motion = kin.chain_motion(w3, v3, theta, theta_rate, chain)
    nominal = kin.nominal_wheel_rates(motion, chain)
    actual = phi_rate[..., :4]
    slip = kin.slip_ratio(actual, nominal, radii[:4], v_eps)

    tread = phi_rate[..., 4:] * radii[4:]
    speed3 = np.abs(v3[..., 0])
    standstill = speed3 < est.min_speed
    ratio = np.abs(tread[..., 1] - tread[..., 0]) / np.maximum(
        np.abs(tread[..., 1] + tread[..., 0]), 1e-12
    )
    vel = motion.velocity
    side_slip = np.arctan2(np.abs(vel[..., :2, 1]), np.abs(vel[..., :2, 0]))
    free_bad = ~standstill & (
        (ratio > est.max_free_wheel_ratio) | np.any(side_slip > est.max_side_slip, axis=-1)
    )
    slow = np.maximum(np.abs(nominal), np.abs(actual)) * radii[:4] < est.min_speed
    flags = (
        np.where(standstill, FLAG_STANDSTILL, 0)[..., None]
        | np.where(free_bad, FLAG_FREE_WHEELS, 0)[..., None]
        | np.where(slow, FLAG_SLOW_WHEEL, 0)
    )
    return {
        "phi_rate": phi_rate,
        "theta_rate": theta_rate,
        "nominal_rate": nominal,
        "actual_rate": actual,
        "slippage": kin.slippage(actual, nominal),
        "slip_ratio": slip,
        "seg_velocity": motion.velocity,
        "seg_omega": motion.omega,
        "seg_yaw_rate": motion.yaw_rate,
        "flags": flags.astype(np.int64),
    }


def odometry_increments(d_free: Array, chain: kin.ChainGeometry) -> tuple[Array, Array]:
    """Travel and heading change of segment 3 from free-wheel angle increments (..., 2).

    Dead reckoning integrates the angles themselves, not the filtered rates: increments add
    up exactly, so neither the filter's lag nor its noise gain enters the pose.
    """
    left = chain.wheel_radii[4] * d_free[..., 0]
    right = chain.wheel_radii[5] * d_free[..., 1]
    return (right + left) / 2.0, (right - left) / (2.0 * chain.half_track)


def _check_sample(phi: Array, theta: Array) -> None:
    if phi.shape[-1] != 6 or theta.shape[-1] != 5:
        raise ValueError(
            f"need 6 wheel angles and 5 joint angles, got {phi.shape} and {theta.shape}"
        )
    if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(theta))):
        raise ValueError("wheel and joint angles must be finite")


# --------------------------------------------------------------------------- streaming


class SlipEstimator:
    """Streaming estimator: feed samples in time order with :meth:`update`."""

    def __init__(self, rover_cfg: RoverConfig, est_cfg: EstimatorConfig | None = None) -> None:
        self.rover_cfg = rover_cfg
        self.est_cfg = est_cfg or EstimatorConfig()
        self.chain = kin.ChainGeometry.from_config(rover_cfg, self.est_cfg.radii(rover_cfg))
        self.v_eps = (
            rover_cfg.tire.v_eps if self.est_cfg.v_eps is None else float(self.est_cfg.v_eps)
        )
        self.reset()

    def reset(self) -> None:
        """Forget all samples: the next one starts a new drive at pose (0, 0, 0)."""
        self._buf: deque[tuple[float, Array]] = deque()
        self._t0: float | None = None
        self._prev_t: float | None = None
        self._prev_y: Array | None = None
        self._state: Array | None = None
        self._pose = np.zeros(3)

    def _rates(self, t: float, y: Array) -> Array:
        est = self.est_cfg
        if est.rate_method == "lsq":
            limit = est.rate_window * (1 + WINDOW_SLACK)
            self._buf.append((t, y))
            while t - self._buf[0][0] > limit:
                self._buf.popleft()
            tw = np.array([s[0] for s in self._buf])
            yw = np.stack([s[1] for s in self._buf])
            return lsq_slope(tw - t, yw - y, np.ones(tw.shape, dtype=bool))
        if self._prev_t is None or self._prev_y is None:
            return np.zeros_like(y)
        dt = t - self._prev_t
        raw = (y - self._prev_y) / dt
        if self._state is None:
            self._state = raw
        else:
            alpha = math.exp(-dt / est.rate_window)
            self._state = alpha * self._state + (1.0 - alpha) * raw
        return self._state

    def update(self, t: float, phi: npt.ArrayLike, theta: npt.ArrayLike) -> SlipEstimate:
        """One sample: time (s), wheel angles (6, rad, cumulative) and joint angles (5, rad)."""
        t = float(t)
        phi_a = np.array(phi, dtype=np.float64).reshape(-1)
        theta_a = np.array(theta, dtype=np.float64).reshape(-1)
        _check_sample(phi_a, theta_a)
        if not math.isfinite(t):
            raise ValueError(f"time must be finite, got {t!r}")
        if self._prev_t is not None and t <= self._prev_t:
            raise ValueError(f"time must increase: {self._prev_t!r} then {t!r}")
        y = np.concatenate([phi_a, theta_a])
        rates = self._rates(t, y)
        if self._t0 is None:
            self._t0 = t
        elif self._prev_y is not None:
            ds, dpsi = odometry_increments(y[4:6] - self._prev_y[4:6], self.chain)
            heading = self._pose[2] + dpsi / 2.0
            self._pose = self._pose + np.array(
                [ds * math.cos(heading), ds * math.sin(heading), dpsi]
            )
        self._prev_t, self._prev_y = t, y
        part = kinematic_part(rates, theta_a, self.chain, self.est_cfg, self.v_eps)
        if t - self._t0 < self.est_cfg.rate_window:
            part["flags"] = part["flags"] | FLAG_WARMUP
        return SlipEstimate(t=np.array(t), pose=self._pose.copy(), **part)


# --------------------------------------------------------------------------- batch


class _AnglesLike(Protocol):
    t: Array
    phi: Array
    theta: Array


def estimate_log(
    log_or_arrays: _AnglesLike | Sequence[npt.ArrayLike],
    rover_cfg: RoverConfig | None = None,
    est_cfg: EstimatorConfig | None = None,
) -> SlipEstimate:
    """The whole log at once: same results as feeding :class:`SlipEstimator` row by row.

    ``log_or_arrays`` is a :class:`rover_env.logs.DriveLog` (or anything with ``t``, ``phi``,
    ``theta``) or a tuple ``(t (N,), phi (N, 6), theta (N, 5))``. ``rover_cfg`` defaults to the
    log's ``meta.rover`` when there is one, else the shipped Proto-Explorer.
    """
    if isinstance(log_or_arrays, Sequence):
        if len(log_or_arrays) != 3:
            raise ValueError("give (t, phi, theta)")
        t_in, phi_in, theta_in = log_or_arrays
        meta = None
    else:
        t_in, phi_in, theta_in = log_or_arrays.t, log_or_arrays.phi, log_or_arrays.theta
        meta = getattr(log_or_arrays, "meta", None)
    if rover_cfg is None:
        rover_cfg = load_rover(meta.rover) if meta is not None else RoverConfig()
    est = est_cfg or EstimatorConfig()
    t = np.array(t_in, dtype=np.float64).reshape(-1)
    phi = np.array(phi_in, dtype=np.float64)
    theta = np.array(theta_in, dtype=np.float64)
    _check_sample(phi, theta)
    if phi.shape != (t.size, 6) or theta.shape != (t.size, 5):
        raise ValueError(f"shapes disagree: t {t.shape}, phi {phi.shape}, theta {theta.shape}")
    if t.size == 0 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("time must be finite, non-empty and strictly increasing")

    chain = kin.ChainGeometry.from_config(rover_cfg, est.radii(rover_cfg))
    v_eps = rover_cfg.tire.v_eps if est.v_eps is None else float(est.v_eps)
    y = np.concatenate([phi, theta], axis=1)
    if est.rate_method == "lsq":
        rates = _lsq_rates_batch(t, y, est.rate_window)
    else:
        rates = _lowpass_rates_batch(t, y, est.rate_window)
    part = kinematic_part(rates, theta, chain, est, v_eps)
    part["flags"] = part["flags"] | np.where(t - t[0] < est.rate_window, FLAG_WARMUP, 0)[:, None]

    ds, dpsi = odometry_increments(np.diff(phi[:, 4:6], axis=0), chain)
    pose = np.zeros((t.size, 3))
    # Sequential sums, in the streaming form's order, so both agree to rounding.
    yaw = np.concatenate([[0.0], np.cumsum(dpsi)])
    heading = yaw[:-1] + dpsi / 2.0
    pose[1:, 0] = np.cumsum(ds * np.cos(heading))
    pose[1:, 1] = np.cumsum(ds * np.sin(heading))
    pose[:, 2] = yaw
    return SlipEstimate(t=t, pose=pose, **part)
