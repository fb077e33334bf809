"""Alpha spending across looks (issue 46): the boundaries against published values and a
simulation of the looks' joint law."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rover_env.benchmark.spending import boundaries, look_alpha, nominal_alphas, spent


@pytest.mark.parametrize(
    ("rule", "looks", "published"),
    [
        # Lan-DeMets O'Brien-Fleming-type, two-sided 0.05 (0.025 a tail), equally spaced:
        # Jennison & Turnbull (2000) Table 7.6 / gsDesign sfLDOF.
        ("obrien-fleming", 2, [2.963, 1.969]),
        ("obrien-fleming", 4, [4.333, 2.963, 2.359, 2.014]),
        # Pocock-type (gsDesign sfLDPocock), two looks.
        ("pocock", 2, [2.157, 2.201]),
    ],
)
def test_boundaries_match_published_values(rule: str, looks: int, published: list[float]) -> None:
    c = boundaries(rule, 0.05, [(k + 1) / looks for k in range(looks)])
    assert c == pytest.approx(published, abs=1.5e-3)


def test_spending_functions_and_one_look() -> None:
    assert spent("obrien-fleming", 0.05, 1.0) == pytest.approx(0.05)
    assert spent("pocock", 0.05, 1.0) == pytest.approx(0.05)
    assert spent("obrien-fleming", 0.05, 0.5) == pytest.approx(
        4 * stats.norm.sf(stats.norm.isf(0.0125) / np.sqrt(0.5))
    )
    assert nominal_alphas("obrien-fleming", 0.05, 1) == pytest.approx([0.05])
    a1, a2 = nominal_alphas("obrien-fleming", 0.05, 2)
    assert a1 == pytest.approx(0.00305, abs=2e-5) and a2 == pytest.approx(0.0490, abs=1e-4)
    assert look_alpha("obrien-fleming", 0.05, 2, 2) == pytest.approx(a2)
    assert look_alpha("obrien-fleming", 0.05, 2, 3) == 0.0  # beyond max looks: none left
    with pytest.raises(ValueError, match="unknown spending rule"):
        spent("haybittle", 0.05, 0.5)


@pytest.mark.parametrize("rule", ["obrien-fleming", "pocock"])
def test_looks_together_keep_the_family_wise_error(rule: str) -> None:
    """Simulated z statistics of three looks on accumulating data under no difference:
    the boundaries are crossed at the planned cumulative rates, in all at alpha."""
    t = np.array([1 / 3, 2 / 3, 1.0])
    c = np.array(boundaries(rule, 0.05, t))
    rng = np.random.default_rng(46)
    n = 400_000
    w = np.cumsum(rng.normal(size=(n, 3)) * np.sqrt(np.diff(t, prepend=0.0)), axis=1)
    z = w / np.sqrt(t)
    crossed = np.abs(z) >= c
    first = np.cumsum(crossed, axis=1) > 0
    se = np.sqrt(0.05 * 0.95 / n)
    for k in range(3):
        assert first[:, k].mean() == pytest.approx(spent(rule, 0.05, t[k]), abs=4 * se)
    # Naively testing every look at 0.05 would not: that is why looks spend alpha.
    naive = (np.abs(z) >= stats.norm.isf(0.025)).any(axis=1).mean()
    assert naive > 0.08
