"""Per-case build tolerances: how this one rover differs from its drawing (issue 47, item 1).

Each quantity is drawn uniformly within its tolerance band (a build is anywhere inside the band,
not clustered at nominal), independently per part:

- segment masses +-5 % each; segment centres of mass moved by up to +-5 % of the segment's
  dimension along each axis (0.36 m spacing along x, 0.40 m width along y, 0.12 m height along z);
- leaf spring (and roll bearing) stiffness and damping +-20 % per joint;
- motor gains +-20 %: each motor's torque constant (= its back-EMF constant) and each speed
  loop's k_p and k_i;
- wheel radius +-1 % per wheel;
- potentiometer gains +-0.5 % per joint, with the offsets of :mod:`sensors` (+-0.2 degrees);
- the wheel encoder part: one of 500, 512, 1000, 1024, 2000, 2048 counts per turn.

The draws are recorded in the case's truth file.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from rover_env.independent.model import RoverParams
from rover_env.independent.sensors import POT_OFFSET

TOL: dict[str, float] = {
    "seg_mass": 0.05,
    "seg_com": 0.05,
    "spring_k": 0.20,
    "spring_c": 0.20,
    "k_t": 0.20,
    "kp": 0.20,
    "ki": 0.20,
    "wheel_radius": 0.01,
    "pot_gain": 0.005,
}
ENCODER_PARTS = (500, 512, 1000, 1024, 2000, 2048)
SEG_DIMS = (0.36, 0.40, 0.12)


def draw(seed: int) -> dict[str, Any]:
    """Relative factors (1 + e) and absolute offsets for one build, as plain lists."""
    rng = np.random.default_rng([47, 1, seed])

    def f(n: int, tol: float) -> list[float]:
        return [float(1.0 + v) for v in rng.uniform(-tol, tol, n)]

    com = rng.uniform(-TOL["seg_com"], TOL["seg_com"], (3, 3)) * np.array(SEG_DIMS)[None, :]
    return {
        "seg_mass": f(3, TOL["seg_mass"]),
        "seg_com_offset_m": [[float(v) for v in row] for row in com],
        "spring_k": f(5, TOL["spring_k"]),
        "spring_c": f(5, TOL["spring_c"]),
        "k_t": f(4, TOL["k_t"]),
        "kp": f(4, TOL["kp"]),
        "ki": f(4, TOL["ki"]),
        "wheel_radius": f(6, TOL["wheel_radius"]),
        "pot_gain": f(5, TOL["pot_gain"]),
        "pot_offset_rad": [float(v) for v in rng.uniform(-POT_OFFSET, POT_OFFSET, 5)],
        "encoder_cpr": int(rng.choice(ENCODER_PARTS)),
    }


def nominal() -> dict[str, Any]:
    """The draw of a rover built exactly to drawing (no nuisance)."""
    return {
        "seg_mass": [1.0] * 3,
        "seg_com_offset_m": [[0.0] * 3 for _ in range(3)],
        "spring_k": [1.0] * 5,
        "spring_c": [1.0] * 5,
        "k_t": [1.0] * 4,
        "kp": [1.0] * 4,
        "ki": [1.0] * 4,
        "wheel_radius": [1.0] * 6,
        "pot_gain": [1.0] * 5,
        "pot_offset_rad": [0.0] * 5,
        "encoder_cpr": RoverParams().encoder_cpr,
    }


GROUPS: dict[str, tuple[str, ...]] = {
    "masses": ("seg_mass",),
    "centres_of_mass": ("seg_com_offset_m",),
    "springs": ("spring_k", "spring_c"),
    "motors": ("k_t", "kp", "ki"),
    "wheel_radii": ("wheel_radius",),
    "sensors": ("pot_gain", "pot_offset_rad", "encoder_cpr"),
}
"""The tolerances by part, for a build that differs from its drawing in some parts only."""


def partial(seed: int, groups: Sequence[str]) -> dict[str, Any]:
    """The draw of ``seed`` in the parts ``groups`` name (:data:`GROUPS`), the drawing's
    elsewhere: which tolerance a diagnosis reads as an effect (stop 80: a clean drive's
    tilt). An unknown group is refused by name."""
    unknown = [g for g in groups if g not in GROUPS]
    if unknown:
        raise ValueError(f"nuisance group(s) {', '.join(unknown)}: not one of {', '.join(GROUPS)}")
    full, out = draw(seed), nominal()
    for g in groups:
        for k in GROUPS[g]:
            out[k] = full[k]
    return out


def apply(p: RoverParams, d: dict[str, Any]) -> RoverParams:
    """The nominal rover ``p`` built with the draw ``d``."""

    def mul(a: list[float], b: list[float]) -> list[float]:
        return [x * y for x, y in zip(a, b, strict=True)]

    return replace(
        p,
        seg_mass=mul(p.seg_mass, d["seg_mass"]),
        seg_com=[
            [c + o for c, o in zip(cc, oo, strict=True)]
            for cc, oo in zip(p.seg_com, d["seg_com_offset_m"], strict=True)
        ],
        spring_k=mul(p.spring_k, d["spring_k"]),
        spring_c=mul(p.spring_c, d["spring_c"]),
        k_t=mul(p.k_t, d["k_t"]),
        kp=mul(p.kp, d["kp"]),
        ki=mul(p.ki, d["ki"]),
        wheel_radius=mul(p.wheel_radius, d["wheel_radius"]),
        pot_gain=mul(p.pot_gain, d["pot_gain"]),
        encoder_cpr=int(d["encoder_cpr"]),
    )


def within_tolerance(d: dict[str, Any]) -> list[str]:
    """Names of the draws outside their band (empty when the build is in tolerance)."""
    bad = [
        k
        for k, tol in TOL.items()
        if k in d and k != "seg_com" and any(abs(v - 1.0) > tol + 1e-12 for v in d[k])
    ]
    for row in d["seg_com_offset_m"]:
        if any(abs(v) > TOL["seg_com"] * s + 1e-12 for v, s in zip(row, SEG_DIMS, strict=True)):
            bad.append("seg_com")
    if any(abs(v) > POT_OFFSET + 1e-12 for v in d["pot_offset_rad"]):
        bad.append("pot_offset_rad")
    if d["encoder_cpr"] not in ENCODER_PARTS:
        bad.append("encoder_cpr")
    return bad
