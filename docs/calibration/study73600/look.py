"""Study 73600's one look: python look.py WORK (WORK/a/summary.json, WORK/b/summary.json)."""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path


def right_wrong(truth: dict[str, object], named: list[str]) -> tuple[set[str], set[str]]:
    return {n for n in named if n in truth}, {n for n in named if n not in truth}


def main(work: Path) -> None:
    parts = {
        p: json.loads((work / p / "summary.json").read_text())
        for p in ("a", "b")
        if (work / p / "summary.json").exists()
    }
    h1_ok, n_a = True, 0
    for part, s in parts.items():
        print(f"part {part}: {s['cases']} cases against {s['against']}")
        for r in s["rows"]:
            truth = r["effects"]
            pr, pw = right_wrong(truth, r["previous_named"])
            cr, cw = right_wrong(truth, r["current_named"])
            keep = pr <= cr and cw <= pw
            h1_ok &= keep
            print(
                f"  {r['case']} {'+'.join(truth) or 'clean'}: previous {r['previous_s']:.0f} s"
                f" {r['previous_named']}, current {r['current_s']:.0f} s {r['current_named']}"
                f" ratio {r['previous_s'] / r['current_s']:.2f}"
                f"{'' if keep else '  <- H1 FAILS HERE'}"
            )
            for k in sorted(
                set(r.get("previous_params") or {}) | set(r.get("current_params") or {})
            ):
                print(f"      {k}: previous {(r.get('previous_params') or {}).get(k)}")
                print(f"      {k}: current  {(r.get('current_params') or {}).get(k)}")
        if part == "a":
            n_a = s["cases"]
    a = parts.get("a")
    print(
        f"H1 (primary): {'passed' if h1_ok else 'FAILED'}"
        f"{'' if n_a >= 12 else ' (not decided: fewer than 12 cases of A)'}"
    )
    if a:
        print(
            f"H2: part A median ratio {a['median_ratio']:.2f} (>= 1.12: "
            f"{'passed' if a['median_ratio'] >= 1.12 else 'failed'})"
        )
        cur = [r["current_s"] for r in a["rows"]]
        print(
            f"H3: part A median seconds now {statistics.median(cur):.0f} (<= 60: "
            f"{'passed' if statistics.median(cur) <= 60 else 'failed'}); previous "
            f"{a['median_previous_s']:.0f}; cases <= 60 s now {sum(c <= 60 for c in cur)}"
            f" of {len(cur)}"
        )
        print(f"same names in {a['same_named']} of {a['cases']}")
    b = parts.get("b")
    if b:
        both = {
            k: sum(set(r["effects"]) <= set(r[f"{k}_named"]) for r in b["rows"])
            for k in ("previous", "current")
        }
        print(
            f"H4: part B both named: previous {both['previous']}, current {both['current']}"
            f" of {b['cases']} ({'passed' if both['current'] >= both['previous'] else 'failed'})"
        )


if __name__ == "__main__":
    main(Path(sys.argv[1]))
