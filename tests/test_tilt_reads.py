"""benchmarks/tilt_reads.py: the polar grid, each group's best tilt, and the clean spread."""

from __future__ import annotations

import pytest
from _bench import load_bench


def test_the_grid_starts_off_and_covers_every_heading() -> None:
    tr = load_bench("tilt_reads")
    grid = tr.tilt_grid([1.0, 3.0])
    assert grid[0] == (0.0, 0.0)
    assert len(grid) == 1 + 2 * 12
    assert {h for d, h in grid if d == 3.0} == set(tr.HEADINGS)


def test_each_group_reads_its_own_best_tilt() -> None:
    tr = load_bench("tilt_reads")
    grid = [(0.0, 0.0), (2.0, 60.0), (3.0, 0.0)]
    groups = [[5.0, 5.0, 5.0, 5.0], [5.0, 1.0, 9.0, 2.0], [4.0, 3.0, 1.0, 3.0]]
    reads = tr.best_tilts(grid, [0.0, -0.2, -0.1], groups)
    assert reads["all"] == [2.0, 60.0]
    assert reads["free wheels"] == [2.0, 60.0] and reads["joints"] == [3.0, 0.0]
    assert reads["driven wheels"] == [3.0, 0.0]
    assert tr.heading_error(170.0, -170.0) == pytest.approx(20.0)
    assert tr.heading_error(60.0, 0.0) == pytest.approx(60.0)


def test_the_table_gives_the_heading_error_and_the_clean_spread() -> None:
    tr = load_bench("tilt_reads")
    slope = {"seed": 1, "truth": [3.0, 70.0], "reads": {key: [3.0, 60.0] for key in tr.KEYS}}
    slope["reads"] = {**slope["reads"], "joints": [1.0, -30.0]}
    clean = [
        {"seed": 2 + i, "truth": [0.0, 0.0], "reads": {key: [v, 0.0] for key in tr.KEYS}}
        for i, v in enumerate((0.0, 1.0, 2.0))
    ]
    lines = tr.table([slope, *clean]).splitlines()
    head = [c.strip() for c in lines[4].strip("|").split("|")]
    (line,) = [x for x in lines if x.startswith("| 1 |")]
    row = dict(zip(head, [c.strip() for c in line.strip("|").split("|")], strict=True))
    assert row["truth"] == "3 @ 70" and row["all"] == "3 @ 60 (10)"
    assert row["joints"] == "1 @ -30 (100)"
    assert "| median size read | 1 | 1 | 1 | 1 | 1 |" in lines
    assert "| largest size read | 2 | 2 | 2 | 2 | 2 |" in lines
    with pytest.raises(SystemExit, match="positive finite sizes"):
        tr.main(["--clean", "1", "--sizes", "0,1"])
