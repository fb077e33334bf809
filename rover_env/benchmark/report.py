"""Tables and plots of a benchmark: mean +- 95 % CI per metric, and paired differences.

Intervals are Student-t intervals: over episodes for a controller's mean, over seeds for the
paired difference of two controllers run on the same seeds (the paired t-interval, which
removes the between-seed spread the two share). With one episode there is no spread to
estimate; the half-width is then reported as 0 and the tables say n = 1.

A paired table makes many comparisons at once (controllers x scenarios x metrics), so its
verdicts (*better*, *worse*) come from the paired t-test's p-values after Holm's correction
over all comparisons of the table (family-wise error 5 %), not from each interval alone;
the table states the number of comparisons. Beside every relative difference it gives the
absolute one and both means. The claim a user signs is the verdict table
(:mod:`rover_env.benchmark.verdict`): success, energy per metre and sinkage together. A final
run's tables use its look's alpha (:mod:`rover_env.benchmark.spending`) in place of 5 %.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rover_env.benchmark.families import family_lines
from rover_env.benchmark.metrics import LOWER_IS_BETTER, METRICS, UNITS, UNORDERED
from rover_env.benchmark.stats import holm, paired_p, paired_rows, t_interval
from rover_env.benchmark.stats import unique as _unique
from rover_env.benchmark.verdict import frontier_plot, verdict_markdown, verdicts

__all__ = [
    "ALPHA",
    "UNITS",
    "holm",
    "paired",
    "paired_p",
    "summarise",
    "t_interval",
    "write_report",
]

ALPHA = 0.05
"""Family-wise error rate of a paired table's verdicts (Holm)."""


def summarise(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (controller, scenario, metric): n, mean, sd, ci_low, ci_high."""
    out = []
    for ctrl in _unique(r["controller"] for r in rows):
        for scen in _unique(r["scenario"] for r in rows):
            sel = [r for r in rows if r["controller"] == ctrl and r["scenario"] == scen]
            if not sel:
                continue
            for m in METRICS:
                x = [float(r[m]) for r in sel]
                mean, lo, hi = t_interval(x)
                sd = float(np.std(x, ddof=1)) if len(x) > 1 else 0.0
                out.append(
                    {
                        "controller": ctrl,
                        "scenario": scen,
                        "metric": m,
                        "n": len(x),
                        "mean": mean,
                        "sd": sd,
                        "ci_low": lo,
                        "ci_high": hi,
                    }
                )
    return out


def paired(
    rows: Sequence[dict[str, Any]], baseline: str, alpha: float = ALPHA
) -> list[dict[str, Any]]:
    """Every other controller minus ``baseline``, per scenario and metric, on shared seeds;
    verdicts after Holm's correction over all rows returned at ``alpha`` (module docstring)."""
    out: list[dict[str, Any]] = []
    for other, scen, a, b in paired_rows(rows, baseline):
        for m in METRICS:
            d = [float(rb[m]) - float(ra[m]) for ra, rb in zip(a, b, strict=True)]
            mean, lo, hi = t_interval(d)
            base_mean = float(np.mean([float(r[m]) for r in a]))
            out.append(
                {
                    "controller": other,
                    "baseline": baseline,
                    "scenario": scen,
                    "metric": m,
                    "n": len(a),
                    "baseline_mean": base_mean,
                    "controller_mean": base_mean + mean,
                    "diff_mean": mean,
                    "ci_low": lo,
                    "ci_high": hi,
                    "relative": mean / base_mean if base_mean != 0 else float("nan"),
                    "p": paired_p(d),
                }
            )
    adjusted = holm([r["p"] for r in out])
    family = sum(math.isfinite(r["p"]) for r in out)
    for r, q in zip(out, adjusted, strict=True):
        r["p_holm"] = q
        r["comparisons"] = family
        if r["n"] < 2:
            r["verdict"] = "n = 1"
        elif q < alpha:
            lower = LOWER_IS_BETTER[r["metric"]]
            r["verdict"] = "better" if (r["diff_mean"] < 0) == lower else "worse"
            if r["metric"] in UNORDERED:
                r["verdict"] = "higher" if r["diff_mean"] > 0 else "lower"
        else:
            r["verdict"] = "no difference"
    return out


def _flat(v: dict[str, Any]) -> dict[str, Any]:
    """A verdict row for the CSV: one column per metric's difference, interval and state."""
    out = {k: v[k] for k in ("controller", "baseline", "scenario", "verdict", "alpha")}
    out["better"], out["worse"] = " ".join(v["better"]), " ".join(v["worse"])
    for m, c in v["metrics"].items():
        for k in ("diff_mean", "ci_low", "ci_high", "p_holm", "state"):
            out[f"{m}_{k}"] = c[k]
    return out


def _fmt(x: float) -> str:
    if not math.isfinite(x):
        return "nan"
    if x == 0:
        return "0"
    a = abs(x)
    if a >= 100:
        return f"{x:.0f}"
    if a >= 1:
        return f"{x:.2f}"
    if a >= 0.01:
        return f"{x:.3f}"
    return f"{x:.2e}"


def _write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    if not rows:
        path.write_text("")
        return
    names = list(dict.fromkeys(k for r in rows for k in r))  # a family's world.* columns
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=names)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def _markdown(
    summary: Sequence[dict[str, Any]],
    pairs: Sequence[dict[str, Any]],
    meta: dict[str, Any],
    verdict_lines: Sequence[str] = (),
    alpha: float = ALPHA,
) -> str:
    lines = ["# Controller benchmark", ""]
    for k, v in meta.items():
        lines.append(f"- {k}: {v}")
    lines += [
        "",
        "Mean ± half-width of the 95 % Student-t interval over episodes (seeds). Metrics: "
        "`rover_env.benchmark.metrics.episode_metrics`; slip is the simulator's true slip of the "
        "driven wheels.",
        "",
    ]
    ctrls = _unique(r["controller"] for r in summary)
    for scen in _unique(r["scenario"] for r in summary):
        lines += [f"## {scen}", ""]
        head = "| controller | n | " + " | ".join(f"{m} [{UNITS[m]}]" for m in METRICS) + " |"
        lines += [head, "|" + "---|" * (len(METRICS) + 2)]
        for c in ctrls:
            sel = {
                r["metric"]: r for r in summary if r["controller"] == c and r["scenario"] == scen
            }
            if not sel:
                continue
            n = next(iter(sel.values()))["n"]
            cells = [
                f"{_fmt(sel[m]['mean'])} ± {_fmt((sel[m]['ci_high'] - sel[m]['ci_low']) / 2)}"
                for m in METRICS
            ]
            lines.append(f"| {c} | {n} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += verdict_lines
    lines += family_lines(summary)
    if pairs:
        family = pairs[0]["comparisons"]
        lines += [
            "## Paired differences (controller − baseline, same seeds)",
            "",
            "95 % paired t-interval of the per-seed difference (absolute, in the metric's "
            "unit); *relative* is that difference over the baseline's mean. *better*/*worse* "
            f"(*higher*/*lower* for the pace ratio): the paired t-test rejects no difference "
            f"after Holm's correction over the {family} comparisons of this table (p Holm < "
            f"{alpha:.4g}); the intervals are not adjusted. The verdict above is the claim.",
            "",
            "| scenario | controller − baseline | metric | n | baseline mean | controller mean "
            "| difference [95 % CI] | relative | p (Holm) | verdict |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in pairs:
            rel = f"{100 * r['relative']:+.1f} %" if math.isfinite(r["relative"]) else "–"
            ph = f"{r['p_holm']:.2g}" if math.isfinite(r["p_holm"]) else "–"
            lines.append(
                f"| {r['scenario']} | {r['controller']} − {r['baseline']} | {r['metric']} | "
                f"{r['n']} | {_fmt(r['baseline_mean'])} | {_fmt(r['controller_mean'])} | "
                f"{_fmt(r['diff_mean'])} [{_fmt(r['ci_low'])}, {_fmt(r['ci_high'])}] | {rel} | "
                f"{ph} | {r['verdict']} |"
            )
        lines.append("")
    return "\n".join(lines)


def _plots(
    out: Path, summary: Sequence[dict[str, Any]], pairs: Sequence[dict[str, Any]]
) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    ctrls = _unique(r["controller"] for r in summary)
    scens = _unique(r["scenario"] for r in summary)
    fig, axes = plt.subplots(4, 4, figsize=(18, 16))
    width = 0.8 / max(len(ctrls), 1)
    x = np.arange(len(scens))
    for ax, m in zip(axes.ravel(), METRICS, strict=False):
        for i, c in enumerate(ctrls):
            sel = {r["scenario"]: r for r in summary if r["controller"] == c and r["metric"] == m}
            means = np.array([sel[s]["mean"] if s in sel else np.nan for s in scens])
            lo = np.array([sel[s]["ci_low"] if s in sel else np.nan for s in scens])
            hi = np.array([sel[s]["ci_high"] if s in sel else np.nan for s in scens])
            ax.bar(
                x + (i - (len(ctrls) - 1) / 2) * width,
                means,
                width,
                label=c,
                yerr=np.vstack([means - lo, hi - means]),
                capsize=2,
            )
        ax.set_title(f"{m} [{UNITS[m]}]")
        ax.set_xticks(x, scens, rotation=30, ha="right", fontsize=8)
        if m == "energy_per_metre":
            ax.set_yscale("log")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("Benchmark: mean and 95 % CI per scenario")
    for ax in axes.ravel()[len(METRICS) :]:
        ax.axis("off")
    fig.tight_layout()
    files.append(out / "metrics.png")
    fig.savefig(files[-1], dpi=110)
    plt.close(fig)

    for other in _unique(r["controller"] for r in pairs):
        mine = [r for r in pairs if r["controller"] == other]
        base = mine[0]["baseline"]
        fig, axes = plt.subplots(4, 4, figsize=(18, 16))
        for ax, m in zip(axes.ravel(), METRICS, strict=False):
            by = {r["scenario"]: r for r in mine if r["metric"] == m}
            d = np.array([by[s]["diff_mean"] if s in by else np.nan for s in scens])
            lo = np.array([by[s]["ci_low"] if s in by else np.nan for s in scens])
            hi = np.array([by[s]["ci_high"] if s in by else np.nan for s in scens])
            ax.errorbar(x, d, yerr=np.vstack([d - lo, hi - d]), fmt="o", capsize=3)
            ax.axhline(0.0, color="k", lw=0.8)
            ax.set_title(f"{m} [{UNITS[m]}]")
            ax.set_xticks(x, scens, rotation=30, ha="right", fontsize=8)
        fig.suptitle(f"Paired difference {other} − {base} (95 % paired t-interval)")
        for ax in axes.ravel()[len(METRICS) :]:
            ax.axis("off")
        fig.tight_layout()
        safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in f"{other}_vs_{base}")
        files.append(out / f"paired_{safe}.png")
        fig.savefig(files[-1], dpi=110)
        plt.close(fig)
    return files


def write_report(
    out: str | Path,
    rows: Sequence[dict[str, Any]],
    meta: dict[str, Any] | None = None,
    plots: bool = True,
    alpha: float = ALPHA,
    look: str = "",
) -> dict[str, Path]:
    """Write episodes.csv, summary.csv, paired.csv, verdict.csv, benchmark.md and the PNG
    plots (``frontier.png`` where a verdict is a trade). ``alpha``: the look's, ``look``: a
    sentence saying which look of which question it is (final runs)."""
    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    summary = summarise(rows)
    ctrls = _unique(r["controller"] for r in rows)
    pairs = paired(rows, ctrls[0], alpha) if len(ctrls) > 1 else []
    vs = verdicts(rows, ctrls[0], alpha) if len(ctrls) > 1 else []
    files = {
        "episodes": d / "episodes.csv",
        "summary": d / "summary.csv",
        "paired": d / "paired.csv",
        "verdict": d / "verdict.csv",
        "markdown": d / "benchmark.md",
    }
    _write_csv(files["episodes"], rows)
    _write_csv(files["summary"], summary)
    _write_csv(files["paired"], pairs)
    _write_csv(files["verdict"], [_flat(v) for v in vs])
    vlines = verdict_markdown(vs, summary, look)
    files["markdown"].write_text(_markdown(summary, pairs, meta or {}, vlines, alpha))
    if plots:
        for p in _plots(d, summary, pairs):
            files[p.stem] = p
        traded = _unique(v["scenario"] for v in vs if v["verdict"] == "trade")
        front = frontier_plot(d, summary, traded)
        if front is not None:
            files["frontier"] = front
    return files
