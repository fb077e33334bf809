"""Loose soil (SOIL.md): Bekker pressure-sinkage, Janosi-Hanamoto shear, Ishigami's stress
distribution, integrated by this module's own fixed Gauss-Legendre rule.

Choices where SOIL.md leaves the design open:

- **Sinkage** ``h`` is geometric: the depth of the rigid wheel's lowest point below the local soil
  surface (the tire's own compliance is neglected on soil). The normal force is SOIL.md's F_z(h, s)
  plus a soil damping ``C_SOIL * dh/dt`` (70 N s/m, the size of SPEC's D_z), floored at 0.
- **Slip** is Wong's ``s = -S`` of the transient-slip state of :mod:`tire` (same relaxation
  length), so at rest the soil, too, holds the wheel as a spring.
- **Excavation** (sustained spin buries a wheel): each wheel digs the surface beneath it at
  ``DIG * max(0, s - S_DIG) * |v_w|`` and leaves the hole behind at ``|v_x| / L_DIG``
  (DIG 0.05, S_DIG 0.2, L_DIG 0.1 m). No rut memory along the path (a wheel passing a rut of
  the wheel ahead sees fresh soil): the ground of this generator forgets.
- **Quadrature**: 12 Gauss points on [theta_r, theta_m] and 12 on [theta_m, theta_f] (the normal
  stress has a kink at theta_m), all six wheels at once.
- Presets: ``regolith`` (SOIL.md's lunar simulant, lambda 0.6: the middle of SOIL.md's range, where
  the drawbar pull crosses zero at a few percent of slip as single-wheel tests on simulants show);
  ``dry_sand`` (Wong, Theory of Ground Vehicles, 4th ed., Table 2.3 "dry sand": n 1.1,
  k_c 0.99 kN/m^(n+1), k_phi 1528.43 kN/m^(n+2), c 1.04 kPa, phi 28 deg; k_x = k_y 0.025 m,
  Ishigami's a0 0.4, a1 0.15, lambda 0.6). ``k_phi`` of either is scaled by the effect's factor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

C_SOIL = 70.0
DIG = 0.05
S_DIG = 0.2
L_DIG = 0.1
V_EPS = 1e-3


@dataclass(frozen=True)
class Soil:
    c: float
    phi_deg: float
    k_c: float
    k_phi: float
    n0: float
    n1: float
    k_x: float
    k_y: float
    a0: float
    a1: float
    lam: float


PRESETS: dict[str, Soil] = {
    "regolith": Soil(800.0, 37.2, 1.37e3, 8.14e5, 1.0, 0.0, 0.036, 0.020, 0.40, 0.15, 0.6),
    "dry_sand": Soil(1040.0, 28.0, 0.99e3, 1528.43e3, 1.1, 0.0, 0.025, 0.025, 0.40, 0.15, 0.6),
}


def preset(name: str, k_phi_factor: float = 1.0) -> Soil:
    base = PRESETS[name]
    return replace(base, k_phi=base.k_phi * k_phi_factor)


_GX, _GW = np.polynomial.legendre.leggauss(12)


def _nodes(a: Array, b: Array) -> tuple[Array, Array]:
    """Gauss nodes and weights mapped onto [a, b], per wheel: shapes (W, 12)."""
    half = 0.5 * (b - a)[:, None]
    mid = 0.5 * (b + a)[:, None]
    return mid + half * _GX[None, :], half * _GW[None, :]


def wheel_forces(
    soil: Soil,
    r: Array,
    b: float,
    h: Array,
    s: Array,
    tan_b: Array,
    tan_phi_scale: float | Array = 1.0,
) -> tuple[Array, Array, Array, Array]:
    """Steady-state (F_x, F_y, F_z, T) for forward travel (mirror for reverse in the caller).

    ``s`` Wong's slip in [-1, 1]; ``tan_b`` tan of the slip angle; ``h`` sinkage (m).
    F_x drawbar pull forward, F_y lateral (opposing sliding), F_z support, T resistive torque.
    """
    hh = np.clip(h, 0.0, r)
    live = h > 1e-7
    th_f = np.arccos(1.0 - hh / r)
    th_r = -np.arccos(1.0 - soil.lam * hh / r)
    th_m = np.clip((soil.a0 + soil.a1 * s) * th_f, th_r, th_f)
    n = soil.n0 + soil.n1 * np.abs(s)
    ks = soil.k_c / b + soil.k_phi
    tan_phi = np.broadcast_to(
        math.tan(math.radians(soil.phi_deg)) * np.asarray(tan_phi_scale), r.shape
    )[:, None]
    th_a, w_a = _nodes(th_r, th_m)  # rear region
    th_b, w_b = _nodes(th_m, th_f)  # front region
    th = np.concatenate([th_a, th_b], axis=1)
    w = np.concatenate([w_a, w_b], axis=1)
    tf, tr, tm = th_f[:, None], th_r[:, None], th_m[:, None]
    rr = r[:, None]
    nn = n[:, None]
    span = np.maximum(tm - tr, 1e-12)
    th_eq = np.where(th < tm, tf - (th - tr) / span * (tf - tm), th)
    depth = np.maximum(rr * (np.cos(th_eq) - np.cos(tf)), 0.0)
    sigma = ks * depth**nn
    ss = s[:, None]
    jx = rr * (tf - th - (1.0 - ss) * (np.sin(tf) - np.sin(th)))
    jy = rr * (1.0 - ss) * (tf - th) * tan_b[:, None]
    tmax = soil.c + sigma * tan_phi
    tau_x = tmax * np.sign(jx) * (1.0 - np.exp(-np.abs(jx) / soil.k_x))
    tau_y = tmax * np.sign(jy) * (1.0 - np.exp(-np.abs(jy) / soil.k_y))
    rb = r * b
    fx = rb * np.sum(w * (tau_x * np.cos(th) - sigma * np.sin(th)), axis=1)
    fz = rb * np.sum(w * (tau_x * np.sin(th) + sigma * np.cos(th)), axis=1)
    fy = -rb * np.sum(w * tau_y, axis=1)
    tq = r * rb * np.sum(w * tau_x, axis=1)
    z = np.zeros_like(fx)
    return (
        np.where(live, fx, z),
        np.where(live, fy, z),
        np.where(live, fz, z),
        np.where(live, tq, z),
    )


def wong_slip(vx: Array, vw: Array) -> tuple[Array, Array]:
    """SOIL.md's travel direction and slip (used by tests; the simulator uses the tire state)."""
    d = np.where(np.abs(vw) >= np.abs(vx), np.sign(vw), np.sign(vx))
    d = np.where(d == 0.0, 1.0, d)
    den = np.maximum(np.maximum(np.abs(vw), np.abs(vx)), V_EPS)
    return d, np.clip(d * (vw - vx) / den, -1.0, 1.0)


def static_sinkage(soil: Soil, r: float, b: float, load: float) -> float:
    """Sinkage at which a wheel at zero slip carries ``load`` (bisection)."""
    lo, hi = 0.0, r
    one = np.ones(1)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        fz = wheel_forces(soil, r * one, b, mid * one, 0 * one, 0 * one)[2][0]
        lo, hi = (mid, hi) if fz < load else (lo, mid)
    return 0.5 * (lo + hi)
