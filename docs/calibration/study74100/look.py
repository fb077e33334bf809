"""Study 74100's one look: ``python docs/calibration/study74100/look.py ROWS.json``.

The rows are ``benchmarks/option_ab.py``'s, run with ``--option no-screen-middle``: arm
``off`` is the new code (the middle rung screened), arm ``on`` the previous behaviour."""

from __future__ import annotations

import json
import statistics
import sys

ARMS = {"new": "off", "previous": "on"}


def alone(arm: dict) -> bool:
    return list(arm["named"]) == ["loose_soil"]


def k_fit(arm: dict) -> float:
    """The named soil's k_phi (NaN when none is named)."""
    soil = (arm.get("final") or {}).get("loose_soil") or {}
    return float((soil.get("loose_soil") or {}).get("k_phi", [float("nan")])[0])


def within2(arm: dict, truth: float) -> bool:
    return alone(arm) and 0.5 <= k_fit(arm) / truth <= 2.0


def median_ratio(rows: list[dict]) -> float:
    if not rows:
        return float("nan")
    return statistics.median(r["off"]["seconds"] / r["on"]["seconds"] for r in rows)


def main(path: str) -> None:
    rows = json.loads(open(path).read())
    soils = [r for r in rows if r["effect"] == "loose_soil"]
    clean = [r for r in rows if r["effect"] == "clean"]
    print(f"cases: {len(rows)} ({len(soils)} soils, {len(clean)} clean builds)")
    for r in rows:
        t = r["truth"].get("k_phi") if r["truth"] else None
        parts = []
        for name, key in ARMS.items():
            a = r[key]
            k = k_fit(a)
            ratio = f", k_phi {k:.3g} (x {k / t:.2f})" if t and k == k else ""
            parts.append(f"{name} {a['named']}{ratio} ({a['seconds']:.0f} s)")
        print(f"  {r['seed']} {r['effect']} {r['params']} truth {r['truth']}: " + "; ".join(parts))
    right = {n: {r["seed"] for r in soils if alone(r[k])} for n, k in ARMS.items()}
    lost = right["previous"] - right["new"]
    print(
        f"H1 soils named alone by the previous code, not by the new: {sorted(lost)}:"
        f" {'passed' if not lost else 'failed'}"
    )
    gain = len(right["new"]) - len(right["previous"])
    print(
        f"H2 soils named alone: new {len(right['new'])}/{len(soils)}, previous"
        f" {len(right['previous'])}/{len(soils)} (gained {sorted(right['new'] - right['previous'])}):"
        f" {'passed' if gain >= 1 else 'failed'}"
    )
    w = {n: sum(within2(r[k], r["truth"]["k_phi"]) for r in soils) for n, k in ARMS.items()}
    print(
        f"H3 within 2 x: new {w['new']}/{len(soils)}, previous {w['previous']}/{len(soils)}:"
        f" {'passed' if w['new'] >= w['previous'] - 1 else 'failed'}"
    )
    named = {n: sum(bool(r[k]["named"]) for r in clean) for n, k in ARMS.items()}
    h4 = named["new"] <= named["previous"] and named["new"] <= 1
    print(
        f"H4 clean builds with a name: new {named['new']}/{len(clean)}, previous"
        f" {named['previous']}/{len(clean)}: {'passed' if h4 else 'failed'}"
    )
    other = [
        r["seed"]
        for r in soils
        if {n for n in r["off"]["named"] if n != "loose_soil"}
        - {n for n in r["on"]["named"] if n != "loose_soil"}
    ]
    print(
        f"H5 another effect named on a soil by the new code only: {other}:"
        f" {'passed' if len(other) <= 1 else 'failed'}"
    )
    print(
        f"H6 seconds, median ratio new/previous: soils {median_ratio(soils):.2f}, clean"
        f" {median_ratio(clean):.2f}; medians new"
        f" {statistics.median(r['off']['seconds'] for r in rows) if rows else float('nan'):.0f} s,"
        f" previous {statistics.median(r['on']['seconds'] for r in rows) if rows else float('nan'):.0f} s"
    )


if __name__ == "__main__":
    main(sys.argv[1])
