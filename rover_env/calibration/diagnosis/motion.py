"""A named soil's k_phi read from the rover's motion (:attr:`.state.Options.soil_from_motion`).

A one-parameter fit reports what each signal group alone says about its parameter
(:attr:`~rover_env.calibration.fit.Fit.groups`). For loose soil those groups rarely agree,
and each of the groups other than the pose carries a form of this model that the soil's
k_phi then stands in for:

* the yaw joints (theta_2, theta_5) answer the soil's side forces in a turn through the yaw
  springs, whose stiffness SPEC does not give; fitted before any effect on soil drives it
  runs to the end of its ladder, and beside the soil k_phi and the spring trade along a
  ridge (exploratory, stop 82, spent case 60808: k_phi 4.1 x the truth at 10 N m/rad,
  0.58 x at 14.1; against one reference the training windows prefer 10 N m/rad);
* the free wheels read the soil's bulldozing through a reading gain profiled at its bound;
* the driven wheels read the soil through the speed loop's gains.

The pose (the segment's travel and heading) is the soil's own effect on the rover: how much
of the wheels' turning becomes travel. So where the pose group has a minimum of its own
(inside the points the search evaluated), the reported k_phi and the configuration written
are the pose group's; the interval is stretched to hold it, then widened as every named
effect's (the groups' disagreement, sensor noise, the allowance). Where the groups agree,
the two are the same within their noise. Measured before it was adopted, on spent study
60800's soil cases (exploratory, first-pass fits): the pose group within 2 x of the true
k_phi on 19 of 25 (16 of the first 19, the count at registration), the fit over every
signal on 14 of 25. Scored on fresh seeds (docs/calibration/study61600, registered): 12 of
19 soil singles within 2 x, short of the registered 70 %, so the option is off by default.
"""

from __future__ import annotations

import math

import numpy as np

from rover_env.calibration.candidates import merge
from rover_env.calibration.fit import Fit

MOTION_GROUP = "pose"
"""The signal group that reads the rover's motion (of
:data:`~rover_env.calibration.fit.SIGNAL_GROUPS`)."""

FROM_MOTION = frozenset({"loose_soil"})
"""The effects whose magnitude is read from the rover's motion (one: the soil)."""


def from_motion(f: Fit) -> float | None:
    """Move a one-effect fit of :data:`FROM_MOTION` to its pose group's own minimiser
    where it has one inside the effect's range, away from "off". Updates ``f.x``,
    ``f.ext`` and stretches the interval to hold the new value. Returns the value over
    every signal that it replaced, or None where nothing changed."""
    if len(f.candidates) != 1 or f.x.size != 1:
        return None
    c = f.candidates[0]
    if c.name not in FROM_MOTION or (f.sided and f.sided[0]):
        return None
    u = (f.groups or {}).get(MOTION_GROUP)
    return None if u is None else move_to(f, u)


def move_to(f: Fit, u: float) -> float | None:
    """Move a one-parameter fit to ``u`` where ``u`` lies inside its candidate's range, away
    from "off": ``f.x``, ``f.ext`` and the interval stretched to hold it. Returns the value
    it replaced, or None where nothing changed."""
    c = f.candidates[0]
    if not math.isfinite(u) or not c.lo[0] <= u <= c.hi[0] or u == c.off[0]:
        return None
    was = float(f.x[0])
    f.x = np.array([float(u)])
    f.ext = merge(f.ext, c.to_ext(f.x))
    f.ci_lo = np.minimum(f.ci_lo, f.x)
    f.ci_hi = np.maximum(f.ci_hi, f.x)
    return was
