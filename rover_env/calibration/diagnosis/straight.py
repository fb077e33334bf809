"""A named soil's k_phi read from straight driving (:attr:`.state.Options.soil_from_straight`).

A loose soil loads the rover in two ways: along the drive (sinkage, the wheels' motion
resistance, slip: how much of the wheels' turning becomes travel) and, in a turn, across it
(the wheels' side forces, which the yaw joints answer through their springs). SPEC gives
neither the yaw springs' stiffness nor the free wheels' exact reading, and each signal
group reads the soil through such a form of this model (:mod:`.motion`): on study 60800's
spent soil cases the yaw spring and k_phi traded along a ridge (case 60808: k_phi 4 x the
truth at 10 N m/rad, 0.6 x at 14). On windows without a turn that trade is gone. So a named
single soil takes the k_phi that one signal group prefers over the windows of every drive
without a turn (training and held-out: the effect is named by then), in the soil's form as
fitted; its interval is stretched to hold it, then widened as every named effect's.

Which group (:data:`SINKAGE_GROUP`, :attr:`.state.Options.soil_from_joints`): the joints.
k_phi is the soil's sinkage modulus (SOIL.md: z = (W / (b (k_c / b + k_phi)))^(1/n)), and
the suspension's angles are set by the wheels' heights, each sunk by its own load. The pose
(the segment's travel and heading) reads the soil through its shear too, how much of the
wheels' turning becomes travel, whose constants (c, phi, K) the catalogue fixes at
mars-sand's: a soil whose shear differs moves the pose's k_phi to make up for it, and on
stiff soils the pose's loss is flat over a decade of k_phi.

Measured: the pose on straight windows within 2 x of the true k_phi on 22 of 27 spent soil
cases of study 60800 (notes soil_straight83.py; every signal over every window: 16 of 27;
every signal on straight windows: 15 of 27) and 13 of 18 of study 61600's; on fresh study
62400 (registered) 13 of 15 soil singles within 2 x; on fresh block 53000 (registered,
stop 116) 7 of 14 named soils, regolith 1 of 5. Then the joints (stop 117, exploratory,
spent soil singles re-diagnosed with every group's loss on a grid of k_phi over the straight
windows, notes soil_flat117.py): of 17 spent singles (blocks 52600-53000) the joints'
minimum within 2 x on 17 (0.51-1.81 x; dry sand read soft, median 0.65 x, regolith stiff,
median 1.3 x), the pose's on 11, the fit over every signal on 10; this search itself, on
the 8 re-diagnosed with it, 7 of 8 (the miss 0.497 x). Fresh block 53100 (registered):
15 of 15 named soils within 2 x (0.66-1.72 x), the pose's reading 14 of 15.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

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

SINKAGE_GROUP = "joints"
"""The signal group whose straight-window minimum is the soil's k_phi
(:attr:`.state.Options.soil_from_joints`): the suspension's angles, set by the wheels'
sinkage."""

READ_GROUPS = (SINKAGE_GROUP, MOTION_GROUP)
"""The groups the straight read locates a minimum for: one moves the fit, both are
recorded (``result.json``'s ``read_from``)."""


class StraightRead(NamedTuple):
    """What :func:`from_straight` read: every group's minimum and the value it replaced."""

    replaced: float | None
    """The fit over every signal that the move replaced (None: the fit was not moved)."""
    group: str
    """The group whose minimum moves the fit."""
    reads: dict[str, float | None]
    """Each of :data:`READ_GROUPS`' minimum (the fit's parameter; None: no reading)."""


def group_minima(
    ev: Evaluator,
    c: Candidate,
    fixed: Extensions,
    groups: tuple[str, ...] = READ_GROUPS,
    which: str = STRAIGHT,
    end: bool = True,
) -> dict[str, float | None]:
    """For each of ``groups``: the value of ``c``'s one parameter (beside ``fixed``) that
    minimises that signal group's loss over window set ``which``: the rungs of its
    magnitude ladder, then a bounded search in log-magnitude between the best rung's
    neighbours (the rungs' replays shared by every group). None where "off" fits the group
    at least as well (nothing to read there), and with ``end`` False where the best rung is
    the range's far end: the minimum may lie beyond the range, so what is found there is the
    effect at its largest, not a reading (:func:`.judge.pegged`; stop 84: three spent soil
    singles read at 0.05-0.15 x the truth so from the pose)."""
    names = list(SIGNAL_GROUPS)
    lo, hi, off = c.lo[0], c.hi[0], c.off[0]
    seen: dict[float, np.ndarray] = {}

    def losses(v: float) -> np.ndarray:
        v = float(np.clip(v, lo, hi))
        if v not in seen:
            try:  # profiled over its own windows: the profile touches no read signal
                res = ev.run(merge(fixed, c.to_ext(np.array([v]))), which, ref=which)
                seen[v] = group_losses(res, ev.scale).sum(axis=0)
            except (EffectError, SimulationError):
                seen[v] = np.full(len(names), math.inf)
        return seen[v]

    rungs = sorted(float(p[0]) for p in (c.ladder or ()) if float(p[0]) != off)
    if not rungs or any(v <= off for v in rungs):
        return dict.fromkeys(groups)  # a one-sided magnitude above "off" only (1 / k_phi)
    return {g: _minimum(losses, names.index(g), rungs, off, end) for g in groups}


def _minimum(
    losses: Callable[[float], np.ndarray], col: int, rungs: list[float], off: float, end: bool
) -> float | None:
    """:func:`group_minima` for the group in column ``col``."""

    def cost(v: float) -> float:
        return float(losses(v)[col])

    j = int(np.argmin([cost(v) for v in rungs]))
    if not end and j == len(rungs) - 1:
        return None
    a = rungs[j - 1] if j > 0 else max(rungs[0] / 3.0, off + 1e-9)
    b = rungs[j + 1] if j < len(rungs) - 1 else rungs[j]
    tried: list[float] = []

    def search(t: float) -> float:
        tried.append(off + math.exp(t))
        return cost(tried[-1])

    if b > a:
        optimize.fminbound(
            search, math.log(a - off), math.log(b - off), xtol=0.02, maxfun=REFINE, disp=0
        )
    best = min([*rungs, *tried], key=cost)
    return None if not math.isfinite(cost(best)) or cost(off) <= cost(best) else best


def from_straight(
    ev: Evaluator, f: Fit, end: bool = True, group: str = SINKAGE_GROUP
) -> StraightRead | None:
    """Move a one-effect fit of :data:`.motion.FROM_MOTION` to ``group``'s minimum
    (:func:`group_minima`) over the straight windows, where there are at least
    :data:`MIN_WINDOWS` (``end``: as there). Updates ``f`` as :func:`.motion.move_to`.
    Returns what it read (its ``replaced`` None where ``group`` has no reading), or None
    where it read nothing."""
    if len(f.candidates) != 1 or f.x.size != 1:
        return None
    c = f.candidates[0]
    if c.name not in FROM_MOTION or (f.sided and f.sided[0]):
        return None
    if len(ev.sets.get(STRAIGHT, ())) < MIN_WINDOWS:
        return None
    reads = group_minima(ev, c, f.ext, tuple(dict.fromkeys((group, *READ_GROUPS))), end=end)
    u = reads[group]
    return StraightRead(None if u is None else move_to(f, u), group, reads)
