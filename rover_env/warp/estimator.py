"""The slip estimator for N rovers on a torch device: :class:`BatchSlipEstimator` in torch.

Same arithmetic as the numpy estimator (``rover_env.estimation.estimator``): least-squares
rates over the last ``rate_window`` seconds of wheel and joint angles, the chain
kinematics of SPEC §2 (eqs. 1–10), slip ratios, reliability flags and dead reckoning from
the free wheels. Every tensor stays on the device and no method waits for it (no host
copies), so :class:`rover_env.warp.env.WarpRoverEnv` runs it between physics steps.

Torch rather than Warp kernels: the work is a few hundred elementwise operations on
(n, 11) and (n, window) tensors, which torch runs as they are, on CPU or GPU, without a
kernel compile; the numbers it returns feed torch (the env's observation) directly.

Differences from the numpy form, all of which leave the results equal to float32 rounding
(tests/test_warp_estimator.py):

* the window is a ring of ``capacity`` samples per rover: a sample leaves it when it is
  older than the window or when ``capacity`` newer samples have come (numpy keeps every
  sample of the window). Size it to the samples a window holds (the env does);
* the slope is computed about the window's mean time (the same least-squares line as
  numpy's normal equations, which cancel more digits in float32);
* ``ids`` may also be a boolean mask over all rovers, with inputs for all of them: rows
  outside it are left alone, without the host sync that selecting rows would cost;
* the checks that need the host (finite input, increasing time, a sample before an
  estimate, no sample lost from a full ring) run only with ``validate=True``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch

from rover_env import kinematics as kin
from rover_env.config import RoverConfig
from rover_env.estimation.estimator import (
    FLAG_FREE_WHEELS,
    FLAG_SLOW_WHEEL,
    FLAG_STANDSTILL,
    FLAG_WARMUP,
    WINDOW_SLACK,
    EstimatorConfig,
    SlipEstimator,
)

__all__ = ["TorchSlipEstimate", "TorchSlipEstimator"]

Ids = torch.Tensor | None


@dataclass(frozen=True)
class TorchSlipEstimate:
    """:class:`~rover_env.estimation.estimator.SlipEstimate`'s fields with a leading rover
    axis (k, ...), as tensors on the estimator's device; ``flags`` is int64."""

    t: torch.Tensor
    phi_rate: torch.Tensor
    theta_rate: torch.Tensor
    nominal_rate: torch.Tensor
    actual_rate: torch.Tensor
    slippage: torch.Tensor
    slip_ratio: torch.Tensor
    seg_velocity: torch.Tensor
    seg_omega: torch.Tensor
    seg_yaw_rate: torch.Tensor
    pose: torch.Tensor
    flags: torch.Tensor

    @property
    def reliable(self) -> torch.Tensor:
        """(k, 4) True where no flag is set."""
        return self.flags == 0


def _rot(axis: int, angle: torch.Tensor) -> torch.Tensor:
    """kinematics.axis_rotation in torch: (..., 3, 3)."""
    c, s = torch.cos(angle), torch.sin(angle)
    one, zero = torch.ones_like(angle), torch.zeros_like(angle)
    if axis == 0:
        rows = [[one, zero, zero], [zero, c, -s], [zero, s, c]]
    elif axis == 1:
        rows = [[c, zero, s], [zero, one, zero], [-s, zero, c]]
    else:
        rows = [[c, -s, zero], [s, c, zero], [zero, zero, one]]
    return torch.stack([torch.stack(r, dim=-1) for r in rows], dim=-2)


def _mv(m: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    return (m * v[..., None, :]).sum(-1)


def _mtv(m: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    return (m * v[..., :, None]).sum(-2)


class TorchSlipEstimator:
    """``BatchSlipEstimator`` for ``n`` rovers on ``device`` in ``dtype``; see the module
    docstring. ``capacity``: samples kept per rover (at least what one window holds)."""

    def __init__(
        self,
        rover_cfg: RoverConfig,
        n: int,
        est_cfg: EstimatorConfig | None = None,
        device: str | torch.device = "cpu",
        dtype: torch.dtype = torch.float32,
        capacity: int = 64,
        validate: bool = False,
    ) -> None:
        one = SlipEstimator(rover_cfg, est_cfg)
        if one.est_cfg.rate_method != "lsq":
            raise NotImplementedError("TorchSlipEstimator implements rate_method='lsq' only")
        if capacity < 2:
            raise ValueError(f"capacity must be >= 2, got {capacity}")
        self.est_cfg = est = one.est_cfg
        self.n, self.capacity, self.validate = int(n), int(capacity), bool(validate)
        self.device, self.dtype = torch.device(device), dtype
        chain = one.chain
        kw: dict[str, Any] = {"device": self.device, "dtype": dtype}
        self._radii = torch.tensor(chain.wheel_radii, **kw)
        self._half_track = float(chain.half_track)
        self._link_a = torch.tensor(chain.link_a, **kw)
        self._anchor = torch.tensor(chain.joint_anchor, **kw)
        self._v_eps = float(one.v_eps)
        self._limit = est.rate_window * (1 + WINDOW_SLACK)
        # times in float64 whatever ``dtype``: the window's edge is a comparison of time
        # differences, which float32 would round differently from numpy
        t64: dict[str, Any] = {"device": self.device, "dtype": torch.float64}
        self._t = torch.full((n, capacity), -torch.inf, **t64)
        self._y = torch.zeros(n, capacity, 11, **kw)
        self._head = torch.zeros(n, dtype=torch.int64, device=self.device)
        self._last_t = torch.zeros(n, **t64)
        self._last_y = torch.zeros(n, 11, **kw)
        self._t0 = torch.zeros(n, **t64)
        self._pose = torch.zeros(n, 3, **kw)
        self._started = torch.zeros(n, dtype=torch.bool, device=self.device)
        self._rows = torch.arange(n, device=self.device)

    # ------------------------------------------------------------------ rows
    def _mask(self, ids: Ids) -> torch.Tensor:
        """The rovers ``ids`` names, as a boolean mask (n,)."""
        if ids is None:
            return torch.ones(self.n, dtype=torch.bool, device=self.device)
        ids = torch.as_tensor(ids, device=self.device)
        if ids.dtype == torch.bool:
            return ids.reshape(self.n)
        m = torch.zeros(self.n, dtype=torch.bool, device=self.device)
        m[ids.reshape(-1).long()] = True
        return m

    def _full(self, ids: Ids, x: Any, width: int, dtype: torch.dtype | None = None) -> torch.Tensor:
        """Inputs for the rows ``ids`` names, spread to all n rows (others zero)."""
        dtype = dtype or self.dtype
        x = torch.as_tensor(x, device=self.device, dtype=dtype)
        if ids is None or torch.as_tensor(ids).dtype == torch.bool:
            return x.reshape(self.n, width)
        idx = torch.as_tensor(ids, device=self.device).reshape(-1).long()
        out = torch.zeros(self.n, width, device=self.device, dtype=dtype)
        out[idx] = x.reshape(idx.numel(), width)
        return out

    def reset(self, ids: Ids = None) -> None:
        """Forget rovers ``ids`` (default all): their next sample starts a new drive."""
        m = self._mask(ids)
        self._t.masked_fill_(m[:, None], -torch.inf)
        self._pose.masked_fill_(m[:, None], 0.0)
        self._started &= ~m

    # ------------------------------------------------------------------ samples
    def push(self, ids: Ids, t: Any, phi: Any, theta: Any) -> None:
        """One sample for each rover of ``ids`` (None: all; indices; or a boolean mask with
        inputs for every rover): times (k,), wheel angles (k, 6), joint angles (k, 5)."""
        m = self._mask(ids)
        t_a = self._full(ids, t, 1, torch.float64)[:, 0]
        y = torch.cat([self._full(ids, phi, 6), self._full(ids, theta, 5)], dim=1)
        started = self._started
        if self.validate:
            self._check(m, t_a, y)
        # dead reckoning from the free wheels' angle increments (SlipEstimator.update)
        d = y[:, 4:6] - self._last_y[:, 4:6]
        left, right = self._radii[4] * d[:, 0], self._radii[5] * d[:, 1]
        ds, dpsi = (right + left) / 2.0, (right - left) / (2.0 * self._half_track)
        heading = self._pose[:, 2] + dpsi / 2.0
        step = torch.stack([ds * torch.cos(heading), ds * torch.sin(heading), dpsi], dim=1)
        move = m & started
        self._pose = torch.where(move[:, None], self._pose + step, self._pose)
        self._t0 = torch.where(m & ~started, t_a, self._t0)
        # the ring: the new sample over the oldest slot
        slot = self._head
        old_t = self._t[self._rows, slot]
        self._t[self._rows, slot] = torch.where(m, t_a, old_t)
        self._y[self._rows, slot] = torch.where(m[:, None], y, self._y[self._rows, slot])
        self._head = torch.where(m, (slot + 1) % self.capacity, slot)
        self._last_t = torch.where(m, t_a, self._last_t)
        self._last_y = torch.where(m[:, None], y, self._last_y)
        self._started = started | m

    def _check(self, m: torch.Tensor, t: torch.Tensor, y: torch.Tensor) -> None:
        if not (torch.isfinite(y[m]).all() and torch.isfinite(t[m]).all()):
            raise ValueError("wheel and joint angles and time must be finite")
        back = m & self._started & (t <= self._last_t)
        if back.any():
            i = int(torch.nonzero(back)[0, 0])
            raise ValueError(f"time must increase: {float(self._last_t[i])!r} then {float(t[i])!r}")
        lost = m & (t - self._t[self._rows, self._head] <= self._limit)
        if lost.any():
            raise ValueError(f"capacity {self.capacity} is less than the samples of one window")

    # ------------------------------------------------------------------ estimates
    def _rates(self) -> torch.Tensor:
        """Least-squares slopes (n, 11) over each rover's window, about its mean time."""
        tau64 = self._t - self._last_t[:, None]
        valid = -tau64 <= self._limit
        w = valid.to(self.dtype)
        cnt = w.sum(1)
        tau = torch.where(valid, tau64, 0.0).to(self.dtype)
        mean = tau.sum(1) / cnt.clamp(min=1.0)
        dt = (tau - mean[:, None]) * w
        z = (self._y - self._last_y[:, None, :]) * w[..., None]
        den = (dt * dt).sum(1)
        ok = (cnt >= 2) & (den > 0)
        slope = (dt[..., None] * z).sum(1) / torch.where(ok, den, 1.0)[:, None]
        return torch.where(ok[:, None], slope, 0.0)

    def _chain(
        self, theta: torch.Tensor, thd: torch.Tensor, w3: torch.Tensor, v3: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """kinematics.chain_motion: (omega, velocity) (n, 3, 3), each segment in its own axes."""
        axes = {name: "xyz".index(a) for name, a in kin.JOINT_AXES.items()}
        rots = {name: _rot(axes[name], theta[:, i]) for i, name in enumerate(kin.JOINT_AXES)}
        couple: dict[int, torch.Tensor] = {}
        for child, names in kin.SEGMENT_JOINTS.items():
            r = rots[names[0]]
            for name in names[1:]:
                r = r @ rots[name]
            couple[child] = r
        q3 = torch.eye(3, device=self.device, dtype=self.dtype).expand_as(couple[3])
        q2 = couple[3].transpose(-1, -2)
        q1 = q2 @ couple[2].transpose(-1, -2)
        q = {1: q1, 2: q2, 3: q3}
        omega, vel = {3: w3}, {3: v3}
        for child in (3, 2):
            names = kin.SEGMENT_JOINTS[child]
            w_rel = torch.zeros_like(w3)
            for k, name in enumerate(names):
                e = torch.zeros_like(w3)
                e[:, axes[name]] = 1.0
                for later in names[k + 1 :]:
                    e = _mtv(rots[later], e)
                w_rel = w_rel + e * thd[:, kin.JOINTS.index(name), None]
            w_c, v_c, qc, qp = omega[child], vel[child], q[child], q[child - 1]
            w_p = w_c - _mv(qc, w_rel)
            v_anchor = v_c + torch.linalg.cross(w_c, _mv(qc, self._anchor.expand_as(w3)))
            v_p = v_anchor + torch.linalg.cross(w_p, -_mv(qp, self._link_a.expand_as(w3)))
            omega[child - 1], vel[child - 1] = w_p, v_p
        w_own = torch.stack([_mtv(q[s], omega[s]) for s in (1, 2, 3)], dim=1)
        v_own = torch.stack([_mtv(q[s], vel[s]) for s in (1, 2, 3)], dim=1)
        return w_own, v_own

    def estimate(self, ids: Ids = None) -> TorchSlipEstimate:
        """The estimate at each listed rover's newest sample (as ``BatchSlipEstimator``),
        fields with a leading axis over ``ids`` (all n rovers for None or a mask)."""
        if self.validate and not bool(self._started[self._mask(ids)].all()):
            raise RuntimeError("estimate() needs at least one sample since reset")
        est, radii, r = self.est_cfg, self._radii, self._half_track
        rates = self._rates()
        theta = self._last_y[:, 6:]
        phi_rate, theta_rate = rates[:, :6], rates[:, 6:]
        tread = phi_rate[:, 4:] * radii[4:]
        zero = torch.zeros_like(tread[:, 0])
        w3 = torch.stack([zero, zero, (tread[:, 1] - tread[:, 0]) / (2.0 * r)], dim=1)
        v3 = torch.stack([(tread[:, 1] + tread[:, 0]) / 2.0, zero, zero], dim=1)
        omega, vel = self._chain(theta, theta_rate, w3, v3)
        vx, wz = vel[:, :2, 0], omega[:, :2, 2]
        left, right = vx - r * wz, vx + r * wz
        nominal = torch.stack([left[:, 0], right[:, 0], left[:, 1], right[:, 1]], dim=1)
        nominal = nominal / radii[:4]
        actual = phi_rate[:, :4]
        hub, wheel = radii[:4] * nominal, radii[:4] * actual
        total = hub + wheel
        direction = torch.sign(torch.where(total == 0.0, hub, total))
        den = torch.clamp(torch.maximum(hub.abs(), wheel.abs()), min=self._v_eps)
        slip = torch.clamp(direction * (hub - wheel) / den, -1.0, 1.0)

        standstill = v3[:, 0].abs() < est.min_speed
        ratio = (tread[:, 1] - tread[:, 0]).abs() / torch.clamp(
            (tread[:, 1] + tread[:, 0]).abs(), min=1e-12
        )
        side_slip = torch.atan2(vel[:, :2, 1].abs(), vel[:, :2, 0].abs())
        free_bad = ~standstill & (
            (ratio > est.max_free_wheel_ratio) | (side_slip > est.max_side_slip).any(dim=1)
        )
        slow = torch.maximum(nominal.abs(), actual.abs()) * radii[:4] < est.min_speed
        warm = (self._last_t - self._t0) < est.rate_window
        flags = (
            (standstill.long() * FLAG_STANDSTILL)[:, None]
            | (free_bad.long() * FLAG_FREE_WHEELS)[:, None]
            | slow.long() * FLAG_SLOW_WHEEL
            | (warm.long() * FLAG_WARMUP)[:, None]
        )
        out = TorchSlipEstimate(
            t=self._last_t,
            phi_rate=phi_rate,
            theta_rate=theta_rate,
            nominal_rate=nominal,
            actual_rate=actual,
            slippage=actual - nominal,
            slip_ratio=slip,
            seg_velocity=vel,
            seg_omega=omega,
            seg_yaw_rate=omega[:, :, 2],
            pose=self._pose.clone(),
            flags=flags,
        )
        if ids is None or torch.as_tensor(ids).dtype == torch.bool:
            return out
        idx = torch.as_tensor(ids, device=self.device).reshape(-1).long()
        return TorchSlipEstimate(**{k: getattr(out, k)[idx] for k in out.__dataclass_fields__})
