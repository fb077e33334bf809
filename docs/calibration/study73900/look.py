"""Study 73900's one look (from study 71600's; its hypotheses renumbered): ``python docs/calibration/study73900/look.py ROWS.json``."""

from __future__ import annotations

import json
import statistics
import sys


def named_right(arm: dict, effect: str, truth: dict) -> bool:
    if effect not in arm["named"]:
        return False
    params = arm["final"].get(effect, {}).get(effect, {})
    # Mended after the look crashed here (the registered script compared a slope's heading,
    # which has no interval: null bounds): a parameter without an interval is not judged.
    return all(
        p in params and (None in params[p][1:] or params[p][1] <= v <= params[p][2])
        for p, v in truth.items()
    )


def fit_alone(arm: dict) -> float:
    """The torque limit's single fit (its value; NaN when it was not fitted)."""
    tl = (arm["fits"].get("torque_limit") or {}).get("torque_limit") or {}
    return float(tl.get("fraction", [float("nan")])[0])


def main(path: str) -> None:
    rows = json.loads(open(path).read())
    torque = [r for r in rows if r["effect"] == "torque_limit"]
    others = [r for r in rows if r["effect"] != "torque_limit"]
    arms = ("off", "on")
    print(f"cases: {len(rows)} ({len(torque)} torque cuts, {len(others)} others)")
    for r in rows:
        print(
            f"  {r['seed']} {r['effect']} {r['params']} truth {r['truth']}: off {r['off']['named']}"
            f" ({r['off']['seconds']:.0f} s, torque fit {fit_alone(r['off']):+.3f}), on"
            f" {r['on']['named']} ({r['on']['seconds']:.0f} s, torque fit {fit_alone(r['on']):+.3f})"
        )
    near = {
        a: sum(abs(fit_alone(r[a]) - r["truth"]["fraction"]) <= 0.15 for r in torque) for a in arms
    }
    h1 = near["on"] - near["off"] >= 2
    print(
        f"H1 torque fits alone within 0.15 of the truth: off {near['off']}/{len(torque)},"
        f" on {near['on']}/{len(torque)}: {'passed' if h1 else 'failed'}"
    )
    right = {a: sum(named_right(r[a], r["effect"], r["truth"]) for r in torque) for a in arms}
    h2 = right["on"] - right["off"] >= 1
    print(
        f"H2 torque cuts named right: off {right['off']}/{len(torque)}, on {right['on']}/{len(torque)}:"
        f" {'passed' if h2 else 'failed'}"
    )
    wrong = sum(
        bool({n for n in r["on"]["named"] if n != r["effect"]} - set(r["off"]["named"]))
        for r in rows
    )
    print(f"H3 wrong names by on, not by off: {wrong}: {'passed' if wrong <= 1 else 'failed'}")
    oright = {a: sum(named_right(r[a], r["effect"], r["truth"]) for r in others) for a in arms}
    h4 = oright["on"] >= oright["off"] - 1
    print(
        f"H4 others named right: off {oright['off']}/{len(others)}, on {oright['on']}/{len(others)}:"
        f" {'passed' if h4 else 'failed'}"
    )
    ratio = (
        statistics.median(r["on"]["seconds"] / r["off"]["seconds"] for r in rows)
        if rows
        else float("nan")
    )
    med = {
        a: statistics.median(r[a]["seconds"] for r in rows) if rows else float("nan") for a in arms
    }
    print(
        f"H5 seconds: median off {med['off']:.0f} s, on {med['on']:.0f} s, median ratio on/off {ratio:.2f}"
    )


if __name__ == "__main__":
    main(sys.argv[1])
