"""Study 72800's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py OUT/independent.json`` (the merged rows of both shards)."""

import json
import math
import sys

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error") and r["kind"] == "pair"]
print(len(rows), "cases;", len(rows) - len(ok), "with an error or not a pair")
named, both, others, held, soil2, above, follow = [], [], [], [], [], [], 0
for r in ok:
    truth = r["truth"]
    hits = [e in r["named"] for e in truth]
    named += hits
    both.append(all(hits))
    also = [n for n in r["named"] if n not in truth]
    others.append(bool(also))
    follow += bool(r.get("followup"))
    parts = []
    for e, hit in zip(truth, hits, strict=True):
        f = r["fits"].get(e) or {}
        t, bar = f.get("truth"), f.get("nameable")
        if bar and t is not None and e != "loose_soil":  # soil: its own parameter
            above.append(abs(t) >= 2 * abs(bar))
        if hit and t is not None:
            lo = f["lo"] if f.get("lo") is not None else -math.inf
            hi = f["hi"] if f.get("hi") is not None else math.inf
            held.append(lo <= t <= hi)
            if e == "loose_soil" and f.get("value"):
                soil2.append(0.5 <= f["value"] / t <= 2.0)
        parts.append(
            f"{e} truth {t:.4g} named-from {bar} fitted {f.get('value')} [{f.get('lo')},"
            f" {f.get('hi')}] {'NAMED' if hit else 'not named'}"
        )
    print(
        f"   {r['case']}: named {r['named']}"
        + (f" (also {also})" if also else "")
        + f"; {r['diagnose_s']:.0f} s; "
        + "; ".join(parts)
    )


def verdict(k: int, n: int, share: float, at_most: bool = False) -> str:
    if len(ok) < 10:
        return "not decided (fewer than 10 cases)"
    good = k <= math.floor(share * n) if at_most else k >= math.ceil(share * n)
    return "passed" if good else "failed"


n_e, k_e = len(named), sum(named)
print(f"H1 (primary, >= 90 %): pair effects named {k_e}/{n_e}: {verdict(k_e, n_e, 0.9)}")
print(
    f"H2 (<= 10 %): cases with an effect outside the pair named {sum(others)}/{len(ok)}:"
    f" {verdict(sum(others), len(ok), 0.1, at_most=True)}"
)
print(
    f"H3 (>= 90 %): named true effects' intervals holding the truth {sum(held)}/{len(held)}:"
    f" {verdict(sum(held), len(held), 0.9)}"
)
print(
    f"reported: both named {sum(both)}/{len(both)}; truth >= 2 x named-from {sum(above)}/"
    f"{len(above)}; loose soil within 2 x {sum(soil2)}/{len(soil2)}; a follow-up drive in"
    f" {follow}/{len(ok)}"
)
