"""Study 71600's one look: ``python docs/calibration/study71600/look.py ROWS.json``."""

from __future__ import annotations

import json
import statistics
import sys


def named_right(arm: dict, effect: str, truth: dict) -> bool:
    if effect not in arm["named"]:
        return False
    params = arm["final"].get(effect, {}).get(effect, {})
    return all(p in params and params[p][1] <= v <= params[p][2] for p, v in truth.items())


def main(path: str) -> None:
    rows = json.loads(open(path).read())
    torque = [r for r in rows if r["effect"] == "torque_limit"]
    others = [r for r in rows if r["effect"] != "torque_limit"]
    right = {
        a: sum(named_right(r[a], r["effect"], r["truth"]) for r in torque) for a in ("off", "on")
    }
    print(f"cases: {len(rows)} ({len(torque)} torque cuts, {len(others)} others)")
    for r in rows:
        print(
            f"  {r['seed']} {r['effect']} {r['params']} truth {r['truth']}: off {r['off']['named']}"
            f" ({r['off']['seconds']:.0f} s), on {r['on']['named']} ({r['on']['seconds']:.0f} s,"
            f" forms beside {r['on']['forms_beside']})"
        )
    h1 = right["on"] - right["off"] >= 1
    print(
        f"H1 torque cuts named right: off {right['off']}/{len(torque)}, on {right['on']}/{len(torque)}:"
        f" {'passed' if h1 else 'failed'}"
    )
    same = sum(sorted(r["off"]["named"]) == sorted(r["on"]["named"]) for r in others)
    print(
        f"H2 others, the same names: {same}/{len(others)}: {'passed' if same >= len(others) - 1 else 'failed'}"
    )
    wrong = sum(
        bool({n for n in r["on"]["named"] if n != r["effect"]} - set(r["off"]["named"]))
        for r in rows
    )
    print(f"H3 wrong names by on, not by off: {wrong}: {'passed' if wrong <= 1 else 'failed'}")
    ratio = (
        statistics.median(r["on"]["seconds"] / r["off"]["seconds"] for r in rows)
        if rows
        else float("nan")
    )
    med = {
        a: statistics.median(r[a]["seconds"] for r in rows) if rows else float("nan")
        for a in ("off", "on")
    }
    print(
        f"H4 seconds: median off {med['off']:.0f} s, on {med['on']:.0f} s, median ratio on/off {ratio:.2f}"
    )


if __name__ == "__main__":
    main(sys.argv[1])
