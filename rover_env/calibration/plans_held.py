"""Which proposed drives the logs already hold, so that a diagnosis asks for a new one.

``diagnose`` proposes a drive as a plan and a seed: ``drive_schedule(plan,
default_rng(seed), PLAN_DURATION, vmax)`` (:mod:`rover_env.calibration.evidence`). A log
carries no record of the plan it drove, but its speed targets are that plan's, sample by
sample. So a log whose targets are a plan's draw holds that draw. A proposal whose plan the
logs already hold asks for the plan's next draw (the next seed): more runs of the same kind
where the first left the question open. Why: after the crossing drive a reading still wider
than 3 x asked for the very drive the logs held (stop 127's note); a user would drive it a
second time, and the second would add nothing new.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from rover_env.calibration.evidence import PLAN_DURATION, PLAN_SEED
from rover_env.generators.drives import PLANS, drive_targets
from rover_env.logs import DriveLog

Array = NDArray[np.float64]

HeldPlans = dict[str, list[dict[str, Any]]]
"""Plan -> the draws the logs hold: ``{"seed": s, "log": file name}`` each."""

SEEDS = 8
"""Draws of each plan looked for: seeds :data:`PLAN_SEED` to ``PLAN_SEED + SEEDS - 1``."""
AGREE = 0.98
"""Share of the plan's samples whose logged targets must be the plan's."""
TOL = 0.01
"""Targets agree within this share of the top wheel speed (the CSV's rounding, a bag's
float32)."""
COVER = 0.95
"""Share of the plan's duration the log must span after the plan's first move."""


def _agreement(cmd: Array, want: Array, vmax: float) -> float:
    """Share of samples whose targets agree with ``want`` at that sample or a neighbour's
    time: a recorder that samples the held command one sample early or late still agrees."""
    if not len(cmd):
        return 0.0

    def agree(a: Array, b: Array) -> NDArray[np.bool_]:
        return np.max(np.abs(a - b), axis=1) <= TOL * vmax

    near = agree(cmd, want)
    near[1:] |= agree(cmd[1:], want[:-1])  # the sample shows the target before it: late
    near[:-1] |= agree(cmd[:-1], want[1:])  # or the one after it: early
    return float(np.mean(near))


def _first_move(moving: Array) -> int | None:
    hit = np.flatnonzero(moving)
    return int(hit[0]) if hit.size else None


def match(log: DriveLog, vmax: float, duration: float = PLAN_DURATION) -> tuple[str, int] | None:
    """The plan and seed whose draw ``log`` drove (None: none of :data:`SEEDS` draws of any
    plan). The plan is placed at the log's first move: a recording may start before the
    commands do. Of draws the log agrees with equally, the first: the ``reversals`` plan
    draws only its pivot's length, and draws 0.2 s apart are one drive to a 10 Hz recorder."""
    t, cmd = log.t, np.nan_to_num(log.cmd)
    i0 = _first_move(np.max(np.abs(cmd), axis=1) > TOL * vmax)
    if i0 is None:
        return None
    grid = np.arange(0.0, duration, 0.005)
    best: tuple[float, str, int] | None = None
    for plan in PLANS:
        for seed in range(PLAN_SEED, PLAN_SEED + SEEDS):
            fine = drive_targets(plan, np.random.default_rng(seed), duration, vmax, grid)
            j0 = _first_move(np.max(np.abs(fine), axis=1) > TOL * vmax)
            if j0 is None:
                continue
            rel = t - t[i0] + grid[j0]
            inside = (rel >= 0.0) & (rel < duration)
            if rel[-1] < COVER * duration:
                continue
            want = drive_targets(plan, np.random.default_rng(seed), duration, vmax, rel[inside])
            share = _agreement(cmd[inside], np.clip(want, -vmax, vmax), vmax)
            if share >= AGREE and (best is None or share > best[0]):
                best = (share, plan, seed)
    return None if best is None else (best[1], best[2])


def held_plans(logs: list[DriveLog], names: list[str], vmax: float) -> HeldPlans:
    """Every proposed draw the logs hold, by plan."""
    out: HeldPlans = {}
    for log, name in zip(logs, names, strict=True):
        m = match(log, vmax)
        if m is not None:
            out.setdefault(m[0], []).append({"seed": m[1], "log": name})
    return out


def ask(rec: dict[str, Any], held: HeldPlans) -> dict[str, Any]:
    """``rec`` (a proposal with ``plan``) asking for the plan's first draw the logs do not
    hold, with the draws they do (``held``) where there are any; ``rec`` itself, changed."""
    have = held.get(rec["plan"], [])
    seeds = {h["seed"] for h in have}
    rec["seed"] = next(s for s in range(PLAN_SEED, PLAN_SEED + len(seeds) + 1) if s not in seeds)
    if have:
        rec["held"] = [dict(h) for h in have]
    return rec


def held_text(rec: dict[str, Any]) -> str:
    """The report's words on a proposal whose plan the logs already hold ("" where none)."""
    have = rec.get("held") or []
    if not have:
        return ""
    draws = ", ".join(f"seed {h['seed']} ({h['log']})" for h in have)
    return (
        f" The logs already hold this plan's draw{'s' if len(have) > 1 else ''} {draws}, so"
        f" this asks for another (seed {rec['seed']}): more runs of the same kind."
    )


__all__ = [
    "AGREE",
    "COVER",
    "SEEDS",
    "TOL",
    "HeldPlans",
    "ask",
    "held_plans",
    "held_text",
    "match",
]
