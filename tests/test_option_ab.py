"""The option A/B's case plan: the same seeds give the same cases, and clean builds come after
the effects without reusing a seed (a clean case's logs must not be an effect case's)."""

from __future__ import annotations

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
