"""A heavier rotor beside a named torque limit: the alternative the drives may not exclude.

On flat ground the motors reach their limit only when the wheels accelerate, and there the
limit shows as the torque over the wheel's reflected rotor inertia (``motor.armature``). A
nominal rotor inertia that is off (the gearhead's is rarely listed; the independent
generator's is twice this configuration's) then reads as a torque cut: stop 57, docs/
independent.md. So whenever a torque limit is named, the rotor inertia is fitted alone in
its place (a ladder around the configured value, the configured limit) and both are
reported side by side on the training and the held-out windows. Nothing is named or
withdrawn by it: the numbers are for the user, and for a rule a fresh block can score.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnosis.form import baseline
from rover_env.calibration.diagnosis.judge import gain, log_ratios
from rover_env.calibration.diagnosis.state import Diagnosis
from rover_env.calibration.fit import information_criteria
from rover_env.calibration.replay import Replayer
from rover_env.config import RoverConfig

FACTORS = tuple(float(2.0 ** (k / 2)) for k in range(-2, 5))
"""Rotor inertias tried, as factors on the configured one: 0.5 to 4, sqrt 2 apart."""


def with_armature(cfg: RoverConfig, armature: float) -> RoverConfig:
    """``cfg`` with the driven wheels' reflected rotor inertia ``armature`` (kg m^2)."""
    return replace(cfg, motor=replace(cfg.motor, armature=armature))


def rotor_alternative(d: Diagnosis) -> dict[str, Any] | None:
    """For a named torque limit: the rotor inertia that best explains the training windows
    without it, and how both models do against the model without effects (training gain
    and BIC with windows as observations, held-out gain), or None when none is named."""
    named = [s for s in d.chosen if any(c.name == "torque_limit" for c in s.fit.candidates)]
    if not named:
        return None
    tl = named[0]
    base = d.base
    scale, l_train, _ = baseline(base, d.prepared, d.train_w, d.st, d.sensor_noise)

    def losses(cfg: RoverConfig, which: str) -> np.ndarray:
        windows = d.train_w if which == "train" else d.held_w
        res = Replayer(cfg, d.st).run(d.prepared, windows)
        return rs.window_losses(res, scale if which == "train" else d.noise)

    l0 = {"train": l_train, "held": losses(base, "held")}
    a0 = base.motor.armature
    tried = {f: losses(with_armature(base, a0 * f), "train") for f in FACTORS if f != 1.0}
    best = min(tried, key=lambda f: float(np.mean(log_ratios(l0["train"], tried[f]))))
    rotor_cfg = with_armature(base, a0 * best)
    tq_cfg = d.ev.config({"torque_limit": tl.fit.ext["torque_limit"]})
    n = len(d.train_w)

    def judged(cfg: RoverConfig, train: np.ndarray) -> dict[str, float]:
        bic = information_criteria(float(np.sum(log_ratios(l0["train"], train))), n, 1)[1]
        return {
            "train_gain": gain(l0["train"], train),
            "d_bic": bic,
            "held_gain": gain(l0["held"], losses(cfg, "held")),
        }

    return {
        "armature_configured": a0,
        "armature": a0 * best,
        "rotor": judged(rotor_cfg, tried[best]),
        "torque_limit": judged(tq_cfg, losses(tq_cfg, "train")),
    }


def rotor_text(alt: dict[str, Any]) -> str:
    """The comparison in a sentence for the report."""
    r, t = alt["rotor"], alt["torque_limit"]

    def pct(x: float) -> str:
        return f"{100 * x:.1f} % {'better' if x >= 0 else 'worse'}"

    return (
        f"Beside it, a heavier or lighter rotor alone (`motor.armature` {alt['armature']:.3g}"
        f" kg m² for {alt['armature_configured']:.3g}, the configured limit): training windows"
        f" {pct(r['train_gain'])} (dBIC {r['d_bic']:+.1f}), held-out drive {pct(r['held_gain'])};"
        f" the torque limit in the same terms: training {pct(t['train_gain'])} (dBIC"
        f" {t['d_bic']:+.1f}), held-out {pct(t['held_gain'])}."
    )
