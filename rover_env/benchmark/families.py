"""The benchmark's side-by-side view of scenario families: each family's training
distribution (``NAME@train``) beside its held-out shifts (``NAME@SHIFT``), per controller.

``rover-env benchmark --shift all`` plays both; :func:`family_lines` is the report's section.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rover_env.benchmark.metrics import UNITS

__all__ = ["FAMILY_METRICS", "family_lines"]

FAMILY_METRICS: tuple[str, ...] = (
    "success",
    "energy_per_metre",
    "mean_abs_slip",
    "distance_made_good",
    "time_stuck",
)
"""The metrics of the side-by-side table (every metric is in the per-scenario tables)."""


def _cell(r: dict[str, Any] | None) -> str:
    if r is None:
        return "–"
    half = (r["ci_high"] - r["ci_low"]) / 2
    return f"{r['mean']:.3g} ± {half:.2g}"


def family_lines(summary: Sequence[dict[str, Any]]) -> list[str]:
    """Markdown: per family, a table of controller x metric with one column per variant
    (training distribution first); nothing when no family was played."""
    fams: dict[str, list[str]] = {}
    for r in summary:
        base, at, variant = str(r["scenario"]).partition("@")
        if at and variant not in fams.setdefault(base, []):
            fams[base].append(variant)
    if not fams:
        return []
    lines = [
        "## Families: training distribution and shifts",
        "",
        "Each column is one distribution of the family's worlds (`NAME@VARIANT`, "
        "configs/scenarios; `train` is what training and tuning see, the others are held-out "
        "shifts), on the same seeds. Mean ± half-width of the 95 % t-interval over episodes.",
        "",
    ]
    ctrls = list(dict.fromkeys(r["controller"] for r in summary))
    for base, variants in fams.items():
        variants.sort(key=lambda v: (v != "train", v))
        by = {
            (r["controller"], str(r["scenario"]).partition("@")[2], r["metric"]): r
            for r in summary
            if str(r["scenario"]).partition("@")[0] == base
        }
        lines += [f"### {base}", "", "| controller | metric | " + " | ".join(variants) + " |"]
        lines.append("|---|---|" + "---|" * len(variants))
        for c in ctrls:
            for m in FAMILY_METRICS:
                cells = [_cell(by.get((c, v, m))) for v in variants]
                if all(x == "–" for x in cells):
                    continue
                lines.append(f"| {c} | {m} [{UNITS[m]}] | " + " | ".join(cells) + " |")
        lines.append("")
    return lines
