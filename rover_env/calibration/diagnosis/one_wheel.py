"""Stage 5c, one wheel: a rolling resistance that only one free wheel feels is not named.

The ground's rolling resistance acts on every wheel alike; a dragging brake or a seized
bearing slows one wheel. In the replay windows both read as a drag on the free wheels
(unpowered, each turns as its own drag lets it), and on the independent generator's spent
blocks a brake dragging on one free wheel was named a rolling resistance in 13 of 24
outside cases (blocks 47500-52400: every block's one brake drag, 0.10-0.48 N m). Dead
reckoning tells them apart: each free wheel's travel against the pose over the straight,
moving seconds (:mod:`.odometry`). So a named rolling resistance is withdrawn where the two
free wheels' differences from the named model's twins disagree by more than clean drives
of another implementation leave (the odometry band's ``split``, 5 %: at most 4.2 % on 325
spent cases without a radius or soil, stop 75, the bar odometry already holds a radius to).
What it was fitted beside is named only by its own fit, as the clean-fit allowance does
(:func:`.select.withdraw`). On spent case 52463 (0.19 N m on wheel 3L, named a rolling
resistance of 0.081) the free wheels disagree by 6.3 %; on the spent rolling-resistance
singles and clean cases of blocks 52300-52400 and study 65000, by -3.4 to +3.4 %. Scored
on fresh study 67200 (registered): 8 of 12 such names withdrawn, none of 120 fresh
rolling-resistance singles and clean cases parted that far.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rover_env.calibration.candidates import merge
from rover_env.calibration.diagnosis.judge import fmt_phys
from rover_env.calibration.diagnosis.odometry import (
    INTERVALS,
    band_of,
    form_of,
    scales,
    twin_scales,
)
from rover_env.calibration.diagnosis.select import withdraw
from rover_env.calibration.diagnosis.state import ODOMETRY_BAND, Diagnosis
from rover_env.estimation.estimator import static_rolling_radius

SHARED = frozenset({"rolling_resistance"})
"""Effects that act on every wheel alike (the ground's), so both free wheels must feel them."""


def statistic_form(d: Diagnosis) -> str:
    """The dead-reckoning statistic's form on these logs (:func:`.odometry.form_of`)."""
    if d.odometry is not None:
        return str(d.odometry.get("form", INTERVALS))
    return form_of([p.log for p in d.prepared], static_rolling_radius(d.base))


def free_wheel_difference(d: Diagnosis) -> dict[str, float]:
    """Dead reckoning's difference, logs minus the named model's twins, per free wheel and
    both (:func:`.odometry.scales`, in :func:`statistic_form`): the odometry stage's when it
    computed one, else here."""
    diff = (d.odometry or {}).get("difference")
    if diff is not None:
        return dict(diff)
    r_e, form = static_rolling_radius(d.base), statistic_form(d)
    on_logs = scales([p.log for p in d.prepared], r_e, form)
    ref_ext = merge(*(s.fit.ext for s in d.chosen))
    on_twins = twin_scales(d.ev.config(ref_ext), d.prepared, r_e, form)
    return {k: on_logs[k] - on_twins[k] for k in on_logs}


def withdraw_one_wheel(d: Diagnosis) -> None:
    """Sets :attr:`Diagnosis.one_wheel` where a named effect is one of :data:`SHARED`, and
    withdraws it (with what was fitted beside it) where the free wheels disagree beyond the
    split limit (:attr:`.state.Options.one_wheel`)."""
    if not d.opts.one_wheel:
        return
    hit = [s for s in d.chosen if any(c.name in SHARED for c in s.fit.candidates)]
    if not hit:
        return
    limit = (band_of(d.opts, statistic_form(d)) or ODOMETRY_BAND).split
    diff = free_wheel_difference(d)
    split = diff["3L"] - diff["3R"]
    rec: dict[str, Any] = {
        "3L": diff["3L"],
        "3R": diff["3R"],
        "split": split,
        "limit": limit,
        "withdrawn": False,
    }
    d.one_wheel = rec
    if not (np.isfinite(split) and abs(split) > limit):
        return
    names = [c.name for s in hit for c in s.fit.candidates if c.name in SHARED]
    beside = [c.name for s in hit for c in s.fit.candidates if c.name not in SHARED]
    rec.update(
        withdrawn=True,
        effects=names,
        params={n: fmt_phys(s.fit, {n}) for s in hit for n in names if n in s.fit.ext},
    )
    why = (
        f"not named: the free wheels disagree (3L {diff['3L']:+.2%}, 3R {diff['3R']:+.2%}"
        f" against the model's twins, beyond {limit:.0%}): one wheel's own drag"
    )
    for s in hit:
        s.test = why
        d.say(f"{s.fit.name} {fmt_phys(s.fit)}: {why}")
    withdraw(d, hit, beside, rec)
