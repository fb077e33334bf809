"""Block 52400's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py MATRIX_ROWS.json [CLEAN_ROWS.json ...]`` (each an ``independent.json``
of ``bench_independent.py``): the full matrix of plan 52400 and the clean cases of plans
66600 on."""

import json
import statistics
import sys

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
rows = [r for r in rows if not r.get("error")] + [r for r in rows if r.get("error")]
print(len(rows), "cases;", sum(bool(r.get("error")) for r in rows), "with an error")


def truth(r):
    return r["truth"] if isinstance(r["truth"], dict) else {}


def nxt(r, i=-1):
    w = (r.get("allowance_withdrawn") or [None])[i] or {}
    return w.get("next")


names = right = 0
for r in rows:
    for n in r["named"]:
        names += 1
        right += n in truth(r)
        if n not in truth(r):
            print("   other name:", r["case"], n, list(truth(r)), "next" if n == nxt(r) else "")
print(
    f"H1 (primary, >= 85 %): final names that are the truth {right}/{names}"
    + (f" ({right / names:.1%})" if names else "")
)
clean = [r for r in rows if r["kind"] == "clean"]
named = sum(bool(r["named"]) for r in clean)
gap = sum(bool(r["unexplained"]) for r in clean)
allowed = max(1, len(clean) // 20)  # at most 5 %, and at least one
print(
    f"H2 (nothing named and a gap in at most {allowed} each): clean {len(clean)}:"
    f" something named {named}, a gap {gap}"
)
for r in clean:
    if r["named"] or r["unexplained"]:
        print("   clean:", r["case"], r["named"], r["unexplained"])
made = [(r, nxt(r)) for r in rows if nxt(r) and nxt(r) in r["named"]]
wrong = [(r["case"], n) for r, n in made if n not in truth(r)]
print(f"H3 (at most 1 wrong): names made by the new rule {len(made)}, not the truth {len(wrong)}")
for r, n in made:
    f = r["fits"].get(n) or {}
    print(
        f"   next: {r['case']} named {n} truth {truth(r)} fit {f.get('value')}"
        f" [{f.get('lo')}, {f.get('hi')}]"
    )
first = [(r["case"], nxt(r, 0)) for r in rows if nxt(r, 0)]
print("reported: next names in the first diagnosis:", first)
withdrawn = sum(bool((r.get("allowance_withdrawn") or [None])[-1]) for r in rows)
print(f"reported: cases with a withdrawal in the final diagnosis {withdrawn}/{len(rows)}")
ds = [r["diagnose_s"] for r in rows if r.get("diagnose_s")]
if ds:
    print(
        f"reported: diagnose seconds median {statistics.median(ds):.1f} over {len(ds)}"
        f" (min {min(ds):.0f}, max {max(ds):.0f}; one worker, two streams side by side)"
    )
