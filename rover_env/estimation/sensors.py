"""Sensor realism for wheel encoders and joint potentiometers (resolution, noise, sample rate).

The simulator reports exact angles; the 1998 rover read its joints through potentiometers and
an A/D converter and its wheels through counters. What differentiating those readings costs
is the subject of the slip estimator, so the degradation is applied explicitly, with a seeded
``np.random.Generator`` the caller owns (runs are reproducible and independent streams are
the caller's choice).

Defaults (:class:`SensorConfig`), chosen as plausible for the period, not measured:

* joints: a single-turn potentiometer of 340 deg electrical travel read by a 10-bit A/D
  converter (5.8 mrad per count), with Gaussian noise of a quarter count (1.4 mrad, ~1 mV on
  a 5 V span: wiper and converter noise) added before conversion, as the analogue noise is;
* wheels: 0.01 rad per count (628 counts per wheel turn: a 157-line optical encoder read in
  quadrature, or far fewer lines on the motor side of the 150:1 gearhead), and no noise:
  counters count exactly, their error is the quantisation;
* sample rate: that of the log (the recorder's 50 Hz by default); set ``sample_rate_hz`` to
  log more slowly.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rover_env.config import ConfigError
from rover_env.logs import DriveLog

__all__ = ["SensorConfig", "SensorModel", "apply_sensors", "quantize"]

Array = npt.NDArray[np.float64]

JOINT_POT_COUNTS = 1024
JOINT_POT_TRAVEL = math.radians(340.0)
_JOINT_LSB = JOINT_POT_TRAVEL / JOINT_POT_COUNTS


@dataclass(frozen=True)
class SensorConfig:
    """Resolution (rad per count, 0 = continuous) and Gaussian noise (rad rms) per sensor."""

    wheel_resolution: float = 0.01
    wheel_noise: float = 0.0
    joint_resolution: float = _JOINT_LSB
    joint_noise: float = 0.25 * _JOINT_LSB
    sample_rate_hz: float | None = None
    """Rate the sensors are read at; None keeps every sample of the input."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if f.name == "sample_rate_hz":
                continue
            v = getattr(self, f.name)
            if isinstance(v, bool) or not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"sensors.{f.name} must be a finite number >= 0, got {v!r}")
        r = self.sample_rate_hz
        if r is not None and not (math.isfinite(r) and r > 0):
            raise ConfigError(f"sensors.sample_rate_hz must be > 0, got {r!r}")

    @classmethod
    def ideal(cls, sample_rate_hz: float | None = None) -> SensorConfig:
        """Exact readings: no quantisation, no noise."""
        return cls(0.0, 0.0, 0.0, 0.0, sample_rate_hz)


def quantize(x: npt.ArrayLike, resolution: float) -> Array:
    """Round to the nearest multiple of ``resolution``; 0 leaves ``x`` unchanged."""
    a = np.asarray(x, dtype=np.float64)
    if resolution == 0:
        return a.copy()
    return np.asarray(np.round(a / resolution) * resolution, dtype=np.float64)


class SensorModel:
    """Degrades readings one sample at a time, for a live loop (simulator or environment).

    Wheel angles are reported relative to the first reading, as a counter reset at start-up.
    """

    def __init__(self, cfg: SensorConfig, rng: np.random.Generator) -> None:
        self.cfg = cfg
        self.rng = rng
        self._phi0: Array | None = None

    def reset(self) -> None:
        self._phi0 = None

    @property
    def counter_zero(self) -> Array | None:
        """The wheel readings the counters count from (set by the first :meth:`read`)."""
        return self._phi0

    def read(self, phi: npt.ArrayLike, theta: npt.ArrayLike) -> tuple[Array, Array]:
        """(phi (6,), theta (5,)) as the rover's electronics would report them."""
        c = self.cfg
        p = np.array(phi, dtype=np.float64)
        if c.wheel_noise > 0:
            p = p + self.rng.normal(0.0, c.wheel_noise, p.shape)
        if self._phi0 is None:
            self._phi0 = p.copy()
        p = quantize(p - self._phi0, c.wheel_resolution)
        th = np.array(theta, dtype=np.float64)
        if c.joint_noise > 0:
            th = th + self.rng.normal(0.0, c.joint_noise, th.shape)
        return p, quantize(th, c.joint_resolution)


def _resample_index(t: Array, rate: float) -> npt.NDArray[np.intp]:
    """Indices of the first sample at or after each tick of ``rate`` (no sample twice)."""
    ticks = np.arange(t[0], t[-1] + 0.5 / rate, 1.0 / rate)
    idx = np.searchsorted(t, ticks - 1e-9 / rate, side="left")
    idx = np.unique(idx[idx < t.size])
    return np.asarray(idx, dtype=np.intp)


def apply_sensors(log: DriveLog, cfg: SensorConfig, rng: np.random.Generator) -> DriveLog:
    """A copy of ``log`` as read through ``cfg``'s sensors (commands and pose untouched).

    With ``sample_rate_hz`` set, rows are thinned to that rate (the log must be at least as
    fast); noise is drawn from ``rng`` in a fixed order (wheels, then joints, row-major).
    """
    idx = np.arange(log.t.size)
    rate = log.meta.sample_rate_hz
    if cfg.sample_rate_hz is not None:
        if cfg.sample_rate_hz > rate * (1 + 1e-9):
            raise ValueError(
                f"sensor rate {cfg.sample_rate_hz} Hz exceeds the log's {rate} Hz: cannot upsample"
            )
        idx = _resample_index(log.t, cfg.sample_rate_hz)
        rate = cfg.sample_rate_hz
    phi = log.phi[idx]
    theta = log.theta[idx]
    if cfg.wheel_noise > 0:
        phi = phi + rng.normal(0.0, cfg.wheel_noise, phi.shape)
    phi = quantize(phi - phi[0], cfg.wheel_resolution)
    if cfg.joint_noise > 0:
        theta = theta + rng.normal(0.0, cfg.joint_noise, theta.shape)
    theta = quantize(theta, cfg.joint_resolution)
    meta = dataclasses.replace(log.meta, sample_rate_hz=rate, extra=dict(log.meta.extra))
    return DriveLog(
        t=log.t[idx] - log.t[idx[0]],
        cmd=log.cmd[idx],
        phi=phi,
        theta=theta,
        pose=log.pose[idx],
        meta=meta,
        effort=log.effort[idx],
    )
