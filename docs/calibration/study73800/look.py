"""Study 73800's one look: python look.py WORK (WORK/a/summary.json)."""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path


def main(work: Path) -> None:
    s = json.loads((work / "a" / "summary.json").read_text())
    print(f"part a: {s['cases']} cases against {s['against']}")
    same = 0
    for r in s["rows"]:
        truth = r["effects"]
        same += bool(r["same_result"])
        print(
            f"  {r['case']} {'+'.join(truth) or 'clean'}: previous {r['previous_s']:.0f} s"
            f" {r['previous_named']}, current {r['current_s']:.0f} s {r['current_named']}"
            f" ratio {r['previous_s'] / r['current_s']:.2f}, result.json"
            f" {'the same' if r['same_result'] else 'DIFFERS  <- H1 FAILS HERE'}"
        )
        for k in sorted(set(r.get("current_params") or {})):
            print(f"      {k}: {(r.get('current_params') or {}).get(k)}")
    n = s["cases"]
    print(
        f"H1 (primary): result.json the same in {same} of {n}:"
        f" {'passed' if same == n else 'FAILED'}"
        f"{'' if n >= 18 else ' (not decided: fewer than 18 cases)'}"
    )
    print(
        f"H2: median ratio {s['median_ratio']:.2f} (>= 1.03: "
        f"{'passed' if s['median_ratio'] >= 1.03 else 'failed'})"
    )
    cur = [r["current_s"] for r in s["rows"]]
    print(
        f"H3: median seconds now {statistics.median(cur):.0f} (<= 60: "
        f"{'passed' if statistics.median(cur) <= 60 else 'failed'}); previous "
        f"{s['median_previous_s']:.0f}; cases <= 60 s now {sum(c <= 60 for c in cur)}"
        f" of {len(cur)}, before {sum(r['previous_s'] <= 60 for r in s['rows'])}"
    )
    print(f"same names in {s['same_named']} of {n}")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
