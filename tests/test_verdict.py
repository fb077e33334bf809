"""The verdict (issue 46): *better* needs success, energy and sinkage all not worse; one
better and one worse is a *trade* with its frontier plot, never a pass."""

from __future__ import annotations

import zlib
from pathlib import Path
from typing import Any

import numpy as np

from rover_env.benchmark.metrics import METRICS
from rover_env.benchmark.report import summarise, write_report
from rover_env.benchmark.verdict import frontier_plot, verdicts

N = 12


def _rows(controller: str, energy: float, sinkage: float, success: float = 1.0) -> list[Any]:
    """N paired seeds; a little seed-to-seed spread shared with the baseline, plus noise."""
    rng = np.random.default_rng(zlib.crc32(controller.encode()))
    out = []
    for seed in range(N):
        row: dict[str, Any] = dict.fromkeys(METRICS, 0.0)
        row.update(controller=controller, scenario="soft-patch", seed=2000 + seed)
        row["energy_per_metre"] = energy + seed + 0.3 * rng.normal()
        row["mean_sinkage"] = sinkage + 1e-4 * seed + 2e-5 * rng.normal()
        row["success"] = success if seed < N - 1 else 1.0
        row["time_to_goal"] = 10.0 + rng.normal()
        row["pace_ratio"] = 1.0
        out.append(row)
    return out


def _one(rows: list[Any], controller: str, alpha: float = 0.05) -> dict[str, Any]:
    (v,) = [v for v in verdicts(rows, "pi", alpha) if v["controller"] == controller]
    return v


def test_better_needs_nothing_worse() -> None:
    base = _rows("pi", 50.0, 0.013)
    rows = base + _rows("cheaper", 40.0, 0.013) + _rows("same", 50.0, 0.013)
    v = _one(rows, "cheaper")
    assert v["verdict"] == "better" and v["better"] == ["energy_per_metre"] and not v["worse"]
    assert _one(rows, "same")["verdict"] == "no difference"


def test_energy_worse_sinkage_better_is_a_trade_not_a_pass(tmp_path: Path) -> None:
    """The soft-patch case of issue 46: sinkage -6 %, energy +30 % passed the old OR line."""
    rows = _rows("pi", 54.0, 0.0131) + _rows("agent", 70.0, 0.0124)
    v = _one(rows, "agent")
    assert v["verdict"] == "trade"
    assert v["better"] == ["mean_sinkage"] and v["worse"] == ["energy_per_metre"]
    files = write_report(tmp_path, rows, {}, plots=False)
    front = frontier_plot(tmp_path, summarise(rows), ["soft-patch"])
    assert front is not None and front.stat().st_size > 1000
    assert frontier_plot(tmp_path, summarise(rows), []) is None
    text = files["markdown"].read_text()
    assert "trade (better: mean_sinkage; worse: energy_per_metre)" in text
    assert "frontier.png" in text


def test_fewer_successes_are_worse_even_when_cheaper() -> None:
    rows = _rows("pi", 50.0, 0.013) + _rows("fast", 50.0, 0.013, success=0.0)
    v = _one(rows, "fast")
    assert v["verdict"] == "worse" and v["worse"] == ["success"]


def test_no_alpha_left_claims_nothing() -> None:
    rows = _rows("pi", 50.0, 0.013) + _rows("cheaper", 40.0, 0.013)
    v = _one(rows, "cheaper", alpha=0.0)
    assert v["verdict"] == "no alpha left" and not v["better"]


def test_a_smaller_look_alpha_resolves_less() -> None:
    """Holm within a look runs at the look's alpha: a small difference resolved at 0.05 is
    not at the first look of an O'Brien-Fleming plan (0.003)."""
    rows = _rows("pi", 50.0, 0.013) + _rows("bit", 49.5, 0.013)
    p_holm = _one(rows, "bit")["metrics"]["energy_per_metre"]["p_holm"]
    assert 0.003 < p_holm < 0.05  # the case this test is about
    assert _one(rows, "bit", 0.05)["verdict"] == "better"
    assert _one(rows, "bit", 0.003)["verdict"] == "no difference"
