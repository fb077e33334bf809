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

Quadrature: the stress integrals run over arcs split where the integrand is not smooth, each
with :data:`NODES` Gauss–Legendre points: at the maximum-stress angle θ_m (where the
normal-stress formula changes), and, for a braking wheel (s < 0) only, wherever the shear
displacement j_x changes sign (|j_x| has a kink there; found by a bracketing test and a few
Newton steps, :func:`_kink_points`). A wheel with s ≥ 0 has the two arcs either side of θ_m
and pays nothing for the split. tests/test_soil_against_reference.py checks the result
against adaptive quadrature over random parameters, speeds and sinkages, deep and braking
wheels included: within 2e-3 of F_z (issue 15), braking ones within 5e-4 (1.7e-4 measured
over 5000). The compiled plugin (sim/fast/tire_plugin.c, its node loop in soil_nodes.h) is the
C twin of :func:`stress_integrals`, operation by operation; the node arithmetic has no library
call (own e^x and log, :func:`_exp`, :func:`_log`), so that the twin can run it on vector lanes
and still round exactly as numpy does.

Frame and signs (SOIL.md): x along the wheel's heading, y left, z the ground normal; forces
are those of the soil on the wheel, ``T`` the resistive torque about the axle (the torque
the motor must supply: the soil's moment on the wheel is ``-T`` about the spin axis); slip
``s`` is Wong's (``s = -S`` of the Gim layer).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from rover_env.config import ConfigError, load_config

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
"""Gauss–Legendre points per arc (two arcs per wheel, up to four where j_x changes sign)."""
_GL_X, _GL_W = np.polynomial.legendre.leggauss(NODES)
# Taylor coefficients of cos and sin/x in x^2 (to x^22): with the angle-addition rule they give
# the nodes' sines and cosines from one sin/cos of the arc's middle (|x| <= pi/2 here, where
# the truncation error is below 1e-16); the compiled plugin runs the same steps (_estrin).
_COS = tuple((-1) ** k / math.factorial(2 * k) for k in range(12))
_SIN = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(12))
_SHORT_HALF = 0.6
"""Half-width (rad) up to which 8 Taylor terms suffice (omitted term < 1e-17 at |x| <= 0.58)."""
_NEWTON_STEPS = 2
"""Newton steps per sign change of j_x (the C twin's SOIL_NEWTON_STEPS; see _kink_points)."""
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
    rut_cell: float = 0.005
    """Cell of the rut map (m): a tenth of the wheel's width, where the footprint map has
    converged (rover_env/rut.py, docs/soil.md 3.4b)."""
    memory: float = 1.0
    """How much the surface remembers of a pass, 0..1: it scales the depth of the rut a wheel
    leaves and the rate at which a spinning wheel digs. 1 is this project's soil (ruts at the
    wheel's depth, holes dug at ``k_dig``); 0 a surface that forgets, so that every wheel meets
    virgin soil (the memoryless design SOIL.md also allows; the second log generator's)."""
    sigma: float = 0.0
    """Relaxation length of the transient slip and slip angle on this soil (m); 0: the
    tire's (``TireParams.sigma_x``, ``sigma_y``). SOIL.md's forces are steady state; how
    fast they follow the slip is a design choice (docs/soil.md), which a shorter length
    brings closer to the steady state."""

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
        for key in ("c", "k_phi", "n1", "damping", "k_dig", "sigma"):
            if getattr(self, key) < 0:
                raise ConfigError(f"soil {self.name}: {key} must be >= 0, got {getattr(self, key)}")
        if not 0.0 <= self.phi_deg < 90.0:
            raise ConfigError(f"soil {self.name}: phi_deg must be in [0, 90), got {self.phi_deg}")
        if not 0.0 <= self.lam <= 1.0:
            raise ConfigError(f"soil {self.name}: lam must be in [0, 1], got {self.lam}")
        if not 0.0 <= self.memory <= 1.0:
            raise ConfigError(f"soil {self.name}: memory must be in [0, 1], got {self.memory}")

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
    return load_config(SoilParams, name_or_path, "soil", drop=("description", "source"))


def soil_variant(name_or_path: str | Path, changes: dict[str, float], folder: Path) -> Path:
    """A YAML copy of soil ``name_or_path`` with ``changes`` in ``folder``, validated by
    loading it back (a bad field or value raises :class:`ConfigError` naming it)."""
    import yaml

    from rover_env.config import to_dict

    base = to_dict(load_soil(name_or_path))
    base.update(changes)
    tag = "-".join(f"{k}{v:g}" for k, v in sorted(changes.items()))
    path = Path(folder) / f"{Path(str(name_or_path)).stem}-{tag}.yaml"
    path.write_text(yaml.safe_dump(base, sort_keys=False))
    load_soil(path)
    return path


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

    # Short arcs (|half| <= _SHORT_HALF, nearly all) need 8 terms for 1e-17; the rest all 12.
    c, sn = _estrin(a2, _COS[:8]), _estrin(a2, _SIN[:8])
    short = (np.abs(half) <= _SHORT_HALF)[..., None]
    if not np.all(short):
        c = np.where(short, c, _estrin(a2, _COS))
        sn = np.where(short, sn, _estrin(a2, _SIN))
    sa = a * sn
    sm = np.sin(mid)[..., None]
    cm = np.cos(mid)[..., None]
    return sm * c + cm * sa, cm * c - sm * sa


# The node arithmetic's exponential and logarithm are our own (the C twin vectorises them; a
# library call per node cannot be): only +, -, *, /, comparisons and integer bit operations,
# so numpy and the C lanes round identically. e^x: Cody–Waite reduction x = k ln2 + r,
# |r| <= ln2/2, then the Taylor polynomial to r^13 (omitted term < 5e-18); log: fdlibm's.
_EXP_C = tuple(1.0 / math.factorial(k) for k in range(14))
_EXP_SHIFT = 6755399441055744.0  # 0x1.8p52: x + it rounds x to an integer (k in the low bits)
_EXP_SHIFT_BITS = np.uint64(0x4338000000000000)
_INV_LN2 = 1.4426950408889634
_LN2_HI = float.fromhex("0x1.62e42fee00000p-1")  # fdlibm's ln2_hi: k * _LN2_HI is exact
_LN2_LO = float.fromhex("0x1.a39ef35793c76p-33")
_LG = (  # fdlibm e_log.c, Lg1 .. Lg7
    6.666666666666735130e-01,
    3.999999999940941908e-01,
    2.857142874366239149e-01,
    2.222219843214978396e-01,
    1.818357216161805012e-01,
    1.531383769920937332e-01,
    1.479819860511658591e-01,
)
_LOG_OFF = np.uint64(0x3FE6A09E667F3BCD)  # bits of sqrt(1/2)
_TOP12 = np.uint64(0xFFF0000000000000)
_TWO52_BITS = np.uint64(0x4330000000000000)
_MIN_NORMAL = 2.0**-1022


def _estrin(y: FloatArray, coef: tuple[float, ...]) -> FloatArray:
    """Σ coef[k] y^k (an even number of them) by Estrin's scheme, as the C twin: the pairs
    coef[2k] + coef[2k+1] y, then pairs of those with y², y⁴, … (short dependency chains)."""
    t = [coef[2 * k] + coef[2 * k + 1] * y for k in range(len(coef) // 2)]
    yy = y
    while len(t) > 1:
        yy = yy * yy
        t = [t[2 * k] + t[2 * k + 1] * yy for k in range(len(t) // 2)] + t[len(t) - len(t) % 2 :]
    return t[0]


def _exp(x: FloatArray) -> FloatArray:
    """e^x (relative error ~2e-16), 0 below −708 and inf above 709; soil_nodes.h's exp_n."""
    with np.errstate(invalid="ignore", over="ignore"):
        kd = x * _INV_LN2 + _EXP_SHIFT
        k = kd - _EXP_SHIFT
        r = (x - k * _LN2_HI) - k * _LN2_LO
        p = _estrin(r, _EXP_C)
        scale = ((kd.view(np.uint64) - _EXP_SHIFT_BITS + np.uint64(1023)) << np.uint64(52)).view(
            np.float64
        )
        y = p * scale
    return np.where(x > 709.0, np.inf, np.where(x < -708.0, 0.0, y))


def _log(x: FloatArray) -> FloatArray:
    """Natural log of normal x > 0 (garbage elsewhere): fdlibm's, x = 2^k z, z in [√½, √2)."""
    with np.errstate(all="ignore"):
        ix = x.view(np.uint64)
        tmp = ix - _LOG_OFF
        ku = (tmp + np.uint64(1 << 62)) >> np.uint64(52)  # k + 1024
        kd = (ku | _TWO52_BITS).view(np.float64) - (4503599627370496.0 + 1024.0)
        f = (ix - (tmp & _TOP12)).view(np.float64) - 1.0
        s = f / (2.0 + f)
        z = s * s
        w = z * z
        t1 = w * (_LG[1] + w * (_LG[3] + w * _LG[5]))
        t2 = z * (_LG[0] + w * (_LG[2] + w * (_LG[4] + w * _LG[6])))
        rr = t2 + t1
        hfsq = 0.5 * f * f
        return kd * _LN2_HI - ((hfsq - (s * (hfsq + rr) + kd * _LN2_LO)) - f)


def _lateral_sign(tb: FloatArray, one_s: FloatArray) -> FloatArray:
    """sign(j_y) at every node: j_y = r (1 - s)(θ_c - θ) tan β, and θ_c - θ > 0 inside arcs."""
    return np.sign(tb)[..., None, None] * (one_s > 0.0)


def _kink_points(
    s: FloatArray,
    one_s: FloatArray,
    th_r: FloatArray,
    th_c: FloatArray,
    sin_c: FloatArray,
    cos_c: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """The sign changes ρ_B ≤ ρ_A of j_x inside (θ_r, θ_c); θ_r stands for a missing one.

    j_x = r g, g(θ) = (θ_c − θ) − q (sin θ_c − sin θ), q = 1 − s: g(θ_c) = 0, g' = q cos θ − 1.
    For s ≥ 0 (q ≤ 1) g decreases, so j_x > 0 on the arc and there is nothing to do. For
    s < 0, g' vanishes at ±θ*, cos θ* = 1/q. If θ_c ≤ θ* (q cos θ_c ≥ 1: the cheap test)
    g < 0 on [−θ*, θ_c) and θ_r ≥ −θ_c ≥ −θ*: no sign change. Otherwise g(θ*) > 0, and g
    rises on [max(θ_r, −θ*), θ*] (root A iff g < 0 at its left end; right or left of 0 by the
    sign of g(0)) and falls on [θ_r, −θ*] (root B iff also θ_r < −θ* and g(θ_r) > 0).
    Each root starts from the nearer of two local models, clipped to its bracket: the
    parabola g(±θ*) ∓ q sin θ* u²/2 about the flat point on its side (u = θ ∓ θ*), or for
    root A the tangent at 0 (g''(0) = 0), whichever extrapolates less; then
    :data:`_NEWTON_STEPS` Newton steps safeguarded by bisection of the bracket leave it
    within ~2e-6 rad, which moves the forces by < 1e-9 of F_z from those at the exact root
    (any split point gives a valid quadrature; the root's accuracy only decides how well
    the kink is resolved).
    """
    maybe = (s < 0.0) & (one_s * cos_c < 1.0)
    if not np.any(maybe):
        return th_r, th_r
    with np.errstate(all="ignore"):  # the lanes without a root compute garbage, then dropped
        ci = 1.0 / np.where(maybe, one_s, 1.0)
        t_s = np.arccos(ci)
        sin_s = np.sqrt((1.0 - ci) * (1.0 + ci))
        g_r = (th_c - th_r) - one_s * (sin_c - np.sin(th_r))
        g_m = (th_c + t_s) - one_s * (sin_c + sin_s)  # g(−θ*)
        g_p = (th_c - t_s) - one_s * (sin_c - sin_s)  # g(θ*)
        g_0 = th_c - one_s * sin_c  # g(0)
        deep = th_r < -t_s
        has_a = maybe & np.where(deep, g_m < 0.0, g_r < 0.0)
        has_b = has_a & deep & (g_r > 0.0)
        a = one_s * sin_s
        u_m = np.sqrt(np.fmax(-2.0 * g_m / a, 0.0))
        u_p = np.sqrt(np.fmax(2.0 * g_p / a, 0.0))
        right = g_0 < 0.0  # root A in (0, θ*), else in [max(θ_r, −θ*), 0]
        lo_a = np.where(right, 0.0, np.maximum(th_r, -t_s))
        hi_a = np.where(right, t_s, 0.0)
        u_a = np.where(right, u_p, u_m)
        x_lin = g_0 / s  # g(0) + g'(0) θ = 0, g'(0) = −s (g''(0) = 0)
        x_a = np.where(np.abs(x_lin) < u_a, x_lin, np.where(right, t_s - u_a, u_a - t_s))
        x_a = np.minimum(np.maximum(x_a, lo_a), hi_a)
        x_b = np.minimum(np.maximum(-t_s - u_m, th_r), -t_s)
        # Rows: root A (g rising), root B (g falling); sgn g rises on both brackets.
        x = np.stack([x_a, x_b])
        lo = np.stack([lo_a, th_r])
        hi = np.stack([hi_a, -t_s])
        sgn = np.stack([np.ones_like(th_r), -np.ones_like(th_r)])
        for _ in range(_NEWTON_STEPS):
            g = (th_c - x) - one_s * (sin_c - np.sin(x))
            dg = one_s * np.cos(x) - 1.0
            below = sgn * g < 0.0
            lo = np.where(below, x, lo)
            hi = np.where(below, hi, x)
            xn = x - g / dg
            x = np.where((xn >= lo) & (xn <= hi), xn, 0.5 * (lo + hi))
    return np.where(has_b, x[1], th_r), np.where(has_a, x[0], th_r)


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
    cos_c = 1.0 - hc / r
    th_c = np.arccos(cos_c)
    th_r = -np.arccos(1.0 - p.lam * hc / r)
    th_m = np.minimum(np.maximum((p.a0 + p.a1 * s) * th_f, th_r), th_c)
    n = p.n0 + p.n1 * np.abs(s)
    ks = p.k_s(width)
    cos_f = 1.0 - hh / r  # cos θ_f and sin θ_c without a round trip through arccos
    sin_c = np.sqrt((1.0 - cos_c) * (1.0 + cos_c))
    tan_phi = math.tan(math.radians(p.phi_deg))
    one_s = 1.0 - s
    # Four arcs between the break points θ_r ≤ b_1 ≤ b_2 ≤ b_3 ≤ θ_c, the sorted θ_m and
    # sign changes of j_x (θ_r where there is none, so that a wheel without one has two
    # zero-width arcs, which add exactly zero, then [θ_r, θ_m] and [θ_m, θ_c]).
    rho_b, rho_a = _kink_points(s, one_s, th_r, th_c, sin_c, cos_c)
    b_1 = np.minimum(rho_b, th_m)
    b_2 = np.maximum(rho_b, np.minimum(rho_a, th_m))
    b_3 = np.maximum(rho_a, th_m)
    lo = np.stack([th_r, b_1, b_2, b_3], axis=-1)
    hi = np.stack([b_1, b_2, b_3, th_c], axis=-1)
    mid = 0.5 * (hi + lo)
    half = 0.5 * (hi - lo)
    th = mid[..., None] + half[..., None] * _GL_X  # (..., 4, NODES)
    sin_t, cos_t = _sincos_nodes(mid, half)
    # Behind θ_m the normal stress is that at θ_eq, which maps [θ_r, θ_m] onto [θ_f, θ_m]
    # affinely; a degenerate rear region (θ_m = θ_r) has zero weight.
    span = np.where(th_m > th_r, th_m - th_r, 1.0)
    slope = ((th_f - th_m) / span)[..., None]
    cos_eq = _sincos_nodes(th_f[..., None] - (mid - th_r[..., None]) * slope, -(half * slope))[1]
    rear = (hi <= th_m[..., None])[..., None]
    base = np.maximum(r * (np.where(rear, cos_eq, cos_t) - cos_f[..., None, None]), 0.0)
    n = n[..., None, None]
    one_s = one_s[..., None, None]
    th_c = th_c[..., None, None]
    j_x = r * ((th_c - th) - one_s * (sin_c[..., None, None] - sin_t))
    g = np.abs(r * one_s * tb[..., None, None]) / p.k_y  # |j_y| / k_y = g (θ_c − θ)
    # The exponentials, in one call: Janosi–Hanamoto's in x and y (1 - exp rather than -expm1:
    # the same to 1e-16 of tau_max) and, where n != 1, Bekker's base^n = e^(n log base).
    # pow(x, 1) == x exactly, and the C twin takes no logarithm there.
    powered = not np.all(n == 1.0)
    args = [-np.abs(j_x) / p.k_x, -(g * (th_c - th))]
    if powered:
        args.append(n * _log(base))
    e = _exp(np.stack(np.broadcast_arrays(*args)))
    if powered:
        sigma = ks * np.where(n == 1.0, base, np.where(base >= _MIN_NORMAL, e[2], 0.0))
    else:
        sigma = ks * base
    tau_max = p.c + sigma * tan_phi
    tau_x = tau_max * np.sign(j_x) * (1.0 - e[0])
    tau_y = tau_max * _lateral_sign(tb, one_s) * (1.0 - e[1])
    w = half[..., None] * _GL_W
    i_x = np.sum(w * (tau_x * cos_t - sigma * sin_t), axis=-1)
    i_y = np.sum(w * tau_y, axis=-1)
    i_z = np.sum(w * (tau_x * sin_t + sigma * cos_t), axis=-1)
    i_t = np.sum(w * tau_x, axis=-1)

    def arcs(i: FloatArray) -> FloatArray:
        """The four arcs' sum, in order (the C twin adds the same way, skipping zero ones)."""
        return ((i[..., 0] + i[..., 1]) + i[..., 2]) + i[..., 3]

    rb = r * width
    on = hc > 0.0
    F_x = np.where(on, d * rb * arcs(i_x), 0.0)
    F_y = np.where(on, -rb * arcs(i_y), 0.0)
    F_z = np.where(on, rb * arcs(i_z), 0.0)
    T = np.where(on, d * r * rb * arcs(i_t), 0.0)
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
    * Memory: the dig rate is scaled by ``memory`` (0: no hole is dug).
    * Sinkage damping: F_z gains ``damping`` × the sinkage rate (zero in steady state).
    """
    p = params
    # Transient slip and slip angle.
    rho_x = np.maximum(np.maximum(np.abs(v_x), np.abs(v_w)), v_eps) / sigma_x
    rho_y = np.maximum(np.abs(v_x), v_eps) / sigma_y
    em_x = np.expm1(-rho_x * dt)  # one call per state: e^(-rho dt) = em + 1
    em_y = np.expm1(-rho_y * dt)
    u_x = u_x * (em_x + 1.0) + (v_x - v_w) * (-em_x / rho_x)
    u_y = u_y * (em_y + 1.0) + v_y * (-em_y / rho_y)
    u_x = np.clip(u_x, -sigma_x, sigma_x)
    u_y = np.clip(u_y, -_MAX_TAN_BETA * sigma_y, _MAX_TAN_BETA * sigma_y)
    s_fwd = -u_x / sigma_x
    tan_b = u_y / sigma_y
    # Digging, then the sinkages.
    contact_prev = delta - np.maximum(rut, dig) > 0.0
    rate = np.where(
        contact_prev, p.k_dig * p.memory * np.maximum(np.abs(v_w) - np.abs(v_x), 0.0), 0.0
    )
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
