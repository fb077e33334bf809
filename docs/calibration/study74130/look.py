"""Study 74130's one look: ``python docs/calibration/study74130/look.py ROWS.json``.

The rows are ``benchmarks/option_ab.py``'s, run with ``--option no-presence-on-windows``:
arm ``off`` is the new rule (the windows' interval), arm ``on`` the previous one."""

from __future__ import annotations

import json
import statistics
import sys

ARMS = {"new": "off", "previous": "on"}
EFFECT = "rolling_resistance"


def interval(arm: dict) -> list | None:
    """The named rolling resistance's [value, low, high] (None when not named)."""
    if EFFECT not in arm["named"]:
        return None
    return ((arm.get("final") or {}).get(EFFECT) or {}).get(EFFECT, {}).get("c_rr")


def right(arm: dict, truth: float) -> bool:
    v = interval(arm)
    return v is not None and None not in v[1:] and v[1] <= truth <= v[2]


def main(path: str) -> None:
    rows = json.loads(open(path).read())
    print(f"cases: {len(rows)}")
    for r in rows:
        t = r["truth"]["c_rr"]
        parts = [
            f"{n} {r[k]['named']} c_rr {interval(r[k])} ({r[k]['seconds']:.0f} s)"
            for n, k in ARMS.items()
        ]
        print(f"  {r['seed']} truth {t:.4f}: " + "; ".join(parts))
    ok = {n: {r["seed"] for r in rows if right(r[k], r["truth"]["c_rr"])} for n, k in ARMS.items()}
    lost = ok["previous"] - ok["new"]
    print(
        f"H1 named right by the previous rule, not by the new: {sorted(lost)}:"
        f" {'passed' if not lost else 'failed'}"
    )
    gain = len(ok["new"]) - len(ok["previous"])
    print(
        f"H2 named right: new {len(ok['new'])}/{len(rows)}, previous {len(ok['previous'])}/{len(rows)}"
        f" (gained {sorted(ok['new'] - ok['previous'])}): {'passed' if gain >= 1 else 'failed'}"
    )
    other = [
        r["seed"]
        for r in rows
        if {n for n in r["off"]["named"] if n != EFFECT}
        - {n for n in r["on"]["named"] if n != EFFECT}
    ]
    print(
        f"H3 another effect named by the new rule only: {other}: {'passed' if len(other) <= 1 else 'failed'}"
    )
    named = [r for r in rows if interval(r["off"]) is not None]
    hold = sum(right(r["off"], r["truth"]["c_rr"]) for r in named)
    h4 = bool(named) and hold >= 0.9 * len(named)
    print(
        f"H4 new rule's named rolling resistances holding the truth: {hold}/{len(named)}: {'passed' if h4 else 'failed'}"
    )
    ratio = (
        statistics.median(r["off"]["seconds"] / r["on"]["seconds"] for r in rows)
        if rows
        else float("nan")
    )
    print(f"H5 seconds, median ratio new/previous {ratio:.2f}")


if __name__ == "__main__":
    main(sys.argv[1])
