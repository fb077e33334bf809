"""benchmarks/pair_grid.py's axes: read as written, and a bad one refused naming it."""

from __future__ import annotations

import re

import pytest

from tests._bench import load_bench


def test_an_axis_is_read_as_effect_param_and_values() -> None:
    pg = load_bench("pair_grid")
    assert pg.parse_axis("command_lag:tau=0,0.38,0.5") == ("command_lag", "tau", [0.0, 0.38, 0.5])


@pytest.mark.parametrize("bad", ["command_lag=0.1", "command_lag:tau", "command_lag:tau=a,b"])
def test_a_bad_axis_is_refused_naming_it(bad: str) -> None:
    pg = load_bench("pair_grid")
    with pytest.raises(SystemExit, match=re.escape(repr(bad))):
        pg.parse_axis(bad)
