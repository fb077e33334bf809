"""benchmarks/truth_ceiling.py's tallies (the naming test at the true effect): what the
table counts. No replay runs here."""

from __future__ import annotations

from types import ModuleType
from typing import Any

import pytest
from _bench import load_bench


@pytest.fixture(scope="module")
def tc() -> ModuleType:
    return load_bench("truth_ceiling")


def test_the_table_counts_strong_cases_only_and_names_against_the_truth(tc: ModuleType) -> None:
    def row(effect: str, s: float | None, passes: bool, named: bool) -> dict[str, Any]:
        return {"effect": effect, "strength": s, "passes": passes, "named_right": named}

    rows = [
        row("friction", 5.0, False, True),  # named right where the truth fails
        row("friction", 3.0, False, False),
        row("friction", 1.0, True, True),  # below 2 x threshold: not counted
        row("command_lag", 9.0, True, True),
        row("command_lag", None, True, True),  # no threshold reported: not counted
        {**row("command_lag", 9.0, True, True), "error": "boom"},  # failed: reported, not counted
    ]
    lines = tc.table(rows)
    assert "| friction | 2 | 0 | 1 | 1 |" in lines
    assert "| command_lag | 1 | 1 | 1 | 0 |" in lines
    assert lines[-1] == "| all | 3 | 1 | 2 | 1 |"
    # The weakest effect (least often passing at the truth) comes first.
    assert lines.index("| friction | 2 | 0 | 1 | 1 |") < lines.index(
        "| command_lag | 1 | 1 | 1 | 0 |"
    )


def test_a_torque_cut_is_read_against_the_motor_it_is_replayed_with(tc: ModuleType) -> None:
    # A cut to 0.8 of a configured 3.0 N m is 2.4 N m; a motor of 0.9333 x that limit
    # (2.8 N m) reaches 2.4 N m at a cut of 1 - 2.4 / 2.8.
    case = {"truth": {"torque_limit": {"fraction": -0.2}}, "equivalent": None}
    got = tc.truth_ext(case, {"torque_limit": 2.8 / 3.0, "anti_windup": "back_calculation"})
    assert got["torque_limit"]["fraction"] == pytest.approx(2.4 / 2.8 - 1)
    assert tc.truth_ext(case, {"armature": 2.0}) == case["truth"]
    assert tc.truth_ext(case) == case["truth"]
    lag = {"truth": {"command_lag": {"tau": 0.1}}}
    assert tc.truth_ext(lag, {"torque_limit": 0.5}) == lag["truth"]
