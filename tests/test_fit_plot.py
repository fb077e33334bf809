"""``benchmarks/fit_plot.py``: the single cases' fits against their truth, one panel per
effect; signed effects by magnitude, a soil's bar as the k_phi to be softer than."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from _bench import load_bench

fp = load_bench("fit_plot")


def _row(
    case: str,
    name: str,
    truth: float,
    value: float,
    lo: float | None,
    hi: float,
    bar: float,
    named: bool,
) -> dict:
    return {
        "case": case,
        "kind": "single",
        "truth": {name: {"x": truth}},
        "named": [name] if named else [],
        "fits": {name: {"truth": truth, "value": value, "lo": lo, "hi": hi, "nameable": bar}},
    }


ROWS = [
    _row("r1", "rolling_radius", -0.05, -0.048, -0.06, -0.035, 0.02, True),
    _row("s1", "loose_soil", 1.0e6, 1.2e6, 0.5e6, 3e6, 0.05, False),
    {"case": "c1", "kind": "clean", "truth": "none", "named": [], "fits": {}},
    {"case": "e1", "kind": "single", "error": "boom"},
]


def test_points_take_magnitudes_with_the_truths_sign_and_keep_only_finished_singles() -> None:
    per = fp.points(ROWS)
    assert sorted(per) == ["loose_soil", "rolling_radius"]
    (r,) = per["rolling_radius"]
    assert r["truth"] == pytest.approx(0.05) and r["value"] == pytest.approx(0.048)
    assert (r["lo"], r["hi"]) == (pytest.approx(0.035), pytest.approx(0.06)) and r["named"]
    (s,) = per["loose_soil"]
    assert s["bar"] == pytest.approx(2e7) and not s["named"]


def test_the_script_draws_a_figure_and_refuses_rows_without_a_single(tmp_path: Path) -> None:
    rows = tmp_path / "independent.json"
    rows.write_text(json.dumps(ROWS))
    out = tmp_path / "fig.png"
    assert fp.main([str(rows), "--out", str(out)]) == 0
    assert out.read_bytes()[:4] == b"\x89PNG"
    rows.write_text(json.dumps(ROWS[2:]))
    with pytest.raises(SystemExit, match="no finished single-effect case"):
        fp.main([str(rows), "--out", str(out)])
