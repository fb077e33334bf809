"""Stage 5's tie: the winner against its runner-up, and the drive that separates them.

A tie the held-out drive cannot break: a force fixed in the world against a drag.

A slope tilts gravity, so it pushes the rover the same way whichever way the rover drives.
Rolling resistance and loose soil's compaction oppose the wheels' motion, so they push back
whichever way it drives. On drives that only go forwards both slow the rover alike. Which of
them fits the held-out drive better is then decided by what else each moves: the load a slope
shifts between the axles, the heading's projection of a slope, the soil's sinkage. Those are
where the model's form errs too (the catalogue's soil constants are not the ground's). Only
driving backwards makes one help where the other hinders. So while no held-out window
reverses, a named slope against a significant drag (or the reverse) is a tie, whatever the
held-out p, and the report asks for the drive that separates them (``reversals``).

Why (stop 118, exploratory, spent loose-soil singles of blocks 53000 and 53100): 2 of 31 were
named a slope of 11-12 degrees (53013, and 53104 with a rolling radius), the soil
significant beside it (held out 81-86 % better against the slope's 94 %). No tie was
declared, so no drive was proposed. Two others (53011, 53109) were first named the same way
but in a tie with a rolling resistance; their reversing drive named the soil. Fresh block
53200 (registered): the other kind named on 0 of 23 strong singles of slope, rolling
resistance and soil; the rule declared 2 ties, and both cases kept their right name.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rover_env.calibration.candidates import separating_plan
from rover_env.calibration.diagnosis.judge import p_improved
from rover_env.calibration.diagnosis.state import Diagnosis, Scored
from rover_env.calibration.evidence import PLAN_DURATION, PLAN_SEED
from rover_env.calibration.plans_held import ask
from rover_env.calibration.replay import PreparedLog, Window

WORLD_FIXED = frozenset({"slope"})
"""Effects whose force is fixed in the world frame: the same on a reversed drive."""
DRAG = frozenset({"rolling_resistance", "loose_soil"})
"""Effects whose force opposes the wheels' motion: reversed with the drive."""
UNSEPARATED = (
    "no held-out window drives backwards, where a slope helps one way and a drag opposes"
    " both, so the held-out drive does not separate them"
)
"""The report's reason for a tie declared by :func:`unseparated_rival`."""


def reverses(prepared: list[PreparedLog], windows: list[Window]) -> bool:
    """Whether any of ``windows`` holds a sample commanded backwards (regime ``reversing``)."""
    return any(
        bool(np.any(prepared[w.log_index].regimes["reversing"][w.k0 : w.k1 + 1])) for w in windows
    )


def unseparated_rival(winner: Scored, ranked: list[Scored], held_reverses: bool) -> Scored | None:
    """The significant candidate of the other kind (a drag against a world-fixed winner, a
    slope against a drag) with the largest held-out gain, where the held-out drive does not
    reverse; None where it does, where the winner is neither kind, or where no such
    candidate passed the window test."""
    if held_reverses:
        return None
    names = {c.name for c in winner.fit.candidates}
    other = DRAG if names & WORLD_FIXED else WORLD_FIXED if names & DRAG else frozenset()
    rivals = [
        s
        for s in ranked
        if s is not winner and s.significant and {c.name for c in s.fit.candidates} & other
    ]
    return max(rivals, key=lambda s: s.gain, default=None)


def runner_up(winner: Scored, ranked: list[Scored]) -> Scored | None:
    """The candidate the winner is tested against for a tie.

    The best other significant candidate, unless a candidate explains the held-out drive
    better than the winner and pays for itself on training (BIC) without passing the
    window test (few windows excite it): naming the winner over a rival that explains more
    would be a choice the data did not make, so that rival is the runner-up and a tie asks
    for the separating drive. (Stop 30: a 42 ms lag of the second generator was named an
    18 ms delay, held-out 47 % better at p 0.008, against the lag's 78 % at p 0.019.)
    """
    others = [s for s in ranked if s is not winner]
    sig = [s for s in others if s.significant]
    rivals = [s for s in others if not s.significant and s.gain > winner.gain and s.d_bic < 0]
    best = max(sig, key=lambda s: s.gain) if sig else None
    rival = max(rivals, key=lambda s: s.gain) if rivals else None
    if rival is not None and (best is None or rival.gain > best.gain):
        return rival
    return best


def tie(d: Diagnosis) -> dict[str, Any] | None:
    """The tie between the winner and its runner-up (:func:`runner_up`) if the held-out
    windows cannot tell them apart at ``tie_alpha``, with the drive that separates them."""
    winner = d.winner
    ru = runner_up(winner, d.ranked) if winner is not None else None
    if winner is None or ru is None:
        return None
    p_diff, unseparated = p_improved(ru.held_losses, winner.held_losses), None
    if p_diff <= d.opts.tie_alpha:  # Options.reversal_tie: unless the drive cannot tell them
        held_rev = not d.opts.reversal_tie or reverses(d.prepared, d.held_w)
        ru = unseparated_rival(winner, d.ranked, held_rev)
        if ru is None:
            return None
        p_diff, unseparated = p_improved(ru.held_losses, winner.held_losses), UNSEPARATED
    plan, why = separating_plan(winner.fit.name, ru.fit.name)
    d.say(f"tie: {winner.fit.name} vs {ru.fit.name} (p={p_diff:.2g}); separate with plan {plan!r}")
    rec = {
        "effects": [winner.fit.name, ru.fit.name],
        "p_winner_better": p_diff,
        "held_gain": [winner.gain, ru.gain],
        "plan": plan,
        "why": why,
        "unseparated": unseparated,
        # The schedule the rover must drive (rover-env drive-plan), as for evidence.
        "seed": PLAN_SEED,
        "duration": PLAN_DURATION,
    }
    return ask(rec, d.held_plans)  # a draw the logs do not hold yet


def reopen(d: Diagnosis) -> None:
    """The tie forward selection resolved by naming both its effects, back where the final
    choice no longer names both (the clean-fit allowance withdrew one): its drive is still
    the evidence to get. Why (stop 118, exploratory, spent soil single 53013): a slope tied
    with a rolling resistance; the two were named together and the resistance was then
    withdrawn, leaving the slope named with no tie and no drive proposed."""
    t = d.tie_resolved
    named = {c.name for s in d.chosen for c in s.fit.candidates}
    if t is None or d.tie is not None or set(t["effects"]) <= named:
        return
    d.tie = t
    d.say(f"tie reopened: {' and '.join(t['effects'])} are no longer both named")
