"""benchmarks/form_allowance.py: the clean-fit allowance read from stored block results, the
interval widened by it, what it covers and what it would refuse. Blocks are built by hand."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType

import pytest
from _bench import load_bench


@pytest.fixture(scope="module")
def fa() -> ModuleType:
    return load_bench("form_allowance")


def _clean(block: Path, i: int, delay: float, tilt: float) -> None:
    out = block / "work" / f"clean_none_{i}" / "out"
    out.mkdir(parents=True)
    fits = {
        "command_delay": {"params": {"command_delay": {"delay": [delay, 0.0, 2 * delay]}}},
        "slope": {"params": {"slope": {"deg": [tilt, 0.0, 1.0], "heading_deg": [10, None, None]}}},
        "combined_slip": {"params": {"combined_slip": {"on": [1.0, 1.0, 1.0]}}},
    }
    (out / "result.json").write_text(json.dumps({"fits": fits}))


def test_the_allowance_is_the_spread_of_what_clean_logs_fit(fa: ModuleType, tmp_path: Path) -> None:
    for i in range(21):
        _clean(tmp_path, i, 0.001 * i, 0.1 * i)
    fits = fa.clean_fits([tmp_path])
    assert set(fits) == {"command_delay", "slope"}  # a switch has no size
    allow = fa.allowance(fits)
    q05, q95, n = allow["command_delay"]
    assert n == 21 and q05 == pytest.approx(0.001) and q95 == pytest.approx(0.019)
    assert allow["slope"][1] == pytest.approx(1.9)
    # A delay fitted 0.112 [0.100, 0.120] for a truth of 0.091 (spent case 51324's pattern):
    lo, hi = fa.widened("command_delay", 0.100, 0.120, allow["command_delay"])
    assert lo == pytest.approx(0.081) and lo <= 0.091 <= hi
    assert hi == 0.120  # q05 is above 0 here: an allowance widens, it never narrows
    # A tilt can gain or lose the spurious one: widened both ways, never below level.
    assert fa.widened("slope", 1.0, 2.0, allow["slope"]) == pytest.approx((0.0, 3.9))


def test_named_effects_are_scored_covered_and_refused(fa: ModuleType) -> None:
    allow = {"command_delay": (0.0, 0.026, 43), "friction": (-0.242, 0.061, 43)}
    rows = [
        {  # a right delay, biased long: covered only once widened
            "case": "single_command_delay_1",
            "kind": "single",
            "truth": {"command_delay": {"delay": 0.091}},
            "named": ["command_delay"],
            "named_fits": {"command_delay": {"delay": [0.112, 0.100, 0.120]}},
            "fits": {"command_delay": {"truth": 0.091}},
        },
        {  # a clean case's friction: within what clean logs fit, refused
            "case": "clean_none_2",
            "kind": "clean",
            "truth": "none",
            "named": ["friction"],
            "named_fits": {"friction": {"fraction": [-0.244, -0.286, -0.201]}},
            "fits": {},
        },
    ]
    got = fa.named(rows, allow)
    assert [(g["effect"], g["right"], g["refused"]) for g in got] == [
        ("command_delay", True, False),
        ("friction", False, True),
    ]
    lines = fa.table(allow, got)
    assert "| command_delay | 43 | 0 | 0.026 | 0/1 | 1/1 | 0/1 | 0/0 |" in lines
    assert "| friction | 43 | -0.242 | 0.061 | 0/0 | 0/0 | 0/0 | 1/1 |" in lines


def test_the_written_table_is_what_diagnose_reads(fa: ModuleType, tmp_path: Path) -> None:
    from rover_env.calibration.form_allowance import load_allowance

    for i in range(21):
        _clean(tmp_path, i, 0.001 * i, 0.1 * i)
    allow = fa.allowance(fa.clean_fits([tmp_path]))
    path = tmp_path / "table.yaml"
    fa.write_table(allow, [tmp_path], path)
    got = load_allowance(path)
    assert set(got.effects) == {"command_delay", "slope"}
    b = got.effects["command_delay"]
    assert (b.low, b.high, b.cases) == (pytest.approx(0.001), pytest.approx(0.019), 21)
    # diagnose's interval for the truth is the benchmark's widened one
    lo, hi = fa.widened("command_delay", 0.100, 0.120, allow["command_delay"])
    below, above = got.pad("command_delay")
    assert (0.100 - below, 0.120 + above) == (pytest.approx(lo), pytest.approx(hi))
