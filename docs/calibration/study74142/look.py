"""Study 74142's one look: ``python docs/calibration/study74142/look.py ROWS.json``.

The rows are ``benchmarks/option_ab.py``'s, run with ``--option no-height-beside-soil``: arm
``off`` is the new code (the joint height judged against the soil), arm ``on`` the previous
behaviour."""

from __future__ import annotations

import json
import statistics
import sys

ARMS = {"new": "off", "previous": "on"}


def alone(arm: dict, effect: str) -> bool:
    return list(arm["named"]) == [effect]


def k_fit(arm: dict) -> float:
    """The named soil's k_phi (NaN when none is named)."""
    soil = (arm.get("final") or {}).get("loose_soil") or {}
    return float((soil.get("loose_soil") or {}).get("k_phi", [float("nan")])[0])


def within2(arm: dict, truth: float) -> bool:
    return alone(arm, "loose_soil") and 0.5 <= k_fit(arm) / truth <= 2.0


def median_ratio(rows: list[dict]) -> float:
    if not rows:
        return float("nan")
    return statistics.median(r["off"]["seconds"] / r["on"]["seconds"] for r in rows)


def verdict(ok: bool) -> str:
    return "passed" if ok else "failed"


def main(path: str) -> None:
    rows = json.loads(open(path).read())
    soils = [r for r in rows if r["effect"] == "loose_soil"]
    others = [r for r in rows if r["effect"] not in ("loose_soil", "clean")]
    clean = [r for r in rows if r["effect"] == "clean"]
    print(f"cases: {len(rows)} ({len(soils)} soils, {len(others)} others, {len(clean)} clean)")
    for r in rows:
        t = r["truth"].get("k_phi") if r["truth"] else None
        parts = []
        for name, key in ARMS.items():
            a = r[key]
            k = k_fit(a)
            ratio = f", k_phi {k:.3g} (x {k / t:.2f})" if t and k == k else ""
            parts.append(f"{name} {a['named']}{ratio} ({a['seconds']:.0f} s)")
        print(f"  {r['seed']} {r['effect']} {r['params']} truth {r['truth']}: " + "; ".join(parts))
    right = {n: {r["seed"] for r in soils if alone(r[k], "loose_soil")} for n, k in ARMS.items()}
    lost = right["previous"] - right["new"]
    print(
        f"H1 soils named alone by the previous code, not by the new: {sorted(lost)}: "
        + verdict(not lost)
    )
    gain = len(right["new"]) - len(right["previous"])
    print(
        f"H2 soils named alone: new {len(right['new'])}/{len(soils)}, previous"
        f" {len(right['previous'])}/{len(soils)} (gained {sorted(right['new'] - right['previous'])}): "
        + verdict(gain >= 1)
    )
    w = {n: sum(within2(r[k], r["truth"]["k_phi"]) for r in soils) for n, k in ARMS.items()}
    print(
        f"H3 within 2 x: new {w['new']}/{len(soils)}, previous {w['previous']}/{len(soils)}: "
        + verdict(w["new"] >= w["previous"] + 1)
    )
    named = {n: sum(bool(r[k]["named"]) for r in clean) for n, k in ARMS.items()}
    print(
        f"H4 clean builds with a name: new {named['new']}/{len(clean)}, previous"
        f" {named['previous']}/{len(clean)}: "
        + verdict(named["new"] <= named["previous"] and named["new"] <= 1)
    )
    o_right = {n: {r["seed"] for r in others if alone(r[k], r["effect"])} for n, k in ARMS.items()}
    o_lost = o_right["previous"] - o_right["new"]
    print(
        f"H5 slopes and rolling resistances named alone: new {len(o_right['new'])}/{len(others)},"
        f" previous {len(o_right['previous'])}/{len(others)}; lost {sorted(o_lost)}: "
        + verdict(not o_lost)
    )
    wrong = [
        r["seed"]
        for r in soils + others
        if set(r["off"]["named"]) - {r["effect"]} - set(r["on"]["named"])
    ]
    print(f"H6 another effect named by the new code only: {wrong}: " + verdict(len(wrong) <= 1))
    same = [r["seed"] for r in clean if r["off"]["fits"] == r["on"]["fits"]]
    print(f"clean builds whose fits agree to the bit in both arms: {len(same)}/{len(clean)}")
    print(
        f"H7 (reported) seconds, median ratio new/previous: soils {median_ratio(soils):.2f},"
        f" others {median_ratio(others):.2f}, clean {median_ratio(clean):.2f}"
    )


if __name__ == "__main__":
    main(sys.argv[1])
