"""Alpha spending across the looks at one research question (Lan-DeMets).

A question of the test ledger (:mod:`rover_env.benchmark.questions`) may be looked at up to
``max_looks`` times; every look spends part of its family-wise error ``alpha`` so that the
chance of any false claim over all looks stays at ``alpha``. The spending function is fixed
in the question file before the first look:

* ``obrien-fleming``: the O'Brien-Fleming-type function of Lan and DeMets (1983), spent per
  tail at alpha/2, ``a(t) = 2 - 2 Phi(z_{1 - alpha/4} / sqrt(t))``: almost nothing early, most
  of alpha at the last look;
* ``pocock``: the Pocock-type function, ``a(t) = alpha ln(1 + (e - 1) t)``: about even.

Looks are planned equally spaced: look k of K sits at information fraction t = k / K. The
boundaries are two-sided and symmetric, the usual convention of group-sequential software
(gsDesign's ``test.type=2``, ldbounds' two-sided bounds): with alpha 0.05 and two looks the
O'Brien-Fleming-type z boundaries are 2.963 and 1.969 (nominal two-sided p 0.0030 and
0.0490), the Pocock-type 2.157 and 2.201. They come from the joint normal law of the
looks' z statistics, corr(Z_j, Z_k) = sqrt(t_j / t_k), integrated numerically on a grid
(Armitage, McPherson and Rowe's recursion), so the same question always gets the same
numbers.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
from scipy import optimize, stats

__all__ = ["RULES", "boundaries", "look_alpha", "nominal_alphas", "spent"]

RULES = ("obrien-fleming", "pocock")

_GRID = 801
"""Points of the recursion's grid over the continuation region (boundaries to ~1e-6)."""


def spent(rule: str, alpha: float, t: float) -> float:
    """Cumulative two-sided alpha spent by information fraction ``t`` (0 < t <= 1)."""
    if not 0.0 < t <= 1.0 + 1e-12:
        raise ValueError(f"information fraction must be in (0, 1], got {t}")
    if rule == "obrien-fleming":
        z = float(stats.norm.isf(alpha / 4.0))
        return float(2.0 * 2.0 * stats.norm.sf(z / math.sqrt(t)))
    if rule == "pocock":
        return alpha * math.log(1.0 + (math.e - 1.0) * t)
    raise ValueError(f"unknown spending rule {rule!r}; have {', '.join(RULES)}")


def _crossing(cont: np.ndarray, dens: np.ndarray, dt: float, b: float) -> float:
    """P(|W_next| >= b, not stopped before) from the density ``dens`` of W on ``cont``."""
    s = math.sqrt(dt)
    tail = stats.norm.sf((b - cont) / s) + stats.norm.cdf((-b - cont) / s)
    return float(np.trapezoid(dens * tail, cont))


def boundaries(rule: str, alpha: float, fractions: Sequence[float]) -> list[float]:
    """Two-sided z boundaries c_k: P(|Z_k| >= c_k at look k, none before) spends exactly
    ``spent(t_k) - spent(t_{k-1})`` under no difference (module docstring)."""
    t = [float(x) for x in fractions]
    if not t or any(b <= a for a, b in itertools.pairwise(t)) or t[-1] > 1 + 1e-12:
        raise ValueError(f"information fractions must increase within (0, 1], got {t}")
    out = [float(stats.norm.isf(spent(rule, alpha, t[0]) / 2.0))]
    # W(t) = Z sqrt(t) is Brownian motion; dens is the density of W on the continuation
    # region of the last look (paths not yet stopped).
    b = out[0] * math.sqrt(t[0])
    cont = np.linspace(-b, b, _GRID)
    dens = stats.norm.pdf(cont / math.sqrt(t[0])) / math.sqrt(t[0])
    for k in range(1, len(t)):
        dt = t[k] - t[k - 1]
        target = spent(rule, alpha, t[k]) - spent(rule, alpha, t[k - 1])

        c = float(
            optimize.brentq(
                lambda c, x=cont, f=dens, dt=dt, k=k, target=target: (
                    _crossing(x, f, dt, c * math.sqrt(t[k])) - target
                ),
                0.1,
                12.0,
                xtol=1e-10,
            )
        )
        out.append(c)
        b_new = c * math.sqrt(t[k])
        new = np.linspace(-b_new, b_new, _GRID)
        s = math.sqrt(dt)
        kern = stats.norm.pdf((new[:, None] - cont[None, :]) / s) / s
        dens = np.trapezoid(kern * dens[None, :], cont, axis=1)
        cont = new
    return out


def nominal_alphas(rule: str, alpha: float, max_looks: int) -> list[float]:
    """Nominal two-sided significance level of each of ``max_looks`` equally spaced looks."""
    if max_looks < 1:
        raise ValueError(f"max_looks must be >= 1, got {max_looks}")
    c = boundaries(rule, alpha, [(k + 1) / max_looks for k in range(max_looks)])
    return [float(2.0 * stats.norm.sf(x)) for x in c]


def look_alpha(rule: str, alpha: float, max_looks: int, look: int) -> float:
    """The nominal alpha of look ``look`` (1-based); 0 beyond ``max_looks`` (none left)."""
    if look < 1:
        raise ValueError(f"looks count from 1, got {look}")
    if look > max_looks:
        return 0.0
    return nominal_alphas(rule, alpha, max_looks)[look - 1]
