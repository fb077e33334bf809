"""The plan of the random-magnitude matrix (benchmarks/bench_diagnose.py): what it draws."""

from __future__ import annotations

from types import ModuleType

from _bench import load_bench


def _bench() -> ModuleType:
    return load_bench("bench_diagnose")


def test_no_pair_holds_an_effect_the_soil_makes_inert() -> None:
    # On loose soil the tire's effects do not act (both generators), so such a pair could
    # never have both effects named. Before stop 30, 16 pairs in 20 plans drew one (seed0 2000:
    # loose soil with friction, and with rolling resistance).
    b = _bench()
    for seed0 in (0, 2000, 3000, 10000):
        pairs = [c for c in b.cases(False, seed0) if c["kind"] == "pair"]
        assert pairs
        for c in pairs:
            names = set(c["effects"])
            assert len(names) == 2
            assert not ("loose_soil" in names and names & b.INERT_ON_SOIL), (seed0, c)
