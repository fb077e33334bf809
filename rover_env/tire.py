"""Gim–Nikravesh tire model of the Proto-Explorer rover (SPEC §3, paper eqs. 10–17).

Two forms are provided:

* the steady-state model of the paper (:func:`tire_forces`), a pure function of the
  contact velocities and the tire compression, used for analysis and as the reference;
* a transient-slip ("relaxation length") form (:func:`transient_step`,
  :func:`transient_forces`) that the simulator integrates instead, because the steady
  slip force is stiff near standstill: a free wheel's slip time constant falls below
  1 ms at walking pace, far under any affordable physics step.

Sign conventions (SPEC §3): contact frame x along the wheel's rolling direction, y
lateral, z the ground normal; ``v_w = r_e * omega`` is the circumferential speed. All
forces are those of the ground on the wheel. This module is numpy-only on purpose so
that it can be tested and reused without MuJoCo.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

__all__ = [
    "DEFAULT_TIRE_PARAMS",
    "TireArrays",
    "TireForces",
    "TireParams",
    "gim_magnitudes",
    "lateral_factor",
    "lateral_slip",
    "normal_force",
    "slip_ratio",
    "stack_params",
    "tire_forces",
    "transient_forces",
    "transient_step",
]

FloatArray = npt.NDArray[np.float64]
ParamValue = float | FloatArray

# Floor of lambda*dt in the exponential integrator and of the critical slips: a safe
# divisor far below any value that changes a result (see transient_step, _gim_magnitude).
_X_FLOOR = 1e-300

# Fields that are damping coefficients: zero damping is a legitimate (undamped) tire.
_MAY_BE_ZERO = frozenset({"D_x", "D_y", "D_z", "k_re", "v_floor", "lateral_split"})


@dataclass(frozen=True, slots=True)
class TireParams:
    """Tire constants; defaults are the paper's Table 3 plus our transient-form choices.

    C_s and C_alpha are stiffnesses per unit slip (N), not N/m as the paper labels them.
    sigma_x, sigma_y (m) and D_x, D_y (N s/m) belong to the transient form only; the
    relaxation length of ~2 cm is of the order of a small wheel's contact half-length.
    k_re sets the rolling radius used for v_w: r_e = d - k_re * delta (SPEC §3 leaves it
    between d - delta and d). 1/3 is the usual deflected-tire value: the tread is not
    compressed along the wheel's circumference, so a loaded wheel rolls nearly as far per
    turn as an unloaded one, and rolling speed depends little on load.
    """

    mu_x: float = 0.4
    mu_y: float = 0.5
    C_s: float = 100.0
    C_alpha: float = 50.0
    C_z: float = 1000.0
    D_z: float = 72.2
    v_eps: float = 1e-3
    sigma_x: float = 0.02
    sigma_y: float = 0.02
    D_x: float = 100.0
    D_y: float = 100.0
    k_re: float = 1.0 / 3.0
    v_floor: float = 0.0
    """Low-speed floor (m/s) of the transient form's slip: its relaxation rate is
    max(|v_x|, |v_w|, v_floor) / sigma, so in steady state the slip is
    (v_x - v_w) / max(|v_x|, |v_w|, v_floor), the regularised slip a steady-state
    implementation of Gim's tire needs at rest. 0 (the default): no floor, the deflection
    is a pure spring at standstill. Another implementation's choice, which diagnose fits as
    model form when asked (``--fit-slip-floor``,
    :func:`rover_env.calibration.diagnosis.form.fit_slip_floor`). Hard ground only:
    on loose soil the soil's own floor (``rover_env.soil.V_EPS``) holds (tried in stop 30:
    a 5 cm/s floor there did not bring the two generators' soils closer)."""
    lateral_split: float = 0.0
    """How the transient form's lateral slip treats a spinning wheel. 0 (the default): the
    lateral deflection relaxes at max(|v_x|, |v_w|, v_floor) / sigma_y, so in steady state
    its slip is |v_y| / max(|v_x|, |v_w|): eq. (11) wherever v_x and v_w share a sign, a
    blend where they do not. 1: eq. (11) for every sign, as SPEC writes it: the deflection
    holds tan(alpha) (relaxing at max(|v_x|, v_floor) / sigma_y) and the force sees
    (1 - |S|) of it while the wheel spins (S < 0 of :func:`slip_ratio`), all of it while it
    skids. The two differ where a wheel turns against its hub's travel, as the driven
    wheels do in a pivot: on a pivot after a straight the free wheels of segment 3 roll at
    0.81 and 1.27 rad/s with 0 and 0.62 and 1.28 with 1, another implementation of SPEC
    0.58 and 1.24 (stop 63). Hard ground only (the soil's lateral slip is tan(alpha)).
    Diagnose does not choose it: on three of that implementation's logs with pivots it
    replayed the free wheels closer and the yaw joints further, the training windows 13-35 %
    worse (assets/README.md)."""

    def __post_init__(self) -> None:
        # Reject bad constants here, once, so the hot per-substep paths need no checks.
        for f in fields(self):
            value = getattr(self, f.name)
            try:
                if isinstance(value, bool):
                    raise TypeError
                x = float(value)
            except (TypeError, ValueError):
                raise ValueError(
                    f"TireParams.{f.name} must be a real number, got {value!r}"
                ) from None
            if f.name in _MAY_BE_ZERO:
                if not (math.isfinite(x) and x >= 0.0):
                    raise ValueError(f"TireParams.{f.name} must be >= 0, got {value!r}")
            elif not (math.isfinite(x) and x > 0.0):
                raise ValueError(f"TireParams.{f.name} must be > 0, got {value!r}")
        if self.k_re > 1.0:
            raise ValueError(f"TireParams.k_re must be in [0, 1], got {self.k_re!r}")
        if self.lateral_split not in (0.0, 1.0):
            raise ValueError(f"TireParams.lateral_split must be 0 or 1, got {self.lateral_split!r}")

    def as_arrays(self, n: int | None = None) -> TireArrays:
        """Plain-number view for the hot path: floats, or shape-(n,) arrays if n is given."""
        values = [float(getattr(self, f.name)) for f in fields(self)]
        if n is None:
            return TireArrays(*values)
        return TireArrays(*(np.full(n, v, dtype=np.float64) for v in values))


class TireArrays(NamedTuple):
    """The TireParams fields as plain floats or per-wheel arrays (e.g. shape (6,)).

    Accepted wherever a TireParams is, so wheels can differ without one dataclass each.
    It is not validated: build it with :meth:`TireParams.as_arrays` or
    :func:`stack_params` to get the checks.
    """

    mu_x: ParamValue
    mu_y: ParamValue
    C_s: ParamValue
    C_alpha: ParamValue
    C_z: ParamValue
    D_z: ParamValue
    v_eps: ParamValue
    sigma_x: ParamValue
    sigma_y: ParamValue
    D_x: ParamValue
    D_y: ParamValue
    k_re: ParamValue
    v_floor: ParamValue
    lateral_split: ParamValue = 0.0


def stack_params(params: Sequence[TireParams]) -> TireArrays:
    """Per-wheel constants from one validated TireParams per wheel."""
    names = [f.name for f in fields(TireParams)]
    return TireArrays(
        *(np.array([float(getattr(p, name)) for p in params], dtype=np.float64) for name in names)
    )


Params = TireParams | TireArrays

DEFAULT_TIRE_PARAMS = TireParams()


class TireForces(NamedTuple):
    """Ground-on-wheel forces (N) in the contact frame with the slips that produced them."""

    F_x: FloatArray
    F_y: FloatArray
    F_z: FloatArray
    S: FloatArray
    S_alpha: FloatArray


# ---------------------------------------------------------------------------------------
# Steady-state Gim–Nikravesh model
# ---------------------------------------------------------------------------------------


def slip_ratio(v_x: npt.ArrayLike, v_w: npt.ArrayLike, v_eps: npt.ArrayLike) -> FloatArray:
    """Longitudinal slip ratio, eq. (10) extended to all signs of motion (SPEC §3).

    S = sign(v_x + v_w) (v_x - v_w) / max(|v_x|, |v_w|, v_eps), clamped to [-1, 1]:
    S < 0 the wheel spins (drives), S > 0 it skids (brakes), relative to the direction
    of travel. v_eps changes nothing unless both speeds are below it; it keeps S finite
    (and continuous, -> 0) at standstill instead of 0/0.

    Our convention: where v_x + v_w == 0 but v_x != v_w (equal speeds of opposite sign)
    sign(v_x) stands in for sign(v_x + v_w), i.e. the hub's motion defines the direction
    of travel. |S| is 1 there anyway; this picks S = +1, a skid (the wheel turns against
    the hub's travel), where the sum's sign would be undefined.
    """
    vx = np.asarray(v_x, dtype=np.float64)
    vw = np.asarray(v_w, dtype=np.float64)
    total = vx + vw
    direction = np.sign(np.where(total == 0.0, vx, total))
    den = np.maximum(np.maximum(np.abs(vx), np.abs(vw)), v_eps)
    return np.asarray(np.clip(direction * (vx - vw) / den, -1.0, 1.0), dtype=np.float64)


def lateral_slip(
    v_x: npt.ArrayLike,
    v_y: npt.ArrayLike,
    v_w: npt.ArrayLike,
    S: npt.ArrayLike,
    v_eps: npt.ArrayLike,
) -> FloatArray:
    """Non-negative lateral slip S_alpha, eq. (11) with tan(alpha) = v_y / v_x.

    |tan alpha| = |v_y| / max(|v_x|, v_eps): only its magnitude enters the model, so the
    sign of v_x is irrelevant here. A spinning wheel (S < 0) has its lateral slip reduced
    by (1 - |S|): the spinning tread already slides, as in Gim and Nikravesh. v_w is not
    needed beyond S; it is accepted to mirror the paper's variable list.
    """
    del v_w  # S already carries everything eq. (11) needs from the wheel speed.
    s = np.asarray(S, dtype=np.float64)
    tan_abs = np.abs(v_y) / np.maximum(np.abs(v_x), v_eps)
    return np.asarray(np.where(s < 0.0, (1.0 - np.abs(s)) * tan_abs, tan_abs), dtype=np.float64)


def normal_force(delta: npt.ArrayLike, delta_dot: npt.ArrayLike, params: Params) -> FloatArray:
    """Normal force, eq. (17): F_z = max(0, C_z delta + D_z delta_dot), delta = compression.

    Zero whenever delta <= 0: a wheel out of contact feels neither tension nor a
    damping-only force (which a fast approach would otherwise produce).
    """
    d = np.asarray(delta, dtype=np.float64)
    fz = np.maximum(params.C_z * d + params.D_z * np.asarray(delta_dot, dtype=np.float64), 0.0)
    return np.asarray(np.where(d > 0.0, fz, 0.0), dtype=np.float64)


def _gim_magnitude(
    slip: npt.ArrayLike, F_z: npt.ArrayLike, mu: npt.ArrayLike, stiffness: ParamValue
) -> tuple[FloatArray, FloatArray]:
    """(|F|, mu F_z): the bound is returned too so the hot path need not recompute it."""
    # With q = min(1, slip / slip_c) = 1 - l_n, eq. (13) becomes mu F_z (1 - l_n^3)
    # = mu F_z q (3 - 3q + q^2). This factored form has no cancellation at small slip
    # (the slope C_s is exact) and gives exactly mu F_z once the whole patch slides.
    mu_fz = np.multiply(mu, F_z)
    slip_c = mu_fz * (3.0 / stiffness)
    # When F_z = 0 the critical slip is 0: the floored divisor gives q = 0 (and the force
    # 0) without 0/0; a positive slip_c below the floor only shrinks an already ~0 force.
    q = np.minimum(slip, slip_c) / np.maximum(slip_c, _X_FLOOR)
    return mu_fz * q * (3.0 + q * (q - 3.0)), mu_fz


def gim_magnitudes(
    S_abs: npt.ArrayLike,
    S_alpha: npt.ArrayLike,
    F_z: npt.ArrayLike,
    mu_x: npt.ArrayLike,
    mu_y: npt.ArrayLike,
    params: Params,
) -> tuple[FloatArray, FloatArray]:
    """Magnitudes (>= 0) of the longitudinal and lateral forces, eqs. (12)–(16).

    S_c = 3 mu_x F_z / C_s and S_alpha_c = 3 mu_y F_z / C_alpha (15, 16); l_n =
    max(0, 1 - slip / slip_c) (12); F = C slip l_n^2 + mu F_z (1 - 3 l_n^2 + 2 l_n^3)
    (13, 14), computed in the equivalent form mu F_z (1 - l_n^3). mu_x, mu_y may be
    per-wheel arrays (terrain friction map). Slips must be >= 0 and F_z >= 0.
    """
    mag_x = _gim_magnitude(S_abs, F_z, mu_x, params.C_s)[0]
    mag_y = _gim_magnitude(S_alpha, F_z, mu_y, params.C_alpha)[0]
    return np.asarray(mag_x, dtype=np.float64), np.asarray(mag_y, dtype=np.float64)


def _check_finite(func: str, name: str, value: npt.ArrayLike) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    finite = np.isfinite(arr)
    if not finite.all():
        index = tuple(int(i) for i in np.argwhere(~finite)[0])
        bad = arr[index]
        kind = "NaN" if np.isnan(bad) else "inf"
        raise ValueError(f"{func}: {name} contains {kind} at index {index}")
    return arr


def tire_forces(
    v_x: npt.ArrayLike,
    v_y: npt.ArrayLike,
    v_w: npt.ArrayLike,
    delta: npt.ArrayLike,
    delta_dot: npt.ArrayLike,
    params: Params = DEFAULT_TIRE_PARAMS,
    mu_x: npt.ArrayLike | None = None,
    mu_y: npt.ArrayLike | None = None,
) -> TireForces:
    """Steady-state ground-on-wheel forces, the paper's model in one call.

    F_x = -sign(v_x - v_w) |F_x|: it opposes the sliding of the contact patch, so it
    pushes forward when the wheel spins and brakes when it skids, in either direction of
    travel. F_y = -sign(v_y) |F_y|. mu_x, mu_y default to params' (per-wheel arrays from a
    friction map may be given). All outputs share the broadcast shape of the inputs.
    Non-finite inputs raise ValueError naming the argument: a NaN would otherwise
    propagate silently into the physics.
    """
    mu_x = params.mu_x if mu_x is None else mu_x
    mu_y = params.mu_y if mu_y is None else mu_y
    named = {
        "v_x": v_x,
        "v_y": v_y,
        "v_w": v_w,
        "delta": delta,
        "delta_dot": delta_dot,
        "mu_x": mu_x,
        "mu_y": mu_y,
    }
    checked = [_check_finite("tire_forces", name, value) for name, value in named.items()]
    for name, arr in zip(("mu_x", "mu_y"), checked[5:], strict=True):
        if (arr < 0.0).any():
            raise ValueError(f"tire_forces: {name} must be >= 0")
    vx, vy, vw, d, d_dot, mux, muy = np.broadcast_arrays(*checked)

    f_z = normal_force(d, d_dot, params)
    s = slip_ratio(vx, vw, params.v_eps)
    s_alpha = lateral_slip(vx, vy, vw, s, params.v_eps)
    mag_x, mag_y = gim_magnitudes(np.abs(s), s_alpha, f_z, mux, muy, params)
    f_x = -np.sign(vx - vw) * mag_x
    f_y = -np.sign(vy) * mag_y
    return TireForces(
        F_x=np.asarray(f_x, dtype=np.float64),
        F_y=np.asarray(f_y, dtype=np.float64),
        F_z=f_z,
        S=s,
        S_alpha=s_alpha,
    )


# ---------------------------------------------------------------------------------------
# Transient-slip (relaxation length) form
# ---------------------------------------------------------------------------------------


LATERAL_FACTOR_MIN = 0.2
"""With ``lateral_split`` 1, the lateral deflection stops growing at the critical slip over
max(1 - |S|, this): a wheel that has lost its lateral grip to spinning does not wind up
an unbounded deflection (at most 5 critical slips) that would hold it sideways long after
it stops spinning."""


def lateral_factor(v_x: npt.ArrayLike, v_w: npt.ArrayLike, params: Params) -> FloatArray:
    """Share of the lateral deflection the force sees (``TireParams.lateral_split``):
    1 - |S| while the wheel spins (S < 0, :func:`slip_ratio`), 1 while it skids, and 1
    everywhere with the split off (0)."""
    vx = np.asarray(v_x, dtype=np.float64)
    split = np.asarray(params.lateral_split, dtype=np.float64) != 0.0
    if not split.any():
        return np.ones_like(vx)
    s = slip_ratio(vx, v_w, params.v_eps)
    return np.asarray(np.where(split & (s < 0.0), 1.0 - np.abs(s), 1.0), dtype=np.float64)


def stable_step(params: TireParams, inertia: float, radius: float) -> float:
    """Largest physics step (s) at which the patch does not ring a wheel of spin inertia
    ``inertia`` (a free wheel: no rotor behind it).

    At small slip the transient form holds the wheel's rim on a spring of stiffness
    C_s / sigma_x and a damper D_x: the wheel's slip oscillates at omega_n = radius
    sqrt(C_s / (sigma_x J)), damped at c = D_x radius^2 / J. The deflection's own update is
    exact (:func:`transient_step`), the wheel's spin is stepped explicitly (semi-implicit
    Euler), which is stable only while (dt omega_n)^2 + 2 dt c < 4; this returns the dt at
    which that equals 4. Why: with the relaxation length of a steady-state tire (0.32 mm,
    which ``diagnose`` fits as model form) at 2 ms, the left side is 9.4 and the free wheels
    of a replay read 20 x what they read at 1 ms (2.9: 0.05 rad against 0.0026, stop 104);
    at 0.64 mm and 2 ms (5.9) 3 x; with 2.5 mm (3.2) and 2 cm (2.4) as at 1 ms.
    """
    w2 = radius**2 * params.C_s / (params.sigma_x * inertia)
    c = params.D_x * radius**2 / inertia
    return float((math.sqrt(c * c + 4.0 * w2) - c) / w2)


def transient_step(
    u_x: npt.ArrayLike,
    u_y: npt.ArrayLike,
    v_x: npt.ArrayLike,
    v_y: npt.ArrayLike,
    v_w: npt.ArrayLike,
    F_z: npt.ArrayLike,
    dt: float,
    params: Params,
    mu_x: npt.ArrayLike | None = None,
    mu_y: npt.ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Advance the contact-patch deflections (u_x, u_y) (m) by dt; return them and rates.

    du_x/dt = (v_x - v_w) - (V / sigma_x) u_x and du_y/dt = v_y - (V / sigma_y) u_y with
    V = max(|v_x|, |v_w|, v_floor) (v_floor 0 by default). In steady state
    u_x / sigma_x = (v_x - v_w) / V, which is eq. (10)'s magnitude with the sliding
    direction as sign, and |u_y| / sigma_y = |v_y| / V, which equals eq. (11)'s S_alpha
    exactly whenever v_x and v_w have the same sign (when spinning, (1 - |S|) |tan alpha| =
    |v_y| / |v_w|). Below the v_eps regularisation and for opposite signs the two forms
    differ, by design. At standstill (V = 0, no floor) u integrates the sliding
    displacement, so the tire is a spring of stiffness C_s / sigma_x (C_alpha / sigma_y) and
    a parked rover holds without creep; with a floor the spring leaks (time constant
    sigma / v_floor).

    The update is exact for velocities frozen over dt (unconditionally stable for any
    V dt / sigma). Afterwards |u_x| <= sigma_x min(1, S_c) and |u_y| <= sigma_y S_alpha_c:
    once the whole patch slides the deflection stops growing; with F_z = 0 it is reset to
    0. The rates returned are (u_new - u) / dt after the clamp, for the patch damping.

    Hot path (6 wheels per physics substep): inputs are not validated, params may be a
    :class:`TireArrays` of per-wheel arrays, dt must be > 0 (F_z < 0 counts as 0).
    """
    mu_x = params.mu_x if mu_x is None else mu_x
    mu_y = params.mu_y if mu_y is None else mu_y
    sx = params.sigma_x
    sy = params.sigma_y
    ux = np.asarray(u_x, dtype=np.float64)
    uy = np.asarray(u_y, dtype=np.float64)
    speed = np.maximum(np.maximum(np.abs(v_x), np.abs(v_w)), params.v_floor)

    # u_new = u exp(-x) + rate * phi with x = lambda dt and phi = dt (-expm1(-x) / x).
    # Flooring x at a tiny positive number is the safe divisor: -expm1(-x) / x is 1 to
    # within x / 2, so phi = dt exactly at standstill (lambda = 0), no 0/0, no branch.
    x = np.maximum(speed * (dt / sx), _X_FLOOR)
    split = np.asarray(params.lateral_split, dtype=np.float64) != 0.0
    if split.any():  # eq. (11)'s tan(alpha): the hub's speed alone relaxes it
        speed_y = np.where(split, np.maximum(np.abs(v_x), params.v_floor), speed)
        y = np.maximum(speed_y * (dt / sy), _X_FLOOR)
    else:
        y = np.maximum(speed * (dt / sy), _X_FLOOR)
    em_x = np.expm1(-x)
    em_y = np.expm1(-y)
    ux_new = ux * (em_x + 1.0) - np.subtract(v_x, v_w) * (dt * em_x / x)
    uy_new = uy * (em_y + 1.0) - np.multiply(v_y, dt * em_y / y)

    fz = np.maximum(F_z, 0.0)  # a negative F_z would invert the clamp below
    lim_x = sx * np.minimum(np.multiply(fz, mu_x) * (3.0 / params.C_s), 1.0)
    lim_y = np.multiply(fz, mu_y) * (3.0 * sy / params.C_alpha)
    if split.any():
        lim_y = lim_y / np.maximum(lateral_factor(v_x, v_w, params), LATERAL_FACTOR_MIN)
    ux_new = np.minimum(np.maximum(ux_new, -lim_x), lim_x)
    uy_new = np.minimum(np.maximum(uy_new, -lim_y), lim_y)
    return (
        np.asarray(ux_new, dtype=np.float64),
        np.asarray(uy_new, dtype=np.float64),
        np.asarray((ux_new - ux) / dt, dtype=np.float64),
        np.asarray((uy_new - uy) / dt, dtype=np.float64),
    )


def transient_forces(
    u_x: npt.ArrayLike,
    u_y: npt.ArrayLike,
    u_x_dot: npt.ArrayLike,
    u_y_dot: npt.ArrayLike,
    F_z: npt.ArrayLike,
    params: Params,
    mu_x: npt.ArrayLike | None = None,
    mu_y: npt.ArrayLike | None = None,
    lat_factor: npt.ArrayLike = 1.0,
) -> tuple[FloatArray, FloatArray]:
    """Ground-on-wheel (F_x, F_y) from the patch deflections of :func:`transient_step`.

    ``lat_factor``: :func:`lateral_factor` of the same step (``TireParams.lateral_split``);
    the lateral deflection and its rate count times it.

    The deflection stands in for the slip: kappa = |u_x| / sigma_x and S_alpha' =
    |u_y| / sigma_y go through the same Gim magnitudes, opposing the deflection, plus
    patch damping -D u_dot; each is clipped to +-mu F_z so the friction bound holds
    (and F = 0 when F_z = 0). With u_dot = 0 (steady state) this equals
    :func:`tire_forces`. Hot path: inputs are not validated (F_z < 0 counts as 0).
    """
    mu_x = params.mu_x if mu_x is None else mu_x
    mu_y = params.mu_y if mu_y is None else mu_y
    fz = np.maximum(F_z, 0.0)  # a negative F_z would invert the friction bound
    mag_x, bound_x = _gim_magnitude(np.abs(u_x) / params.sigma_x, fz, mu_x, params.C_s)
    uy = np.multiply(u_y, lat_factor)
    mag_y, bound_y = _gim_magnitude(np.abs(uy) / params.sigma_y, fz, mu_y, params.C_alpha)
    f_x = -np.sign(u_x) * mag_x - np.multiply(params.D_x, u_x_dot)
    f_y = -np.sign(uy) * mag_y - np.multiply(params.D_y, np.multiply(u_y_dot, lat_factor))
    return (
        np.asarray(np.minimum(np.maximum(f_x, -bound_x), bound_x), dtype=np.float64),
        np.asarray(np.minimum(np.maximum(f_y, -bound_y), bound_y), dtype=np.float64),
    )
