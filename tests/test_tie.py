"""Ties: a slope against a drag is a tie while the held-out drive never reverses (stop 118)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, cast

import numpy as np

from rover_env.calibration.candidates import catalogue, separating_plan
from rover_env.calibration.diagnosis.state import Diagnosis, Options, Scored
from rover_env.calibration.diagnosis.tie import (
    UNSEPARATED,
    reopen,
    reverses,
    tie,
    unseparated_rival,
)
from rover_env.calibration.evidence import PLAN_DURATION, PLAN_SEED
from rover_env.calibration.fit import Fit
from rover_env.calibration.replay import PreparedLog, Window
from rover_env.calibration.report import tie_text


def _scored(name: str, x: list[float], gain: float, held: float) -> Scored:
    (c,) = catalogue([name])
    v = np.array(x)
    f = Fit([c], v, v, v, np.zeros_like(v), 0.0, 0, c.to_ext(v), 0.0, "train")
    # 12 held-out windows, each with its own loss ratio around ``held``.
    losses = held * (1.0 + 0.01 * np.arange(12))
    return Scored(f, 0.0, losses, gain, 1e-4, -50.0, -50.0, 24, significant=True)


def _log(reversing: list[bool]) -> PreparedLog:
    rev = np.array(reversing)
    return cast(PreparedLog, SimpleNamespace(regimes={"reversing": rev}))


def test_a_held_out_window_reverses_only_where_a_sample_is_commanded_backwards() -> None:
    logs = [_log([False] * 10), _log([False] * 6 + [True] + [False] * 3)]
    assert not reverses(logs, [Window(0, 0, 9), Window(1, 0, 5)])
    assert reverses(logs, [Window(0, 0, 9), Window(1, 4, 8)])
    assert not reverses(logs, [Window(1, 7, 9)])


def test_a_slope_and_a_drag_are_rivals_only_on_a_drive_that_never_reverses() -> None:
    # Spent case 53104's ranking: the slope led a rolling resistance and the soil.
    slope = _scored("slope", [12.1, 3.0], 0.936, 0.06)
    rr = _scored("rolling_resistance", [0.3], 0.877, 0.12)
    soil = _scored("loose_soil", [1 / 4.8e5], 0.855, 0.14)
    friction = _scored("friction", [-0.3], 0.95, 0.05)
    ranked = [slope, friction, rr, soil]
    assert unseparated_rival(slope, ranked, held_reverses=False) is rr
    assert unseparated_rival(slope, ranked, held_reverses=True) is None
    # The other way round: a drag's rival is the slope, never a tire effect.
    assert unseparated_rival(soil, ranked, held_reverses=False) is slope
    # A candidate that failed the window test is no rival; a winner of neither kind has none.
    rr.significant = False
    assert unseparated_rival(slope, ranked, held_reverses=False) is soil
    soil.significant = False
    assert unseparated_rival(slope, ranked, held_reverses=False) is None
    assert unseparated_rival(friction, [friction, slope], held_reverses=False) is None


def _diagnosis(winner: Scored, ranked: list[Scored], rev: bool, **opts: Any) -> Diagnosis:
    said: list[str] = []
    return cast(
        Diagnosis,
        SimpleNamespace(
            winner=winner,
            ranked=ranked,
            opts=Options(**opts),
            prepared=[_log([False] * 20 + [rev] * 5)],
            held_w=[Window(0, 0, 24)],
            say=said.append,
            held_plans={},
        ),
    )


def test_a_slope_clearly_better_than_a_drag_ties_with_it_until_the_drive_reverses() -> None:
    slope = _scored("slope", [12.1, 3.0], 0.936, 0.06)
    soil = _scored("loose_soil", [1 / 4.8e5], 0.855, 0.14)
    # Every held-out window is better under the slope: the window test alone declares no tie.
    t = tie(_diagnosis(slope, [slope, soil], rev=False))
    assert t is not None and t["effects"] == ["slope", "loose_soil"]
    assert t["p_winner_better"] < 0.05 and t["unseparated"] == UNSEPARATED
    assert t["plan"] == "reversals" == separating_plan("slope", "loose_soil")[0]
    assert (t["seed"], t["duration"]) == (PLAN_SEED, PLAN_DURATION)  # what drive-plan drives
    assert UNSEPARATED in tie_text(t)
    assert tie(_diagnosis(slope, [slope, soil], rev=True)) is None
    assert tie(_diagnosis(slope, [slope, soil], rev=False, reversal_tie=False)) is None


def test_a_tie_the_window_test_declares_is_not_marked_unseparated() -> None:
    slope = _scored("slope", [5.0, 0.0], 0.40, 0.60)
    rr = _scored("rolling_resistance", [0.08], 0.40, 0.60)
    t = tie(_diagnosis(slope, [slope, rr], rev=True))
    assert t is not None and t["unseparated"] is None
    assert "is not shown better" in tie_text(t)


def test_a_tie_resolved_by_naming_both_reopens_when_one_is_withdrawn() -> None:
    # Spent case 53013: slope and rolling resistance were named together, the resistance
    # then withdrawn by its clean-fit allowance; the slope alone stood with no drive asked.
    slope = _scored("slope", [10.7, -11.0], 0.885, 0.1)
    (c_rr,) = catalogue(["rolling_resistance"])
    pair = _scored("slope", [10.7, -11.0], 0.90, 0.1)
    pair.fit.candidates.append(c_rr)
    t = {"effects": ["slope", "rolling_resistance"], "plan": "reversals"}
    said: list[str] = []
    d = SimpleNamespace(tie=None, tie_resolved=t, chosen=[pair], say=said.append)
    reopen(cast(Diagnosis, d))
    assert d.tie is None and not said  # both still named: resolved
    d.chosen = [slope]
    reopen(cast(Diagnosis, d))
    assert d.tie is t and "reopened" in said[0]
    d.tie, d.chosen = None, []  # nothing named at all: the drive is still the evidence
    reopen(cast(Diagnosis, d))
    assert d.tie is t
