"""The option A/B's case plan: the same seeds give the same cases, and clean builds come after
the effects without reusing a seed (a clean case's logs must not be an effect case's)."""

from __future__ import annotations

import pytest
from _bench import load_bench


def test_plan_adds_clean_builds_after_the_effects() -> None:
    ab = load_bench("option_ab")
    cases = ab.plan(500, 2, 3, clean=2)
    seeds = [s for s, _, _ in cases]
    assert len(set(seeds)) == len(seeds) == 7
    assert [e for _, e, _ in cases[-2:]] == [ab.CLEAN, ab.CLEAN]
    assert [s for s, _, _ in cases[-2:]] == [505, 506]
    assert all(p == {} for _, e, p in cases if e == ab.CLEAN)
    assert sum(e == "torque_limit" for _, e, _ in cases) == 2
    # Adding clean builds leaves the effect cases as they were.
    assert cases[:5] == ab.plan(500, 2, 3)
    assert ab.plan(500, 0, 0, clean=3) == [(500 + k, ab.CLEAN, {}) for k in range(3)]


def test_plan_draws_the_other_effects_from_the_pool_given() -> None:
    ab = load_bench("option_ab")
    soils = ab.plan(900, 0, 4, clean=1, pool=("loose_soil",))
    assert [e for _, e, _ in soils] == ["loose_soil"] * 4 + [ab.CLEAN]
    assert all("k_phi" in p for _, e, p in soils[:4])
    # Each soil is the generator's own draw for its seed, as the full matrix draws it.
    draw = ab.generator_params
    assert [p for _, _, p in soils[:4]] == [draw("loose_soil", 900 + k) for k in range(4)]
    assert len({p["k_phi"] for _, _, p in soils[:4]}) == 4
    assert {p["sand"] for _, _, p in soils[:4]} == {0.0}
    sands = ab.plan(900, 0, 4, pool=("loose_soil",), dry_sand=True)
    assert [p["sand"] for _, _, p in sands] == [0.0, 1.0, 0.0, 1.0]
    assert [p["k_phi"] for _, _, p in sands] == [p["k_phi"] for _, _, p in soils[:4]]


def test_plan_draws_strong_effects_over_their_strong_ranges() -> None:
    ab = load_bench("option_ab")
    rr = ab.plan(950, 0, 6, pool=("rolling_resistance",), strong=True)
    _, lo, hi, _ = ab.STRONG["rolling_resistance"]
    assert all(lo <= p["c_rr"] <= hi for _, _, p in rr)
    assert [p for _, _, p in rr] == [
        ab.strong_params("rolling_resistance", 950 + k) for k in range(6)
    ]
    with pytest.raises(ValueError, match="friction"):
        ab.plan(950, 0, 2, pool=("friction",), strong=True)
