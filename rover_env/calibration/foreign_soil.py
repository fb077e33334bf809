"""Loose-soil contact of the second log generator, written apart from :mod:`rover_env.soil`.

The same steady-state equations (``shared/SOIL.md``: Bekker pressure-sinkage, Wong-Reece
stress distribution, Janosi-Hanamoto shear, n = n0 + n1 |s|) and the same soil constants,
but another implementation and another dynamic design, on purpose (issue 16, item 6):

* slip and travel direction: SOIL.md's definition, :func:`rover_env.soil.slip_and_direction`
  with this generator's 5 cm/s floor (a definition, not a design);
* quadrature: Gauss-Legendre, ``NODES`` points on each side of the maximum-stress angle
  (the project: its own node scheme in :func:`rover_env.soil.stress_integrals`);
* sinkage: the rigid wheel's penetration of a flat soil surface, no state of its own and
  no memory (the project: a sinkage state with damping, a dug hole and a rut map the
  following wheels run in), so a following wheel meets fresh soil;
* damping: the soil's ``damping`` (N s/m, the same number the project damps its sinkage
  rate with) on the hub's vertical speed while in contact; the tire's ``D_z`` (72 N s/m)
  let the rover bounce off a stiff sand (k_phi 1e7) at this explicit step;
* wheel spin: semi-implicit through the resisting torque (bisection on the spin rate after
  the step), as this generator's tire does.

Used by :class:`rover_env.calibration.foreign_logs.ForeignRover` for the ``loose_soil``
effect, with the constants :func:`rover_env.sim.simulator.effect_soil` would use.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from rover_env.soil import SoilParams, slip_and_direction

Array = NDArray[np.float64]

NODES = 6
"""Gauss-Legendre points per region (front of, and behind, the maximum-stress angle)."""
_GX, _GW = np.polynomial.legendre.leggauss(NODES)
V_EPS = 0.05
"""Slip regularisation speed (m/s), as this generator's tire."""


class WheelSoil(NamedTuple):
    """Soil forces on each wheel in its own frame (N, N m); ``s`` is Wong's slip."""

    F_x: Array
    F_y: Array
    F_z: Array
    T: Array
    s: Array


def _angles(h: Array, radius: float, lam: float) -> tuple[Array, Array, Array]:
    """Sinkage clipped to [0, r], entry angle theta_f and exit angle theta_r (SOIL.md)."""
    h = np.clip(h, 0.0, radius)
    return h, np.arccos(1.0 - h / radius), -np.arccos(1.0 - lam * h / radius)


def _region(lo: Array, hi: Array) -> tuple[Array, Array]:
    """Nodes (n, NODES) and weights of Gauss-Legendre on each row's [lo, hi]."""
    half = 0.5 * (hi - lo)
    return (lo + half)[:, None] + half[:, None] * _GX, half[:, None] * _GW


def wheel_soil(
    h: Array,
    s: Array,
    d: Array,
    tan_beta: Array,
    radius: float,
    width: float,
    p: SoilParams,
) -> WheelSoil:
    """Steady-state forces at sinkage ``h`` (m), slip ``s``, direction ``d``, tan(slip angle)."""
    r, b = radius, width
    h, t_f, t_r = _angles(h, r, p.lam)
    t_m = np.clip((p.a0 + p.a1 * s) * t_f, t_r, t_f)
    n = (p.n0 + p.n1 * np.abs(s))[:, None]
    k_s = p.k_c / b + p.k_phi
    cf = np.cos(t_f)[:, None]

    def sigma(theta: Array) -> Array:
        return np.asarray(k_s * np.maximum(r * (np.cos(theta) - cf), 0.0) ** n)

    th_f, w_f = _region(t_m, t_f)
    th_r, w_r = _region(t_r, t_m)
    span = np.maximum(t_m - t_r, 1e-12)[:, None]
    th_eq = t_f[:, None] - (th_r - t_r[:, None]) / span * (t_f - t_m)[:, None]
    theta = np.concatenate([th_f, th_r], axis=1)
    w = np.concatenate([w_f, w_r], axis=1)
    sig = np.concatenate([sigma(th_f), sigma(th_eq)], axis=1)
    tf_ = t_f[:, None]
    one_s = (1.0 - s)[:, None]
    j_x = r * (tf_ - theta - one_s * (np.sin(tf_) - np.sin(theta)))
    j_y = r * one_s * (tf_ - theta) * tan_beta[:, None]
    strength = p.c + sig * math.tan(math.radians(p.phi_deg))
    tau_x = strength * np.sign(j_x) * (1.0 - np.exp(-np.abs(j_x) / p.k_x))
    tau_y = strength * np.sign(j_y) * (1.0 - np.exp(-np.abs(j_y) / p.k_y))
    c, sn = np.cos(theta), np.sin(theta)
    F_x = d * r * b * np.sum(w * (tau_x * c - sig * sn), axis=1)
    F_z = r * b * np.sum(w * (tau_x * sn + sig * c), axis=1)
    F_y = -r * b * np.sum(w * tau_y, axis=1)
    T = d * r * r * b * np.sum(w * tau_x, axis=1)
    return WheelSoil(F_x, F_y, F_z, T, s)


def at_spin(
    omega: Array,
    h: Array,
    v_x: Array,
    v_y: Array,
    radius: float,
    width: float,
    p: SoilParams,
) -> WheelSoil:
    """:func:`wheel_soil` at the wheels' spin rates ``omega`` (rad/s) and contact velocities."""
    s, d = slip_and_direction(v_x, radius * omega, V_EPS)
    tan_beta = v_y / np.maximum(np.abs(v_x), V_EPS)
    return wheel_soil(h, s, d, tan_beta, radius, width, p)


def spin_after_step(
    omega: Array,
    torque: Array,
    k_w: Array,
    h: Array,
    v_x: Array,
    v_y: Array,
    radius: float,
    width: float,
    p: SoilParams,
    iterations: int = 7,
) -> Array:
    """The spin rate w' = omega + k_w (torque - T(w')) with the soil's resisting torque T at
    w' itself (semi-implicit: a light free wheel on stiff shear stays stable at this step).
    T rises with the spin, so the root lies within T's bound on either side of the explicit
    step."""
    hc, t_f, t_r = _angles(h, radius, p.lam)
    # |T| <= r^2 b (t_f - t_r) (c + sigma_max tan(phi)), sigma_max = k_s h^n0 (h < 1 m).
    sig_max = (p.k_c / width + p.k_phi) * hc**p.n0
    tb = radius * radius * width * (t_f - t_r) * (p.c + sig_max * math.tan(math.radians(p.phi_deg)))
    tb = tb * 1.01 + 1e-9
    lo = omega + k_w * (torque - tb)
    hi = omega + k_w * (torque + tb)

    def g(w1: Array) -> Array:
        return np.asarray(
            w1 - omega - k_w * (torque - at_spin(w1, h, v_x, v_y, radius, width, p).T)
        )

    return monotone_root(g, lo, hi, iterations)


def monotone_root(g: Callable[[Array], Array], lo: Array, hi: Array, iterations: int) -> Array:
    """Root of each row of an increasing ``g`` bracketed by [lo, hi]: bisection, then a
    secant step between the last bracket ends (smooth in the inputs, no bisection noise).
    This generator's semi-implicit solves (tire force, soil spin) share it."""
    g_lo, g_hi = g(lo), g(hi)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        g_mid = g(mid)
        neg = g_mid < 0
        lo, g_lo = np.where(neg, mid, lo), np.where(neg, g_mid, g_lo)
        hi, g_hi = np.where(neg, hi, mid), np.where(neg, g_hi, g_mid)
    den = g_hi - g_lo
    return np.asarray(np.where(den > 0, lo - g_lo * (hi - lo) / np.where(den > 0, den, 1.0), lo))


__all__ = [
    "NODES",
    "V_EPS",
    "WheelSoil",
    "at_spin",
    "monotone_root",
    "spin_after_step",
    "wheel_soil",
]
