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

Used by :class:`rover_env.generators.foreign_logs.ForeignRover` for the ``loose_soil``
effect, with the constants :func:`rover_env.sim.build.effect_soil` would use.
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


class _Contact(NamedTuple):
    """What the sinkage alone fixes (the spin solve evaluates many slips at one sinkage)."""

    h: Array
    t_f: Array
    t_r: Array
    cf: Array
    tf_: Array
    sin_tf: Array


def _contact(h: Array, radius: float, lam: float) -> _Contact:
    hc, t_f, t_r = _angles(h, radius, lam)
    tf_ = t_f[:, None]
    return _Contact(hc, t_f, t_r, np.cos(t_f)[:, None], tf_, np.sin(tf_))


def _stresses(
    g: _Contact, s: Array, radius: float, width: float, p: SoilParams
) -> tuple[Array, Array, Array, Array]:
    """Nodes ``theta`` (n, 2 NODES), weights, normal stress and shear displacement j_x."""
    r, b = radius, width
    t_f, t_r, cf, tf_ = g.t_f, g.t_r, g.cf, g.tf_
    t_m = np.minimum(np.maximum((p.a0 + p.a1 * s) * t_f, t_r), t_f)
    n = (p.n0 + p.n1 * np.abs(s))[:, None]
    k_s = p.k_c / b + p.k_phi
    # Both regions in one array: front of t_m, then behind it (Gauss-Legendre on each).
    lo = np.concatenate([t_m, t_r])
    half = 0.5 * (np.concatenate([t_f, t_m]) - lo)
    nodes = ((lo + half)[:, None] + half[:, None] * _GX).reshape(2, -1, NODES)
    wts = (half[:, None] * _GW).reshape(2, -1, NODES)
    th_f, th_r = nodes[0], nodes[1]
    span = np.maximum(t_m - t_r, 1e-12)[:, None]
    th_eq = t_f[:, None] - (th_r - t_r[:, None]) / span * (t_f - t_m)[:, None]
    theta = np.concatenate([th_f, th_r], axis=1)
    w = np.concatenate([wts[0], wts[1]], axis=1)
    # sigma at the front nodes, and behind t_m at the equivalent front angles (SOIL.md).
    sig = k_s * np.maximum(r * (np.cos(np.concatenate([th_f, th_eq], axis=1)) - cf), 0.0) ** n
    one_s = (1.0 - s)[:, None]
    j_x = r * (tf_ - theta - one_s * (g.sin_tf - np.sin(theta)))
    return theta, w, sig, j_x


def _shear(sig: Array, j: Array, k: float, p: SoilParams, tan_phi: float) -> Array:
    """Janosi-Hanamoto shear stress at normal stress ``sig`` and shear displacement ``j``."""
    return np.asarray((p.c + sig * tan_phi) * np.sign(j) * (1.0 - np.exp(-np.abs(j) / k)))


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
    g = _contact(h, r, p.lam)
    theta, w, sig, j_x = _stresses(g, s, r, b, p)
    one_s = (1.0 - s)[:, None]
    j_y = r * one_s * (g.tf_ - theta) * tan_beta[:, None]
    tan_phi = math.tan(math.radians(p.phi_deg))
    tau_x = _shear(sig, j_x, p.k_x, p, tan_phi)
    tau_y = _shear(sig, j_y, p.k_y, p, tan_phi)
    c, sn = np.cos(theta), np.sin(theta)
    F_x = d * r * b * (w * (tau_x * c - sig * sn)).sum(axis=1)
    F_z = r * b * (w * (tau_x * sn + sig * c)).sum(axis=1)
    F_y = -r * b * (w * tau_y).sum(axis=1)
    T = d * r * r * b * (w * tau_x).sum(axis=1)
    return WheelSoil(F_x, F_y, F_z, T, s)


def _torque(g: _Contact, s: Array, d: Array, radius: float, width: float, p: SoilParams) -> Array:
    """The resisting torque of :func:`wheel_soil` alone (the spin solve needs no force)."""
    r, b = radius, width
    _, w, sig, j_x = _stresses(g, s, r, b, p)
    tau_x = _shear(sig, j_x, p.k_x, p, math.tan(math.radians(p.phi_deg)))
    return np.asarray(d * r * r * b * (w * tau_x).sum(axis=1))


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
    geo = _contact(h, radius, p.lam)
    # |T| <= r^2 b (t_f - t_r) (c + sigma_max tan(phi)), sigma_max = k_s h^n0 (h < 1 m).
    sig_max = (p.k_c / width + p.k_phi) * geo.h**p.n0
    tb = (
        radius
        * radius
        * width
        * (geo.t_f - geo.t_r)
        * (p.c + sig_max * math.tan(math.radians(p.phi_deg)))
    )
    tb = tb * 1.01 + 1e-9
    lo = omega + k_w * (torque - tb)
    hi = omega + k_w * (torque + tb)

    def g(w1: Array) -> Array:
        s, d = slip_and_direction(v_x, radius * w1, V_EPS)
        return np.asarray(w1 - omega - k_w * (torque - _torque(geo, s, d, radius, width, p)))

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
