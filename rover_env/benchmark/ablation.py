"""The no-learning ablation of a learned agent: the best *fixed* setting of the knob it learns.

A learned gain schedule is worth what it adds over the best constant setting of the same
knob, so every learned agent is shown beside that constant, found on the validation seeds
(never on test). :func:`run_ablation` runs the slip PI ``base`` with ``knob`` fixed at each
value of a grid (``slip-pi[:GAINS]@knob=value`` controllers) on the same validation
episodes, writes the benchmark's tables for the grid (the first value is the baseline of
the Holm-corrected paired table) and ranks the values by one metric.

Ranking: each scenario's mean of ``metric`` is divided by that scenario's mean over the
whole grid, so that every scenario counts alike (a stuck rover's |S| is fifty times a
fighting axle's), and the values are ordered by the mean of these ratios over scenarios
(lowest first for a lower-is-better metric).

Command line: ``rover-env ablate --base slip-pi:slip_pi_axle_fight --knob stuck_retry_scale
--values 0.5,0.71,1,1.41,2 --scenarios stuck-wheel,split-mu,ice-patch``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["AblationResult", "grid_specs", "rank", "run_ablation"]


@dataclass(frozen=True)
class AblationResult:
    specs: list[str]
    scores: dict[str, float]
    """spec -> mean over scenarios of the metric relative to the scenario's grid mean."""
    best: str
    files: dict[str, Path]


def grid_specs(base: str, knob: str, values: Sequence[float]) -> list[str]:
    """One controller spec per value: ``base@knob=value`` (validated)."""
    from rover_env.policies.specs import parse_specs

    if not values:
        raise ValueError("the ablation grid needs at least one value")
    specs = [f"{base}@{knob}={float(v):g}" for v in values]
    return parse_specs(",".join(specs))


def rank(rows: Sequence[dict[str, Any]], specs: Sequence[str], metric: str) -> dict[str, float]:
    """Score of each spec (module docstring), from the benchmark's episode rows."""
    from rover_env.benchmark.metrics import LOWER_IS_BETTER

    if metric not in LOWER_IS_BETTER:
        raise ValueError(f"unknown metric {metric!r}; have {', '.join(LOWER_IS_BETTER)}")
    scenarios = sorted({r["scenario"] for r in rows})
    means: dict[tuple[str, str], float] = {}
    for spec in specs:
        for scen in scenarios:
            x = [
                float(r[metric]) for r in rows if r["controller"] == spec and r["scenario"] == scen
            ]
            means[spec, scen] = sum(x) / len(x)
    scores = {}
    for spec in specs:
        ratios = []
        for scen in scenarios:
            grid_mean = sum(means[s, scen] for s in specs) / len(specs)
            ratios.append(means[spec, scen] / grid_mean if grid_mean != 0 else 1.0)
        scores[spec] = sum(ratios) / len(ratios)
    return scores


def run_ablation(
    base: str,
    knob: str,
    values: Sequence[float],
    scenarios: Sequence[str],
    episodes: int,
    out: str | Path,
    metric: str = "mean_abs_slip",
    split: str = "validation",
    duration: float | None = None,
    workers: int = 1,
    progress: bool = True,
    command: str | None = None,
) -> AblationResult:
    """Run the grid on ``split`` (validation or tuning, never test) and rank it by ``metric``."""
    from rover_env.benchmark.metrics import LOWER_IS_BETTER
    from rover_env.benchmark.suite import run_benchmark

    if split not in ("validation", "tuning"):
        raise ValueError(f"an ablation selects a setting: run it on validation, not {split!r}")
    specs = grid_specs(base, knob, values)
    files = run_benchmark(
        specs,
        scenarios,
        episodes,
        out,
        split=split,
        duration=duration,
        workers=workers,
        progress=progress,
        plots=False,
        command=command,
    )
    import csv

    with files["episodes"].open() as fh:
        rows = list(csv.DictReader(fh))
    scores = rank(rows, specs, metric)
    sign = 1.0 if LOWER_IS_BETTER[metric] else -1.0
    best = min(specs, key=lambda s: sign * scores[s])
    lines = [
        f"# Ablation: {base} with {knob} fixed ({split} seeds)",
        "",
        f"Ranked by {metric}, each scenario's mean over that scenario's grid mean, averaged "
        f"over {', '.join(scenarios)} ({episodes} seeds each); "
        f"{'lower' if sign > 0 else 'higher'} is better. Tables: `benchmark.md`.",
        "",
        f"| {knob} | score | " + " | ".join(f"{s} {metric}" for s in scenarios) + " |",
        "|---|---|" + "---|" * len(scenarios),
    ]
    for spec, v in zip(specs, values, strict=True):
        cells = []
        for scen in scenarios:
            x = [
                float(r[metric]) for r in rows if r["controller"] == spec and r["scenario"] == scen
            ]
            cells.append(f"{sum(x) / len(x):.4g}")
        mark = " (best)" if spec == best else ""
        score = scores[spec]
        lines.append(
            f"| {float(v):g}{mark} | {score:.4f} | " + " | ".join(cells) + " |"
            if math.isfinite(score)
            else f"| {float(v):g} | nan | " + " | ".join(cells) + " |"
        )
    lines += ["", f"Best fixed setting: `{best}`.", ""]
    files["ablation"] = Path(out) / "ablation.md"
    files["ablation"].write_text("\n".join(lines))
    return AblationResult(specs=specs, scores=scores, best=best, files=files)
