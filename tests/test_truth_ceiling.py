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
