"""Independent reference for the wheel-soil model of /work/shared/SOIL.md (not the fast path).

Written from SOIL.md alone, scalar Python with scipy's adaptive quadrature and tight
tolerances, so that `rover_env.soil.soil_forces` (fixed quadrature, vectorised) can be
checked against something that shares none of its code. The integrals are split where the
integrand is not smooth: at theta_m (the normal-stress formula changes) and wherever the
longitudinal shear displacement j_x changes sign (|j_x| has a kink there; only at negative
slip). Signs are SOIL.md's: Wong's slip s > 0 when driving, d the travel direction.

Parameters come as a plain dict with SOIL.md's names: c [Pa], phi_deg, k_c [N/m^(n+1)],
k_phi [N/m^(n+2)], n0, n1, k_x, k_y [m], a0, a1, lam. Extra keys (name, ...) are ignored.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from scipy.integrate import quad
from scipy.optimize import brentq

V_EPS = 1e-3  # m/s; SOIL.md leaves v_eps open; 1e-3 matches rover_env.tire's default
QUAD_OPTS: dict[str, Any] = {"epsabs": 1e-12, "epsrel": 1e-10, "limit": 400}
"""epsabs is relative to the stress scale times the arc (see reference_soil_forces)."""
REQUIRED = ("c", "phi_deg", "k_c", "k_phi", "n0", "n1", "k_x", "k_y", "a0", "a1", "lam")


def _check_params(p: Mapping[str, Any]) -> None:
    missing = [k for k in REQUIRED if k not in p]
    if missing:
        raise KeyError(f"soil parameters: missing key(s) {missing}")
    if not 0.0 <= float(p["lam"]) <= 1.0:
        raise ValueError(f"soil parameters: lam = {p['lam']} outside [0, 1]")


def _sign(x: float) -> float:
    """sign with +1 at zero (SOIL.md: d = +1 at rest)."""
    return -1.0 if x < 0.0 else 1.0


def wong_slip(v_x: float, v_w: float, v_eps: float = V_EPS) -> tuple[float, float]:
    """(s, d): Wong's slip and the travel direction, exactly as SOIL.md defines them."""
    d = _sign(v_w) if abs(v_w) >= abs(v_x) else _sign(v_x)
    s = d * (v_w - v_x) / max(abs(v_w), abs(v_x), v_eps)
    return min(max(s, -1.0), 1.0), d


def _zero_crossings(f: Any, lo: float, hi: float, samples: int = 400) -> list[float]:
    """Sign changes of f inside (lo, hi), located by sampling then brentq.

    The end points are not sampled: j_x vanishes at theta_f, where rounding would report
    spurious crossings; a crossing within one sample of an end only leaves a tiny kink to quad.
    """
    out: list[float] = []
    xs = [lo + (hi - lo) * i / samples for i in range(1, samples)]
    fs = [f(x) for x in xs]
    for x0, x1, f0, f1 in zip(xs[:-1], xs[1:], fs[:-1], fs[1:], strict=True):
        if f0 * f1 < 0.0:
            out.append(brentq(f, x0, x1, xtol=1e-15, rtol=1e-14))
    return out


def reference_soil_forces(
    v_x: float,
    v_y: float,
    v_w: float,
    sinkage: float,
    radius: float,
    width: float,
    p: Mapping[str, Any],
    v_eps: float = V_EPS,
) -> dict[str, float]:
    """SOIL.md's steady-state forces on one rigid wheel: keys F_x, F_y, F_z, T, s (and n, theta_*).

    F_x is along the wheel's heading (drawbar pull, positive forward), F_z up, F_y left,
    T the resistive torque about the axle (same sign as d: it opposes a driving wheel).
    """
    _check_params(p)
    r, b = float(radius), float(width)
    s, d = wong_slip(float(v_x), float(v_w), v_eps)
    beta = math.atan2(float(v_y), max(abs(float(v_x)), v_eps))
    zeros = {"F_x": 0.0, "F_y": 0.0, "F_z": 0.0, "T": 0.0, "s": s}
    h = min(float(sinkage), r)
    if h <= 0.0:
        return zeros

    c = float(p["c"])
    tan_phi = math.tan(math.radians(float(p["phi_deg"])))
    k_s = float(p["k_c"]) / b + float(p["k_phi"])
    n = float(p["n0"]) + float(p["n1"]) * abs(s)
    k_x, k_y = float(p["k_x"]), float(p["k_y"])
    lam = float(p["lam"])

    th_f = math.acos(1.0 - h / r)
    th_r = -math.acos(1.0 - lam * h / r)
    th_m = min(max((float(p["a0"]) + float(p["a1"]) * s) * th_f, th_r), th_f)
    cos_f, sin_f = math.cos(th_f), math.sin(th_f)
    tan_beta = math.tan(beta)

    def sigma(th: float) -> float:
        if th >= th_m:
            arg = math.cos(th) - cos_f
        else:
            th_eq = th_f - (th - th_r) / (th_m - th_r) * (th_f - th_m)
            arg = math.cos(th_eq) - cos_f
        return k_s * (r * max(arg, 0.0)) ** n

    def j_x(th: float) -> float:
        return r * (th_f - th - (1.0 - s) * (sin_f - math.sin(th)))

    def j_y(th: float) -> float:
        return r * (1.0 - s) * (th_f - th) * tan_beta

    def shear(th: float, j: float, k: float) -> float:
        return (c + sigma(th) * tan_phi) * _sign(j) * (1.0 - math.exp(-abs(j) / k)) if j else 0.0

    def tau_x(th: float) -> float:
        return shear(th, j_x(th), k_x)

    def tau_y(th: float) -> float:
        return shear(th, j_y(th), k_y)

    # Break points: theta_m, and the sign changes of j_x (kinks of |j_x|).
    cuts = sorted({th_r, th_m, th_f, *_zero_crossings(j_x, th_r, th_f)})
    pieces = [(a, z) for a, z in itertools.pairwise(cuts) if z > a]

    # Absolute tolerance on the scale of the stresses times the arc: an integral that nearly
    # cancels (F_x near zero pull) cannot meet a relative one, and needs none finer than this.
    stress_scale = c + k_s * h**n * (1.0 + tan_phi)
    eps_abs = QUAD_OPTS["epsabs"] * stress_scale * (th_f - th_r)

    def integral(f: Any) -> float:
        opts = {**QUAD_OPTS, "epsabs": eps_abs}
        return sum(quad(f, a, z, **opts)[0] for a, z in pieces)

    i_fx = integral(lambda th: tau_x(th) * math.cos(th) - sigma(th) * math.sin(th))
    i_fz = integral(lambda th: tau_x(th) * math.sin(th) + sigma(th) * math.cos(th))
    i_fy = integral(tau_y)
    i_t = integral(tau_x)
    return {
        "F_x": d * r * b * i_fx,
        "F_y": -r * b * i_fy,
        "F_z": r * b * i_fz,
        "T": d * r * r * b * i_t,
        "s": s,
        "n": n,
        "theta_f": th_f,
        "theta_r": th_r,
        "theta_m": th_m,
    }


def slip_speeds(s: float, v_x: float = 0.1) -> tuple[float, float]:
    """(v_x, v_w) that hold Wong's slip at s: v_w = v_x/(1-s) driving, v_x (1+s) braking."""
    if not -1.0 <= s < 1.0:
        raise ValueError(f"slip s = {s} outside [-1, 1)")
    return (v_x, v_x / (1.0 - s)) if s >= 0.0 else (v_x, v_x * (1.0 + s))


def reference_static_sinkage(
    load: float,
    radius: float,
    width: float,
    p: Mapping[str, Any],
    s: float = 0.0,
    v_x: float = 0.1,
    *,
    pressure_only: bool = False,
) -> float:
    """Sinkage h at which the wheel carries `load` (F_z = load) while held at slip s.

    Brackets F_z(h) - load on (0, radius] and solves with brentq; raises ValueError when even
    the full radius cannot carry the load (the wheel would sink to its axle and beyond).
    F_z is SOIL.md's full vertical force, shear included (at s = 0 j_x is not zero, so a rolling
    wheel's shear still lifts it a little). `pressure_only=True` balances the load with the
    normal stress alone (c = tan(phi) = 0): the classical static (non-rotating) sinkage,
    which is how SOIL.md's orientation figures for lambda 0.3 / 0 were evidently obtained.
    """
    if load <= 0.0:
        raise ValueError(f"load = {load} N must be positive")
    if pressure_only:
        p = {**p, "c": 0.0, "phi_deg": 0.0}
    vx, vw = slip_speeds(s, v_x)

    def excess(h: float) -> float:
        return reference_soil_forces(vx, 0.0, vw, h, radius, width, p)["F_z"] - load

    hi = float(radius)
    top = excess(hi)
    if top == 0.0:
        return hi
    if top < 0.0:
        raise ValueError(
            f"soil {p.get('name', '?')}: F_z at sinkage = radius {radius} m is below the "
            f"load {load} N at s = {s}"
        )
    lo = hi
    while excess(lo) > 0.0:  # shrink geometrically until F_z < load
        lo *= 0.5
        if lo < 1e-9 * hi:
            raise ValueError(f"soil {p.get('name', '?')}: cannot bracket F_z = {load} N")
    return float(brentq(excess, lo, min(2.0 * lo, hi), xtol=1e-12, rtol=1e-12))


def reference_operating_point(
    load: float, radius: float, width: float, p: Mapping[str, Any], s: float
) -> dict[str, float]:
    """Forces at the sinkage that carries `load` at slip s, plus h and DP/W = F_x/F_z."""
    h = reference_static_sinkage(load, radius, width, p, s=s)
    vx, vw = slip_speeds(s)
    out = reference_soil_forces(vx, 0.0, vw, h, radius, width, p)
    out["h"] = h
    out["DP/W"] = out["F_x"] / out["F_z"]
    return out


PRESET_KEYS = {"name", "description", "source", *REQUIRED}
ROVER_WHEEL = {"radius": 0.085, "width": 0.05, "load": 27.0}  # SPEC: r, b, N per wheel at rest
TABLE_SLIPS = (0.0, 0.2, 0.5, 0.9)


def load_preset(path: str | Path) -> dict[str, Any]:
    """A configs/soil/*.yaml preset as a plain dict, checked for exactly SOIL.md's keys."""
    path = Path(path)
    data = yaml.safe_load(path.read_text())
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping of soil parameters")
    missing, extra = PRESET_KEYS - data.keys(), data.keys() - PRESET_KEYS
    if missing or extra:
        raise KeyError(f"{path}: missing keys {sorted(missing)}, unknown keys {sorted(extra)}")
    for key in REQUIRED:
        if not isinstance(data[key], int | float) or isinstance(data[key], bool):
            raise ValueError(f"{path}: key {key!r} = {data[key]!r} is not a number")
    return data


def preset_rows(
    paths: list[Path], load: float = ROVER_WHEEL["load"]
) -> list[tuple[str, float, list[tuple[float, float]]]]:
    """(name, static sinkage [m], [(sinkage [m], DP/W) at each TABLE_SLIPS]) per preset."""
    r, b = ROVER_WHEEL["radius"], ROVER_WHEEL["width"]
    rows = []
    for path in paths:
        p = load_preset(path)
        ops = [reference_operating_point(load, r, b, p, s) for s in TABLE_SLIPS]
        rows.append((p["name"], ops[0]["h"], [(op["h"], op["DP/W"]) for op in ops]))
    return rows


def markdown_table(paths: list[Path], load: float = ROVER_WHEEL["load"]) -> str:
    """The README table: static sinkage and sinkage / DP/W at each slip, from this reference."""
    head = "| preset | static sinkage (mm) | " + " | ".join(
        f"s = {s:g}: h (mm), DP/W" for s in TABLE_SLIPS
    )
    lines = [head + " |", "|" + "---|" * (2 + len(TABLE_SLIPS))]
    for name, h0, cells in preset_rows(paths, load):
        body = " | ".join(f"{h * 1e3:.1f}, {dpw:+.3f}" for h, dpw in cells)
        lines.append(f"| {name} | {h0 * 1e3:.1f} | {body} |")
    return "\n".join(lines)


if __name__ == "__main__":  # python tests/soil_reference.py configs/soil [load_N ...]
    import sys

    folder = Path(sys.argv[1] if len(sys.argv) > 1 else "configs/soil")
    files = sorted(folder.glob("*.yaml"))
    for w in [float(a) for a in sys.argv[2:]] or [ROVER_WHEEL["load"]]:
        print(f"\nload {w:g} N, r {ROVER_WHEEL['radius']} m, b {ROVER_WHEEL['width']} m\n")
        print(markdown_table(files, w))
