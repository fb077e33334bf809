"""The plan of the random-magnitude matrix (benchmarks/bench_diagnose.py): what it draws."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_diagnose.py"


def _bench() -> ModuleType:
    if str(BENCH.parent) not in sys.path:  # its sibling modules (_report)
        sys.path.insert(0, str(BENCH.parent))
    spec = importlib.util.spec_from_file_location("bench_diagnose", BENCH)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["bench_diagnose"] = mod
    spec.loader.exec_module(mod)
    return mod


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
