"""make-logs' start headings (``--headings``): drives that start facing drawn ways, on a
slope whose heading is in the world; each log sees it turned by its start (SPEC §6: a log's
frame has segment 3 along +x at its start)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from rover_env.generators.make_logs import facing, make_logs, start_heading
from rover_env.logs import read_log

SLOPE = {"slope": {"deg": 3.0, "heading_deg": 40.0}}


def _made(root: Path, headings: str, effects: dict = SLOPE) -> list[Path]:
    return make_logs(
        root / headings, effects, drives=2, seed=5, duration=4.0, progress=False, headings=headings
    )


def test_drawn_starts_are_written_unlogged_ones_are_not(tmp_path: Path) -> None:
    """ "drawn" writes each drive's start heading to its YAML; "unlogged" draws the same
    starts and writes none, its samples equal; truth.yaml lists the starts either way."""
    drawn, blind = _made(tmp_path, "drawn"), _made(tmp_path, "unlogged")
    for k, (a, b) in enumerate(zip(drawn, blind, strict=True)):
        la, lb = read_log(a), read_log(b)
        assert la.meta.start_heading_deg == start_heading(5, k)
        assert lb.meta.start_heading_deg is None
        assert np.array_equal(la.phi, lb.phi) and np.array_equal(la.theta, lb.theta)
    truth = yaml.safe_load((tmp_path / "unlogged" / "truth.yaml").read_text())
    assert truth["headings"] == "unlogged"
    assert truth["start_headings_deg"] == [start_heading(5, k) for k in range(2)]
    assert len(set(truth["start_headings_deg"])) == 2  # each drive its own


def test_a_drawn_drive_is_the_same_drive_on_the_slope_turned_by_its_start(
    tmp_path: Path,
) -> None:
    """Drive 0 started facing ``psi`` on a slope rising toward 40° in the world is, sample
    for sample, the drive started along +x on one rising toward ``40 - psi``; without a
    slope the start changes nothing."""
    psi = start_heading(5, 0)
    (turned, _) = _made(tmp_path, "drawn")
    seen = {"slope": {"deg": 3.0, "heading_deg": 40.0 - psi}}
    (plain, _) = _made(tmp_path / "plain", "same", seen)
    a, b = read_log(turned), read_log(plain)
    assert np.allclose(a.phi, b.phi) and np.allclose(a.theta, b.theta)
    # The slope matters: facing the other way it drives differently.
    (other, _) = _made(tmp_path / "other", "same", SLOPE)
    assert not np.allclose(read_log(other).phi, a.phi)
    flat_a, _ = _made(tmp_path / "flat", "drawn", {})
    flat_b, _ = _made(tmp_path / "flat2", "same", {})
    assert np.array_equal(read_log(flat_a).phi, read_log(flat_b).phi)


def test_facing_turns_only_the_slope_and_bad_modes_are_refused(tmp_path: Path) -> None:
    from rover_env.config import RoverConfig

    cfg = RoverConfig(extensions={**SLOPE, "rolling_resistance": {"c_rr": 0.05}})
    turned = facing(cfg, 100.0)
    assert turned.extensions["slope"]["heading_deg"] == pytest.approx(-60.0)
    assert turned.extensions["rolling_resistance"] == {"c_rr": 0.05}
    assert cfg.extensions["slope"]["heading_deg"] == 40.0  # the original untouched
    assert facing(cfg, 0.0) is cfg
    assert facing(cfg, -170.0).extensions["slope"]["heading_deg"] == pytest.approx(-150.0)
    RoverConfig(extensions=facing(cfg, -170.0).extensions)  # within the key's range
    assert all(-180.0 <= start_heading(1, k) <= 180.0 for k in range(20))
    assert not math.isclose(start_heading(1, 0), start_heading(2, 0))
    with pytest.raises(ValueError, match="headings must be one of"):
        make_logs(tmp_path, {}, drives=1, duration=1.0, progress=False, headings="north")
