"""The interval and test arithmetic of the benchmark's tables (Student-t, paired t, Holm)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence
from typing import Any

import numpy as np

__all__ = ["holm", "paired_p", "t_interval"]


def t_interval(x: Sequence[float], level: float = 0.95) -> tuple[float, float, float]:
    """(mean, low, high) of the Student-t interval for the mean of ``x``."""
    from scipy import stats

    a = np.asarray(x, dtype=np.float64)
    m = float(np.mean(a))
    if a.size < 2:
        return m, m, m
    sd = float(np.std(a, ddof=1))
    hw = float(stats.t.ppf(0.5 + level / 2, a.size - 1)) * sd / math.sqrt(a.size)
    return m, m - hw, m + hw


def paired_p(d: Sequence[float]) -> float:
    """Two-sided p-value of the paired t-test that the mean difference ``d`` is 0."""
    from scipy import stats

    a = np.asarray(d, dtype=np.float64)
    if a.size < 2:
        return float("nan")
    m, sd = float(np.mean(a)), float(np.std(a, ddof=1))
    if sd == 0.0:
        return 1.0 if m == 0.0 else 0.0
    t = m / (sd / math.sqrt(a.size))
    return float(2.0 * stats.t.sf(abs(t), a.size - 1))


def holm(p: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values (NaN entries stay NaN and do not count)."""
    idx = [i for i, x in enumerate(p) if math.isfinite(x)]
    m = len(idx)
    out = [float("nan")] * len(p)
    running = 0.0
    for rank, i in enumerate(sorted(idx, key=lambda i: p[i])):
        running = max(running, min(1.0, (m - rank) * p[i]))
        out[i] = running
    return out


def unique(items: Iterable[Any]) -> list[Any]:
    """``items`` without repeats, in first-seen order (controllers, scenarios as run)."""
    seen: dict[Any, None] = {}
    for i in items:
        seen.setdefault(i, None)
    return list(seen)


def paired_rows(
    rows: Sequence[dict[str, Any]], baseline: str
) -> Iterator[tuple[str, str, list[dict[str, Any]], list[dict[str, Any]]]]:
    """(controller, scenario, baseline rows, controller rows) of every other controller and
    scenario, on the seeds both played, in seed order: what every paired comparison pairs."""
    for other in [c for c in unique(r["controller"] for r in rows) if c != baseline]:
        for scen in unique(r["scenario"] for r in rows):
            a = {
                r["seed"]: r for r in rows if r["controller"] == baseline and r["scenario"] == scen
            }
            b = {r["seed"]: r for r in rows if r["controller"] == other and r["scenario"] == scen}
            shared = sorted(set(a) & set(b))
            if shared:
                yield other, scen, [a[s] for s in shared], [b[s] for s in shared]
