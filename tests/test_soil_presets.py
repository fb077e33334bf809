"""Soil presets (configs/soil/*.yaml): complete, sourced, physically sensible at the rover's wheel.

Figures come from the independent reference `soil_reference.py` (SOIL.md's equations by
adaptive quadrature), at the rover's wheel r 0.085 m, b 0.05 m and 20 / 27 / 40 N per wheel.
"""

from __future__ import annotations

import itertools
import re
import warnings
from pathlib import Path

import pytest
from soil_reference import (
    ROVER_WHEEL,
    load_preset,
    markdown_table,
    reference_operating_point,
    reference_static_sinkage,
)

SOIL_DIR = Path(__file__).resolve().parents[1] / "configs" / "soil"
PRESETS = sorted(SOIL_DIR.glob("*.yaml"))
R, B = ROVER_WHEEL["radius"], ROVER_WHEEL["width"]
SLIPS = (0.0, 0.1, 0.2, 0.3, 0.5)


@pytest.fixture(autouse=True)
def _quad_warnings_fail():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


def test_required_presets_exist():
    assert {p.stem for p in PRESETS} >= {"regolith", "mars-sand", "dune-sand"}


@pytest.mark.parametrize("path", PRESETS, ids=lambda p: p.stem)
def test_preset_is_complete_and_sourced(path):
    p = load_preset(path)
    assert p["name"] == path.stem
    assert len(p["source"]) > 80 and re.search(r"(19|20)\d\d", p["source"])  # a dated citation
    assert 0.0 <= p["lam"] <= 1.0 and 0.0 < p["phi_deg"] < 60.0
    assert min(p["k_x"], p["k_y"]) > 0.0 and p["n0"] > 0.0 and p["n1"] >= 0.0


def test_regolith_preset_is_soil_md_reference_set():
    p = load_preset(SOIL_DIR / "regolith.yaml")
    ref = {"c": 800, "phi_deg": 37.2, "k_c": 1.37e3, "k_phi": 8.14e5, "n0": 1.0, "n1": 0.0}
    ref |= {"a0": 0.40, "a1": 0.15, "k_x": 0.036, "k_y": 0.020}
    assert {k: p[k] for k in ref} == pytest.approx(ref)


@pytest.mark.parametrize("load", [20.0, 27.0, 40.0])
@pytest.mark.parametrize("path", PRESETS, ids=lambda p: p.stem)
def test_sinkage_and_pull_are_sensible(path, load):
    """Sinkage a few mm .. a radius; pull rising with slip up to 0.5; small drag when rolling."""
    p = load_preset(path)
    h0 = reference_static_sinkage(load, R, B, p)
    assert 0.003 < h0 < R
    pull = [reference_operating_point(load, R, B, p, s)["DP/W"] for s in SLIPS]
    assert all(a < b for a, b in itertools.pairwise(pull)), pull
    assert -0.2 < pull[0] < 0.05  # rolling resistance, not traction, at zero slip
    assert 0.15 < pull[-1] < 0.6  # traction at s = 0.5 bounded by the friction of sand


@pytest.mark.parametrize("path", PRESETS, ids=lambda p: p.stem)
def test_which_presets_dig_in(path):
    """Sustained slip 0.9 at 27 N buries the wheel beyond 0.5 r on dune sand only."""
    p = load_preset(path)
    h = reference_operating_point(ROVER_WHEEL["load"], R, B, p, 0.9)["h"]
    assert (h > 0.5 * R) == (p["name"] == "dune-sand"), h


def test_dune_sand_pull_falls_when_it_digs_in_at_40n():
    p = load_preset(SOIL_DIR / "dune-sand.yaml")
    half, spin = (reference_operating_point(40.0, R, B, p, s) for s in (0.5, 0.9))
    assert spin["h"] > 0.65 * R and spin["DP/W"] < half["DP/W"]


def test_readme_tables_are_current():
    """configs/soil/README.md quotes this reference: regenerate it if a preset changes."""
    text = (SOIL_DIR / "README.md").read_text()
    for load in (27.0, 20.0, 40.0):
        assert markdown_table(PRESETS, load) in text, f"README table at {load} N is stale"
