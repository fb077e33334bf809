"""Study 73300's registered hypotheses (one look, after the stop).

Usage: ``python look.py WORK/summary.json WORK`` (``benchmarks/diagnose_speed.py``'s summary
and its work folder: each case's ``prev/`` and ``cur/`` diagnoses)."""

import json
import statistics
import sys
from pathlib import Path

TIMING = {"seconds", "replay_seconds", "replays", "stage_seconds", "model_form_weak_beside"}


def findings(out: Path) -> object:
    def strip(x: object) -> object:
        if isinstance(x, dict):
            return {k: strip(v) for k, v in x.items() if k not in TIMING}
        if isinstance(x, list):
            return [strip(v) for v in x]
        return x.replace(str(out), "OUT") if isinstance(x, str) else x

    return strip(json.loads((out / "result.json").read_text()))


summary = json.load(open(sys.argv[1]))
work = Path(sys.argv[2])
rows = summary["rows"]
print(len(rows), "cases")
lost, other_diff, acted, faster, ratios = 0, 0, 0, 0, []
for r in rows:
    d = work / f"case_{r['case']}"
    prev = json.loads((d / "prev" / "result.json").read_text())
    cur = json.loads((d / "cur" / "result.json").read_text())
    truth = set(r["effects"])
    p_hit = truth <= set(prev["named"])
    c_hit = truth <= set(cur["named"])
    lost += p_hit and not c_hit
    weak = cur.get("model_form_weak_beside")
    p_passes = len(prev.get("stage_seconds") or [])
    c_passes = len(cur.get("stage_seconds") or [])
    same = findings(d / "prev") == findings(d / "cur")
    if weak is None:
        other_diff += not same
    act = weak is not None and p_passes > 1
    acted += act
    faster += act and r["current_s"] < r["previous_s"]
    ratios.append(r["previous_s"] / r["current_s"])
    print(
        f"   {r['case']} {'+'.join(truth)}: previous {prev['named']} {r['previous_s']:.0f} s"
        f" {p_passes} pass(es); current {cur['named']} {r['current_s']:.0f} s {c_passes}"
        f" pass(es); weak adoption {weak}; same result.json {same}"
    )
enough = len(rows) >= 5
print(
    f"H1 (primary): the truth named by previous, not by current, in {lost}:"
    f" {('passed' if lost == 0 else 'failed') if enough else 'not decided'}"
)
print(
    f"H2: no weak adoption recorded, result.json differs in {other_diff}:"
    f" {('passed' if other_diff == 0 else 'failed') if enough else 'not decided'}"
)
print(
    f"H3: the rule acted in {acted}, faster in {faster}:"
    f" {('passed' if faster == acted else 'failed') if enough and acted else 'not decided'}"
)
print(
    f"reported: median ratio previous/current {statistics.median(ratios):.2f};"
    f" median seconds previous {statistics.median(r['previous_s'] for r in rows):.0f},"
    f" current {statistics.median(r['current_s'] for r in rows):.0f}"
)
