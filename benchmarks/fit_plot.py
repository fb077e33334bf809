"""Fitted against true magnitude for the single-effect cases of a ``bench_independent.py``
run: one panel per effect, each case's fit with its stored 95 % interval, filled where the
effect was named, with the report's "named from" beside it (the bar a name must clear; a
soil's is a k_phi to be softer than). Signed effects are drawn by magnitude, the fit's sign
taken with the truth's.

    python benchmarks/fit_plot.py OUT/independent.json --out OUT/fit_vs_truth.png

Why a figure: a table lists each case; the panel shows at a glance whether the misses sit
under the bar (not expected to be named), over it (failures), or were named with an
interval that misses the line.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

UNITS = {
    "command_lag": "tau (s)",
    "command_delay": "delay (s)",
    "slope": "deg",
    "rolling_resistance": "c_rr",
    "rolling_radius": "|fraction|",
    "loose_soil": "k_phi (N/m^(n+2))",
    "friction": "fraction",
    "torque_limit": "|fraction|",
    "load_dependent_friction": "fall",
}


def points(rows: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """Per effect, each finished single's truth, fit, interval, bar and whether it was named
    (magnitudes: a radius's sign dropped; a soil's k_phi as is, its bar 1e6 / bar)."""
    out: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        if r.get("error") or r.get("kind") != "single" or not isinstance(r.get("truth"), dict):
            continue
        ((name, _),) = r["truth"].items()
        f = r["fits"].get(name) or {}
        if f.get("truth") is None or f.get("value") is None:
            continue
        soil = name == "loose_soil"
        sign = -1.0 if (not soil and f["truth"] < 0) else 1.0
        bar = f.get("nameable")

        def mag(v: float | None, sign: float = sign) -> float | None:
            return None if v is None or not math.isfinite(v) else sign * v

        lo, hi = mag(f.get("lo")), mag(f.get("hi"))
        if sign < 0:
            lo, hi = hi, lo
        out.setdefault(name, []).append(
            {
                "case": r["case"],
                "truth": sign * f["truth"],
                "value": mag(f["value"]),
                "lo": lo,
                "hi": hi,
                "bar": (1e6 / bar if soil else bar) if bar else None,
                "named": name in r["named"],
            }
        )
    return out


def draw(per: dict[str, list[dict[str, Any]]], out: Path, title: str) -> None:
    """One panel per effect (matplotlib, Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = sorted(per)
    cols = min(3, len(names)) or 1
    rows = math.ceil(len(names) / cols) or 1
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.8 * rows), squeeze=False)
    for ax, name in zip(axes.flat, names, strict=False):
        pts = per[name]
        top = max(max(p["truth"], p["value"] or 0.0, p["hi"] or 0.0) for p in pts) * 1.15
        for p in pts:
            v = p["value"] if p["value"] is not None else 0.0
            lo = p["lo"] if p["lo"] is not None else 0.0
            hi = p["hi"] if p["hi"] is not None else top
            ax.errorbar(
                p["truth"],
                v,
                yerr=[[max(v - lo, 0.0)], [max(hi - v, 0.0)]],
                fmt="o",
                color="tab:blue" if p["named"] else "tab:red",
                mfc="tab:blue" if p["named"] else "white",
                capsize=3,
            )
            if p["bar"]:
                ax.plot([p["truth"]], [p["bar"]], "_", color="grey", ms=12)
        ax.plot([0, top], [0, top], "k:", lw=1)
        if name == "loose_soil":
            ax.set_xscale("log")
            ax.set_yscale("log")
        ax.set_title(name)
        ax.set_xlabel(f"truth, {UNITS.get(name, 'value')}")
        ax.set_ylabel("fitted (bar: 95 % interval)")
    for ax in list(axes.flat)[len(names) :]:
        ax.axis("off")
    fig.suptitle(
        f"{title}: filled blue named, open red not named; grey dash: named from"
        " (a soil: named below it)"
    )
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("rows", help="independent.json of a bench_independent.py run")
    ap.add_argument("--out", required=True, help="the figure (PNG)")
    ap.add_argument("--title", default="single effects")
    args = ap.parse_args(argv)
    path = Path(args.rows)
    try:
        rows = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise SystemExit(f"{path}: cannot read the rows: {exc}") from exc
    per = points(rows)
    if not per:
        raise SystemExit(f"{path}: no finished single-effect case")
    draw(per, Path(args.out), args.title)
    print(f"wrote {args.out}: {sum(len(v) for v in per.values())} cases, {len(per)} effects")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
