"""The line a user would sign: *better* only when nothing that matters got worse.

Per scenario, each controller is compared with the baseline (the run's first controller) on
the verdict metrics (:data:`PRIMARY`: success at the commanded pace, energy per metre, mean
sinkage), on the same seeds. Each metric's state comes from the two-sided paired t-test after
Holm's correction over every comparison of the verdict table (controllers x scenarios x
metrics) at the look's alpha (:mod:`rover_env.benchmark.spending`): *better* or *worse* when
the Holm-adjusted p is below alpha, else *no difference* (which is not proof of equality).
The intervals shown are the paired t-intervals at the Bonferroni level 1 - alpha/m, m the
number of comparisons: simultaneous intervals that exclude 0 only where Holm also rejects.

The verdict of a (controller, scenario):

* **better**: at least one metric better and none worse;
* **trade**: some better, some worse (the report names which, and draws the frontier of
  energy per metre against time to goal, :func:`frontier_plot`);
* **worse**: some worse, none better;
* **no difference**: none resolved; **no alpha left**: the look has alpha 0 (beyond the
  question's planned looks), so nothing is claimed.

This replaces the soil lines of issue 15 (energy *or* sinkage), under which a controller
could pass with energy +30 % worse.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rover_env.benchmark.metrics import LOWER_IS_BETTER, UNITS
from rover_env.benchmark.stats import holm, paired_p, paired_rows, t_interval
from rover_env.benchmark.stats import unique as _unique

__all__ = ["PRIMARY", "frontier_plot", "verdict_markdown", "verdicts"]

PRIMARY: tuple[str, ...] = ("success", "energy_per_metre", "mean_sinkage")
"""The verdict metrics: success (goal at the commanded pace), energy per metre, sinkage."""


def _comparisons(
    rows: Sequence[dict[str, Any]], baseline: str, metrics: Sequence[str], level: float
) -> list[dict[str, Any]]:
    out = []
    for other, scen, a, b in paired_rows(rows, baseline):
        for m in metrics:
            d = [float(rb[m]) - float(ra[m]) for ra, rb in zip(a, b, strict=True)]
            mean, lo, hi = t_interval(d, level)
            out.append(
                {
                    "controller": other,
                    "scenario": scen,
                    "metric": m,
                    "n": len(a),
                    "baseline_mean": float(np.mean([float(r[m]) for r in a])),
                    "diff_mean": mean,
                    "ci_low": lo,
                    "ci_high": hi,
                    "p": paired_p(d),
                }
            )
    return out


def verdicts(
    rows: Sequence[dict[str, Any]],
    baseline: str,
    alpha: float,
    metrics: Sequence[str] = PRIMARY,
) -> list[dict[str, Any]]:
    """One row per (controller, scenario): ``verdict``, ``better``, ``worse`` (metric lists)
    and ``metrics`` (each metric's comparison: difference, interval, p, Holm p, state)."""
    m = sum(1 for _ in _comparisons(rows, baseline, metrics, 0.95))
    level = 1.0 - alpha / max(m, 1) if alpha > 0 else 0.95
    comps = _comparisons(rows, baseline, metrics, level)
    for c, q in zip(comps, holm([c["p"] for c in comps]), strict=True):
        c["p_holm"] = q
        c["level"] = level
        if c["n"] < 2 or alpha <= 0 or not (q < alpha):
            c["state"] = "no difference"
        else:
            c["state"] = (
                "better" if (c["diff_mean"] < 0) == LOWER_IS_BETTER[c["metric"]] else "worse"
            )
    out = []
    for other in _unique(c["controller"] for c in comps):
        for scen in _unique(c["scenario"] for c in comps if c["controller"] == other):
            mine = [c for c in comps if c["controller"] == other and c["scenario"] == scen]
            better = [c["metric"] for c in mine if c["state"] == "better"]
            worse = [c["metric"] for c in mine if c["state"] == "worse"]
            if mine[0]["n"] < 2:
                v = "n = 1"
            elif alpha <= 0:
                v = "no alpha left"
            elif better and worse:
                v = "trade"
            elif better:
                v = "better"
            elif worse:
                v = "worse"
            else:
                v = "no difference"
            out.append(
                {
                    "controller": other,
                    "baseline": baseline,
                    "scenario": scen,
                    "verdict": v,
                    "better": better,
                    "worse": worse,
                    "metrics": {c["metric"]: c for c in mine},
                    "comparisons": len(comps),
                    "alpha": alpha,
                }
            )
    return out


def _fmt(x: float) -> str:
    if not math.isfinite(x):
        return "nan"
    return f"{x:.3g}"


def verdict_markdown(
    vs: Sequence[dict[str, Any]], summary: Sequence[dict[str, Any]], look: str = ""
) -> list[str]:
    """The verdict table (markdown lines) beside the pace and tracking of both controllers."""
    if not vs:
        return []
    alpha, m = vs[0]["alpha"], vs[0]["comparisons"]
    metrics = list(vs[0]["metrics"])
    means = {(r["controller"], r["scenario"], r["metric"]): r["mean"] for r in summary}
    lines = [
        "## Verdict (controller against baseline)",
        "",
        (look + " " if look else "")
        + f"*better*: at least one of {', '.join(metrics)} better and none worse, each by the "
        f"paired t-test after Holm over the {m} comparisons of this table at alpha {alpha:.4g}; "
        "*trade*: some better, some worse (frontier plot: `frontier.png`); *worse*: some worse, "
        f"none better. Differences with their Bonferroni {100 * (1 - alpha / max(m, 1)):.2f} % "
        "paired intervals (simultaneous). Success is the goal reached within ±25 % of the "
        "commanded pace; pace is the mean speed over the mean commanded speed.",
        "",
        "| scenario | controller − baseline | "
        + " | ".join(f"Δ {x} [{UNITS[x]}]" for x in metrics)
        + " | pace (base → ctrl) | RMS speed error (base → ctrl) | verdict |",
        "|" + "---|" * (len(metrics) + 5),
    ]
    for v in vs:
        cells = []
        for x in metrics:
            c = v["metrics"][x]
            cells.append(f"{_fmt(c['diff_mean'])} [{_fmt(c['ci_low'])}, {_fmt(c['ci_high'])}]")
        key = (v["baseline"], v["scenario"])
        own = (v["controller"], v["scenario"])
        pace = f"{_fmt(means.get((*key, 'pace_ratio'), math.nan))} → "
        pace += _fmt(means.get((*own, "pace_ratio"), math.nan))
        rms = f"{_fmt(means.get((*key, 'rms_speed_error'), math.nan))} → "
        rms += _fmt(means.get((*own, "rms_speed_error"), math.nan))
        word = v["verdict"]
        if word == "trade":
            word += f" (better: {', '.join(v['better'])}; worse: {', '.join(v['worse'])})"
        lines.append(
            f"| {v['scenario']} | {v['controller']} − {v['baseline']} | "
            + " | ".join(cells)
            + f" | {pace} | {rms} | **{word}** |"
        )
    lines.append("")
    return lines


def frontier_plot(
    out: Path, summary: Sequence[dict[str, Any]], scenarios: Sequence[str]
) -> Path | None:
    """Energy per metre against time to goal, one point per controller with its 95 % intervals,
    one panel per scenario in ``scenarios`` (those with a trade); None when there is none."""
    if not scenarios:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    by = {(r["controller"], r["scenario"], r["metric"]): r for r in summary}
    ctrls = _unique(r["controller"] for r in summary)
    fig, axes = plt.subplots(1, len(scenarios), figsize=(6 * len(scenarios), 5), squeeze=False)
    for ax, scen in zip(axes[0], scenarios, strict=True):
        for c in ctrls:
            e, t = by.get((c, scen, "energy_per_metre")), by.get((c, scen, "time_to_goal"))
            if e is None or t is None:
                continue
            ax.errorbar(
                t["mean"],
                e["mean"],
                xerr=[[t["mean"] - t["ci_low"]], [t["ci_high"] - t["mean"]]],
                yerr=[[e["mean"] - e["ci_low"]], [e["ci_high"] - e["mean"]]],
                fmt="o",
                capsize=3,
                label=c,
            )
        ax.set_xlabel("time to goal [s] (a missed goal counts the episode's length)")
        ax.set_ylabel("energy per metre [J/m]")
        ax.set_title(scen)
        ax.legend(fontsize=8)
    fig.suptitle("Trade-off frontier: energy per metre against time to goal (mean, 95 % CI)")
    fig.tight_layout()
    path = out / "frontier.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
