"""A named soil's k_phi read from straight driving (:attr:`.state.Options.soil_from_straight`).

A loose soil loads the rover in two ways: along the drive (sinkage, the wheels' motion
resistance, slip: how much of the wheels' turning becomes travel) and, in a turn, across it
(the wheels' side forces, which the yaw joints answer through their springs). SPEC gives
neither the yaw springs' stiffness nor the free wheels' exact reading, and each signal
group reads the soil through such a form of this model (:mod:`.motion`): on study 60800's
spent soil cases the yaw spring and k_phi traded along a ridge (case 60808: k_phi 4 x the
truth at 10 N m/rad, 0.6 x at 14). On windows without a turn that trade is gone, and the
pose (the segment's travel and heading) is the soil's own effect on the rover. So a named
single soil takes the k_phi that the pose signals prefer over the windows of every drive
without a turn (training and held-out: the effect is named by then), in the soil's form
as fitted; its interval is stretched to hold it, then widened as every named effect's.

Measured before it was adopted (exploratory, notes soil_straight83.py): the pose on straight
windows within 2 x of the true k_phi on 22 of 27 spent soil cases of study 60800 (every
signal over every window, diagnose's default then: 16 of 27; every signal on straight
windows: 15 of 27, soft on most stiff soils) and 13 of 18
of study 61600's (the pose over every window: 12 of 18). Scored on fresh seeds (study 62400,
registered): 13 of 15 soil singles within 2 x, every one named as soil; intervals held the
truth 16 of 16 (docs/calibration/study62400).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

from rover_env.calibration.candidates import Candidate, Extensions, merge
from rover_env.calibration.diagnosis.motion import FROM_MOTION, MOTION_GROUP, move_to
from rover_env.calibration.diagnosis.state import STRAIGHT
from rover_env.calibration.evaluator import Evaluator
from rover_env.calibration.fit import SIGNAL_GROUPS, Fit, group_losses
from rover_env.effects import EffectError
from rover_env.sim.simulator import SimulationError

MIN_WINDOWS = 4
"""Fewest straight windows the soil is read from (fewer: left as fitted)."""

REFINE = 8
"""Replays of the bounded search between the best rung's neighbours."""


def pose_minimum(
    ev: Evaluator, c: Candidate, fixed: Extensions, which: str = STRAIGHT, end: bool = True
) -> float | None:
    """The value of ``c``'s one parameter (beside ``fixed``) that minimises the pose
    signals' loss over window set ``which``: the rungs of its magnitude ladder, then a
    bounded search in log-magnitude between the best rung's neighbours. None where "off"
    fits the pose at least as well (nothing to read there), and with ``end`` False where
    the best rung is the range's far end: the pose's minimum may lie beyond the range, so
    what is found there is the effect at its largest, not a reading
    (:func:`.judge.pegged`; stop 84: three spent soil singles read at 0.05-0.15 x the
    truth so)."""
    col = list(SIGNAL_GROUPS).index(MOTION_GROUP)
    lo, hi, off = c.lo[0], c.hi[0], c.off[0]
    seen: dict[float, float] = {}

    def cost(v: float) -> float:
        v = float(np.clip(v, lo, hi))
        if v not in seen:
            try:  # profiled over its own windows: the profile touches no pose signal
                res = ev.run(merge(fixed, c.to_ext(np.array([v]))), which, ref=which)
                seen[v] = float(group_losses(res, ev.scale)[:, col].sum())
            except (EffectError, SimulationError):
                seen[v] = math.inf
        return seen[v]

    rungs = sorted(float(p[0]) for p in (c.ladder or ()) if float(p[0]) != off)
    if not rungs or any(v <= off for v in rungs):
        return None  # a one-sided magnitude above "off" only (as the soil's 1 / k_phi)
    j = int(np.argmin([cost(v) for v in rungs]))
    if not end and j == len(rungs) - 1:
        return None
    a = rungs[j - 1] if j > 0 else max(rungs[0] / 3.0, off + 1e-9)
    b = rungs[j + 1] if j < len(rungs) - 1 else rungs[j]
    if b > a:
        optimize.fminbound(
            lambda t: cost(off + math.exp(t)),
            math.log(a - off),
            math.log(b - off),
            xtol=0.02,
            maxfun=REFINE,
            disp=0,
        )
    best = min(seen, key=lambda v: seen[v])
    return None if not math.isfinite(seen[best]) or cost(off) <= seen[best] else best


def from_straight(ev: Evaluator, f: Fit, end: bool = True) -> float | None:
    """Move a one-effect fit of :data:`.motion.FROM_MOTION` to :func:`pose_minimum` over the
    straight windows, where there are at least :data:`MIN_WINDOWS` (``end``: as there).
    Updates ``f`` as :func:`.motion.move_to`; returns the value it replaced, or None where
    nothing changed."""
    if len(f.candidates) != 1 or f.x.size != 1:
        return None
    c = f.candidates[0]
    if c.name not in FROM_MOTION or (f.sided and f.sided[0]):
        return None
    if len(ev.sets.get(STRAIGHT, ())) < MIN_WINDOWS:
        return None
    u = pose_minimum(ev, c, f.ext, end=end)
    return None if u is None else move_to(f, u)
