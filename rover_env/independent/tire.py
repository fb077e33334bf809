"""Gim's tire (SPEC §3, equations (10)-(17)) with a transient-slip state, written from SPEC alone.

Choices where SPEC is silent:

- **Slip is a state, not an algebraic ratio.** (10) is singular at rest and, with C_s = 100 N on a
  1 g wheel inertia, infinitely stiff near it. Each wheel carries a longitudinal deflection ``u_x``
  and a lateral one ``u_y`` (relaxation length ``sigma``, Pacejka/Bernard-Clover style):
  ``du_x/dt = (v_x - v_w) - max(|v_x|, |v_w|, v_min) u_x / sigma``,
  ``du_y/dt = v_y - max(|v_x|, v_min) u_y / sigma``.
  In steady rolling ``u_x / sigma`` is exactly SPEC's ``(v_x - v_w) / max(|v_x|, |v_w|)`` and
  ``u_y / sigma`` is ``tan(alpha) = v_y / v_x``; at rest the tire is a spring (it holds the
  rover). sigma = 0.04 m (about half the 0.14 m static contact length), v_min = 2 mm/s.
  The states are advanced with the exact exponential of the linear update over one step.
- **Rolling radius** ``r_e = d - delta/3`` (the classic effective rolling radius of a deflected
  pneumatic tire: between the loaded radius d - delta and d, as SPEC asks), with ``delta`` the
  current compression. The force acts at the ground point, a torque arm of ``d - delta``.
- F_x, F_y follow (13)-(16) literally (the grip term plus the sliding term), as magnitudes opposing
  the patch's sliding; S_alpha follows (11) with the spin/skid split of the travel-relative slip.
- F_z (17) with compression ``delta`` and its rate, floored at 0.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

SIGMA = 0.04
V_MIN = 0.002
TAN_ALPHA_MAX = 5.0


def normal_force(delta: Array, delta_dot: Array, c_z: float, d_z: float) -> Array:
    """(17): F_z = max(0, C_z delta + D_z delta_dot), zero when not in contact."""
    fz = c_z * delta + d_z * delta_dot
    return np.where(delta > 0.0, np.maximum(fz, 0.0), 0.0)


def rolling_radius(d: Array, delta: Array) -> Array:
    """Effective rolling radius of the deflected tire, d - delta/3 (delta clipped to [0, d/2])."""
    return d - np.clip(delta, 0.0, 0.5 * d) / 3.0


def relax(u: Array, drive: Array, rate: Array, dt: float) -> Array:
    """Exact step of du/dt = drive - rate u over dt (rate > 0)."""
    e = np.exp(-rate * dt)
    return u * e + drive * (1.0 - e) / rate


def step_states(
    ux: Array, uy: Array, vx: Array, vy: Array, vw: Array, dt: float
) -> tuple[Array, Array]:
    """Advance the deflection states over one step; clamps keep |S| <= 1, |tan a| <= 5."""
    rate_x = np.maximum(np.maximum(np.abs(vx), np.abs(vw)), V_MIN) / SIGMA
    rate_y = np.maximum(np.abs(vx), V_MIN) / SIGMA
    ux = np.clip(relax(ux, vx - vw, rate_x, dt), -SIGMA, SIGMA)
    uy = np.clip(relax(uy, vy, rate_y, dt), -TAN_ALPHA_MAX * SIGMA, TAN_ALPHA_MAX * SIGMA)
    return ux, uy


def _grip(slip: Array, c: float, mu: Array, fz: Array) -> Array:
    """(13)/(14) magnitude for a slip magnitude ``slip`` (>= 0)."""
    safe_fz = np.maximum(fz, 1e-9)
    s_crit = 3.0 * mu * safe_fz / c  # (15)/(16)
    ln = np.maximum(1.0 - slip / s_crit, 0.0)  # (12)
    gripping = c * slip * ln**2 + mu * fz * (1.0 - 3.0 * ln**2 + 2.0 * ln**3)
    return np.where(slip < s_crit, gripping, mu * fz) * (fz > 0.0)


def gim_forces(
    ux: Array,
    uy: Array,
    travel: Array,
    fz: Array,
    mu_x: Array,
    mu_y: Array,
    c_s: float,
    c_alpha: float,
) -> tuple[Array, Array, Array]:
    """Contact-frame (F_x, F_y) from the states, and SPEC's travel-relative slip S.

    ``travel`` is sign(v_x + v_w) (+1 when zero). Returns (fx, fy, S).
    """
    q = ux / SIGMA  # (v_x - v_w) / max(|v_x|, |v_w|) in steady state
    s_travel = np.clip(travel * q, -1.0, 1.0)  # SPEC's S: > 0 skid, < 0 spin
    tan_a = uy / SIGMA
    s_alpha = np.where(s_travel > 0.0, np.abs(tan_a), (1.0 - np.abs(s_travel)) * np.abs(tan_a))
    fx = -np.sign(q) * _grip(np.abs(s_travel), c_s, mu_x, fz)
    fy = -np.sign(tan_a) * _grip(s_alpha, c_alpha, mu_y, fz)
    return fx, fy, s_travel
