"""Loose soil: terramechanics wheel–soil contact (shared/SOIL.md), numpy only.

Two parts:

* the steady-state model of SOIL.md (:func:`soil_forces`): Wong–Reece normal and shear
  stresses over the contact arc, with Bekker pressure–sinkage, Janosi–Hanamoto shear, the
  entry/exit/maximum-stress angles of Ishigami et al. (2007) and the slip-sinkage exponent
  of Ding et al. (2011). It is a pure function of the contact velocities and the sinkage.
* the per-substep form the simulator integrates (:func:`soil_step`): the same stresses, fed
  with a transient slip and slip angle (relaxation-length states, as the Gim layer), a
  direction blend that stays well-posed at standstill, a surface that remembers ruts and a
  wheel that digs itself in under sustained slip. With the states settled it returns
  exactly :func:`soil_forces`; docs/soil.md derives the design and names its sources.

Quadrature: the stress integrals run over two arcs, behind and ahead of the maximum-stress
angle θ_m (where the normal-stress formula changes and the integrand has a kink), each with
:data:`NODES` Gauss–Legendre points. tests/test_soil.py bounds its error against adaptive
quadrature (below 1e-4 of F_z over random parameters, speeds and sinkages).

Frame and signs (SOIL.md): x along the wheel's heading, y left, z the ground normal; forces
are those of the soil on the wheel, ``T`` the resistive torque about the axle (the torque
the motor must supply: the soil's moment on the wheel is ``-T`` about the spin axis); slip
``s`` is Wong's (``s = -S`` of the Gim layer).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from rover_env.config import ConfigError, _load_yaml, _resolve, from_dict

__all__ = [
    "NODES",
    "SoilForces",
    "SoilParams",
    "SoilStep",
    "load_soil",
    "soil_forces",
    "soil_step",
    "static_sinkage",
    "stress_integrals",
]

FloatArray = npt.NDArray[np.float64]
ArrayLike = float | FloatArray

NODES = 8
"""Gauss–Legendre points per arc (two arcs per wheel)."""
_GL_X, _GL_W = np.polynomial.legendre.leggauss(NODES)
# Taylor coefficients of cos and sin/x in x^2 (to x^22): with the angle-addition rule they give
# the nodes' sines and cosines from one sin/cos of the arc's middle (|x| <= pi/2 here, where
# the truncation error is below 1e-16); the compiled plugin runs the same Horner steps.
_COS = tuple((-1) ** k / math.factorial(2 * k) for k in range(12))
_SIN = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(12))
V_EPS = 1e-3
"""Speed floor of the slip and slip-angle denominators (m/s), the Gim layer's v_eps."""
V_BLEND = 0.03
"""Speed (m/s) over which the forward and backward stress fields are blended at standstill.

The blend makes the zero-slip resistance a damper of slope 1.5 T0 / V_BLEND about rest,
applied explicitly; a free wheel (inertia I about its axle) stays stable while
1.5 r T0 dt / (I V_BLEND) < 2. At the rover's wheel (I 1.26e-3 kg m^2, r 0.085 m), dt 1 ms and
T0 <= 0.17 N m (every preset at 27 N) that needs V_BLEND > 8.6 mm/s: 30 mm/s keeps a margin
of 3.5 and is still well below driving speeds, where the blend is exactly one-sided."""
_MAX_TAN_BETA = 20.0
"""Bound of the transient slip angle's tangent (β < 87°): a wheel sliding sideways at
standstill integrates its lateral displacement; beyond this the shear is saturated anyway."""


@dataclass(frozen=True, slots=True)
class SoilParams:
    """Soil constants: SOIL.md's fields, then the dynamic model's (docs/soil.md).

    Units: c Pa, phi_deg degrees, k_c N/m^(n+1), k_phi N/m^(n+2), k_x and k_y m, the rest
    dimensionless. The dynamic fields only act away from steady state (damping of the
    sinkage rate, the hole a spinning wheel digs) or in ruts (rut_cell, the rut map's grid).
    """

    name: str = "regolith"
    c: float = 800.0
    phi_deg: float = 37.2
    k_c: float = 1.37e3
    k_phi: float = 8.14e5
    n0: float = 1.0
    n1: float = 0.0
    k_x: float = 0.036
    k_y: float = 0.020
    a0: float = 0.40
    a1: float = 0.15
    lam: float = 0.9
    damping: float = 150.0
    """Damping of the sinkage rate (N s/m): the soil's plastic flow dissipates; zero in steady state."""
    k_dig: float = 0.02
    """Depth dug per unit of slip travel (m per m of |v_w| - |v_x|) under a spinning wheel."""
    rut_cell: float = 0.025
    """Cell of the rut map (m): half the wheel's width, so a rut is two cells wide."""

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name == "name":
                continue
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ConfigError(f"soil {self.name}: {f.name} must be a finite number, got {v!r}")
        for key in ("k_x", "k_y", "n0", "rut_cell"):
            if getattr(self, key) <= 0:
                raise ConfigError(f"soil {self.name}: {key} must be > 0, got {getattr(self, key)}")
        for key in ("c", "k_phi", "n1", "damping", "k_dig"):
            if getattr(self, key) < 0:
                raise ConfigError(f"soil {self.name}: {key} must be >= 0, got {getattr(self, key)}")
        if not 0.0 <= self.phi_deg < 90.0:
            raise ConfigError(f"soil {self.name}: phi_deg must be in [0, 90), got {self.phi_deg}")
        if not 0.0 <= self.lam <= 1.0:
            raise ConfigError(f"soil {self.name}: lam must be in [0, 1], got {self.lam}")

    def k_s(self, width: float) -> float:
        """Bekker's modulus k_c / b + k_phi for a wheel of this width."""
        return self.k_c / width + self.k_phi

    def numbers(self) -> tuple[float, ...]:
        """The numeric fields in declaration order (the compiled plugin's soil table)."""
        return tuple(float(getattr(self, f.name)) for f in fields(self) if f.name != "name")


def load_soil(name_or_path: str | Path) -> SoilParams:
    """A soil preset by shipped name (``configs/soil/NAME.yaml``) or YAML path.

    The preset files carry ``description`` and ``source`` (the literature behind the
    numbers) beside the fields; those two keys are documentation and are not kept.
    """
    path = _resolve(name_or_path, "soil")
    data: Any = _load_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of soil parameters")
    data = {k: v for k, v in data.items() if k not in ("description", "source")}
    try:
        return from_dict(SoilParams, data)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


class SoilForces(NamedTuple):
    """Soil-on-wheel forces (N), resistive torque (N m) and the slips that produced them."""

    F_x: FloatArray
    F_y: FloatArray
    F_z: FloatArray
    T: FloatArray
    s: FloatArray
    beta: FloatArray


def _sincos_nodes(mid: FloatArray, half: FloatArray) -> tuple[FloatArray, FloatArray]:
    """sin and cos at the Gauss nodes mid + half * x_k, shape (..., NODES)."""
    a = half[..., None] * _GL_X
    a2 = a * a
    c = np.full_like(a, _COS[-1])
    sn = np.full_like(a, _SIN[-1])
    for k in range(len(_COS) - 2, -1, -1):
        c = c * a2 + _COS[k]
        sn = sn * a2 + _SIN[k]
    sa = a * sn
    sm = np.sin(mid)[..., None]
    cm = np.cos(mid)[..., None]
    return sm * c + cm * sa, cm * c - sm * sa


def stress_integrals(
    s: ArrayLike,
    tan_beta: ArrayLike,
    d: ArrayLike,
    h: ArrayLike,
    h_c: ArrayLike,
    radius: float,
    width: float,
    p: SoilParams,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """F_x, F_y, F_z, T of SOIL.md for given slip, tan(slip angle), direction and sinkage.

    ``h`` is the sinkage below the virgin surface (it sets θ_f and the normal stress);
    ``h_c`` ≤ h the depth below the surface the wheel meets, which is shallower in a rut the
    soil remembers (contact then starts at θ_c < θ_f with the stress of the full sinkage).
    ``h_c == h`` is SOIL.md exactly. Arrays broadcast; h_c ≤ 0 gives zeros.
    """
    s, tb, d, h, hc = np.broadcast_arrays(
        *(np.asarray(v, dtype=np.float64) for v in (s, tan_beta, d, h, h_c))
    )
    r = radius
    hh = np.clip(h, 0.0, r)
    hc = np.clip(np.minimum(hc, hh), 0.0, r)
    th_f = np.arccos(1.0 - hh / r)
    th_c = np.arccos(1.0 - hc / r)
    th_r = -np.arccos(1.0 - p.lam * hc / r)
    th_m = np.minimum(np.maximum((p.a0 + p.a1 * s) * th_f, th_r), th_c)
    n = p.n0 + p.n1 * np.abs(s)
    ks = p.k_s(width)
    cos_f = np.cos(th_f)
    sin_c = np.sin(th_c)
    tan_phi = math.tan(math.radians(p.phi_deg))
    # Nodes of the rear arc [θ_r, θ_m] and the front arc [θ_m, θ_c], (..., NODES) each.
    half_r = 0.5 * (th_m - th_r)
    half_f = 0.5 * (th_c - th_m)
    th_rear = (0.5 * (th_m + th_r))[..., None] + half_r[..., None] * _GL_X
    th_front = (0.5 * (th_c + th_m))[..., None] + half_f[..., None] * _GL_X
    # θ_eq maps the rear arc onto [θ_m, θ_f], affinely: θ_eq = A + B x_k; a degenerate arc
    # (θ_m = θ_r) has zero weight.
    span = np.where(th_m > th_r, th_m - th_r, 1.0)
    slope = (th_f - th_m) / span
    sin_r, cos_r = _sincos_nodes(0.5 * (th_m + th_r), half_r)
    sin_f, cos_f_n = _sincos_nodes(0.5 * (th_c + th_m), half_f)
    cos_eq = _sincos_nodes(th_f - (0.5 * (th_m + th_r) - th_r) * slope, -(half_r * slope))[1]
    out = []
    # Rear arc: the normal stress at θ_eq; front arc: at θ itself.
    arcs = ((th_rear, sin_r, cos_r, cos_eq, half_r), (th_front, sin_f, cos_f_n, cos_f_n, half_f))
    for th, sin_t, cos_t, cos_base, half in arcs:
        base = np.maximum(r * (cos_base - cos_f[..., None]), 0.0)
        sigma = ks * base ** n[..., None]
        one_s = (1.0 - s)[..., None]
        j_x = r * ((th_c[..., None] - th) - one_s * (sin_c[..., None] - sin_t))
        j_y = r * one_s * (th_c[..., None] - th) * tb[..., None]
        tau_max = p.c + sigma * tan_phi
        tau_x = tau_max * np.sign(j_x) * -np.expm1(-np.abs(j_x) / p.k_x)
        tau_y = tau_max * np.sign(j_y) * -np.expm1(-np.abs(j_y) / p.k_y)
        w = half[..., None] * _GL_W
        out.append(
            (
                np.sum(w * (tau_x * cos_t - sigma * sin_t), axis=-1),
                np.sum(w * tau_y, axis=-1),
                np.sum(w * (tau_x * sin_t + sigma * cos_t), axis=-1),
                np.sum(w * tau_x, axis=-1),
            )
        )
    (ix_r, iy_r, iz_r, it_r), (ix_f, iy_f, iz_f, it_f) = out
    rb = r * width
    on = hc > 0.0
    F_x = np.where(on, d * rb * (ix_r + ix_f), 0.0)
    F_y = np.where(on, -rb * (iy_r + iy_f), 0.0)
    F_z = np.where(on, rb * (iz_r + iz_f), 0.0)
    T = np.where(on, d * r * rb * (it_r + it_f), 0.0)
    return F_x, F_y, F_z, T


def slip_and_direction(
    v_x: ArrayLike, v_w: ArrayLike, v_eps: float = V_EPS
) -> tuple[FloatArray, FloatArray]:
    """Wong's slip s and travel direction d of SOIL.md."""
    v_x = np.asarray(v_x, dtype=np.float64)
    v_w = np.asarray(v_w, dtype=np.float64)
    lead = np.where(np.abs(v_w) >= np.abs(v_x), v_w, v_x)
    d = np.where(lead < 0.0, -1.0, 1.0)
    den = np.maximum(np.maximum(np.abs(v_w), np.abs(v_x)), v_eps)
    s = np.clip(d * (v_w - v_x) / den, -1.0, 1.0)
    return s, d


def soil_forces(
    v_x: ArrayLike,
    v_y: ArrayLike,
    v_w: ArrayLike,
    sinkage: ArrayLike,
    radius: float,
    width: float,
    params: SoilParams,
    v_eps: float = V_EPS,
) -> SoilForces:
    """Steady-state soil forces of SOIL.md at contact velocities and sinkage (m)."""
    s, d = slip_and_direction(v_x, v_w, v_eps)
    v_y = np.asarray(v_y, dtype=np.float64)
    denom = np.maximum(np.abs(np.asarray(v_x, dtype=np.float64)), v_eps)
    beta = np.arctan2(v_y, denom)
    F_x, F_y, F_z, T = stress_integrals(s, np.tan(beta), d, sinkage, sinkage, radius, width, params)
    return SoilForces(F_x, F_y, F_z, T, s, beta)


def static_sinkage(
    load: float,
    radius: float,
    width: float,
    params: SoilParams,
    slip: float = 0.0,
    tol: float = 1e-10,
) -> float:
    """Sinkage (m) at which the wheel carries ``load`` (N) at steady slip ``slip``.

    Bisection on F_z(h), which rises with h (more contact, more stress); raises if the
    load exceeds what the soil carries with the wheel sunk to its axle.
    """
    v_x = 0.1
    v_w = v_x / (1.0 - slip) if slip >= 0 else v_x * (1.0 + slip)

    def fz(h: float) -> float:
        return float(soil_forces(v_x, 0.0, v_w, h, radius, width, params).F_z)

    lo, hi = 0.0, radius
    if fz(hi) < load:
        raise ValueError(
            f"soil {params.name}: cannot carry {load} N even sunk to the axle (F_z {fz(hi):.1f} N)"
        )
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if fz(mid) < load:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


class SoilStep(NamedTuple):
    """One substep of the dynamic soil contact: new states and the forces applied."""

    u_x: FloatArray
    u_y: FloatArray
    dig: FloatArray
    F_x: FloatArray
    F_y: FloatArray
    F_z: FloatArray
    T: FloatArray
    sinkage: FloatArray
    contact: npt.NDArray[np.bool_]


def soil_step(
    u_x: FloatArray,
    u_y: FloatArray,
    dig: FloatArray,
    v_x: FloatArray,
    v_y: FloatArray,
    v_w: FloatArray,
    delta: FloatArray,
    delta_dot: FloatArray,
    rut: FloatArray,
    dt: float,
    sigma_x: float,
    sigma_y: float,
    radius: float,
    width: float,
    params: SoilParams,
    v_eps: float = V_EPS,
) -> SoilStep:
    """Advance the dynamic soil contact of wheels on one soil by one substep (docs/soil.md).

    States: ``u_x``, ``u_y`` relaxation deflections (m; shared with the Gim layer: the same
    quantity, so a wheel crossing onto soil keeps its history), ``dig`` the depth a wheel has
    dug below the virgin surface where it stands (m). Inputs: contact-point velocities,
    ``delta`` the depth of the wheel's lowest point below the terrain surface and its rate,
    ``rut`` the depth of the rut map there (compacted by earlier passes).

    * Transient slip: du_x/dt = (v_x − v_w) − ρ_x u_x with ρ_x = max(|v_x|, |v_w|, v_eps)/σ_x,
      so in steady state s = −d u_x/σ_x is SOIL.md's slip, and at standstill u_x is the
      accumulated shear displacement (a spring). Likewise tan β = u_y/σ_y with
      ρ_y = max(|v_x|, v_eps)/σ_y. Exponential integration, exact for constant inputs.
    * Direction: the forward (d = +1) and backward (d = −1) stress fields are blended with
      the smoothstep weight w = 1/2 + z (3/4 − z²/4), z = clip(v_lead / V_BLEND, −1, 1), so
      the compaction resistance vanishes at rest instead of flipping sign, stably (see
      :data:`V_BLEND`); beyond V_BLEND the weight is exactly 1 or 0.
    * Digging: d(dig)/dt = k_dig max(|v_w| − |v_x|, 0) − (|v_x| / r) dig while in contact:
      a spinning wheel excavates, travel leaves the hole behind (depth k_dig r s/(1−s) in
      steady driving); sinkage counts from the dug surface, so a wheel kept spinning in
      place buries itself (dig is capped at the radius).
    * Sinkage damping: F_z gains ``damping`` × the sinkage rate (zero in steady state).
    """
    p = params
    # Transient slip and slip angle.
    rho_x = np.maximum(np.maximum(np.abs(v_x), np.abs(v_w)), v_eps) / sigma_x
    rho_y = np.maximum(np.abs(v_x), v_eps) / sigma_y
    ex = np.exp(-rho_x * dt)
    ey = np.exp(-rho_y * dt)
    u_x = u_x * ex + (v_x - v_w) * (-np.expm1(-rho_x * dt) / rho_x)
    u_y = u_y * ey + v_y * (-np.expm1(-rho_y * dt) / rho_y)
    u_x = np.clip(u_x, -sigma_x, sigma_x)
    u_y = np.clip(u_y, -_MAX_TAN_BETA * sigma_y, _MAX_TAN_BETA * sigma_y)
    s_fwd = -u_x / sigma_x
    tan_b = u_y / sigma_y
    # Digging, then the sinkages.
    contact_prev = delta - np.maximum(rut, dig) > 0.0
    rate = np.where(contact_prev, p.k_dig * np.maximum(np.abs(v_w) - np.abs(v_x), 0.0), 0.0)
    dig = np.minimum(dig * np.exp(-np.abs(v_x) * dt / radius) + rate * dt, radius)
    h = delta - dig
    h_c = delta - np.maximum(rut, dig)
    lead = np.where(np.abs(v_w) >= np.abs(v_x), v_w, v_x)
    z = np.clip(lead / V_BLEND, -1.0, 1.0)
    w = 0.5 + z * (0.75 - 0.25 * z * z)
    fx_f, fy_f, fz_f, t_f = stress_integrals(s_fwd, tan_b, 1.0, h, h_c, radius, width, p)
    fx_b, fy_b, fz_b, t_b = stress_integrals(-s_fwd, tan_b, -1.0, h, h_c, radius, width, p)
    F_x = w * fx_f + (1.0 - w) * fx_b
    F_y = w * fy_f + (1.0 - w) * fy_b
    F_z = w * fz_f + (1.0 - w) * fz_b
    T = w * t_f + (1.0 - w) * t_b
    contact = h_c > 0.0
    F_z = np.where(contact, np.maximum(F_z + p.damping * delta_dot, 0.0), 0.0)
    return SoilStep(u_x, u_y, dig, F_x, F_y, F_z, T, np.maximum(h, 0.0), contact)
