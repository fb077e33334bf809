"""Study 73200's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py OUT/independent.json [WORK]`` (the merged rows of both shards; with
the shards' ``--work`` folder, each diagnosis whose dead reckoning asked the leading unnamed
fit is reported too: stop 105's ``slip_beside_lead``)."""

import json
import math
import sys
from pathlib import Path

rows = json.load(open(sys.argv[1]))
work = Path(sys.argv[2]) if len(sys.argv) > 2 else None
ok = [r for r in rows if not r.get("error") and r["kind"] in ("pair", "single")]
pairs = [r for r in ok if r["kind"] == "pair"]
singles = [r for r in ok if r["kind"] == "single"]
print(
    len(rows),
    "cases;",
    len(rows) - len(ok),
    "with an error; pairs",
    len(pairs),
    "singles",
    len(singles),
)
named, both, held, others, single_hit, follow = [], [], [], [], [], 0
for r in ok:
    truth = r["truth"]
    hits = [e in r["named"] for e in truth]
    also = [n for n in r["named"] if n not in truth]
    if r["kind"] == "pair":
        named += hits
        both.append(all(hits))
    else:
        others.append(bool(also))
        single_hit.append(all(hits))
    follow += bool(r.get("followup"))
    parts = []
    for e, hit in zip(truth, hits, strict=True):
        f = r["fits"].get(e) or {}
        t, bar = f.get("truth"), f.get("nameable")
        if hit and t is not None:
            lo = f["lo"] if f.get("lo") is not None else -math.inf
            hi = f["hi"] if f.get("hi") is not None else math.inf
            held.append(lo <= t <= hi)
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


def verdict(k: int, n: int, share: float, enough: bool, at_most: bool = False) -> str:
    if not enough:
        return "not decided (too few cases)"
    good = k <= math.floor(share * n) if at_most else k >= math.ceil(share * n)
    return "passed" if good else "failed"


n_e, k_e = len(named), sum(named)
print(
    f"H1 (primary, >= 90 %): pair effects named {k_e}/{n_e}:"
    f" {verdict(k_e, n_e, 0.9, len(pairs) >= 6)}"
)
print(
    f"H2 (<= 10 %): singles with another effect named {sum(others)}/{len(singles)}:"
    f" {verdict(sum(others), len(singles), 0.1, len(singles) >= 2, at_most=True)}"
)
print(
    f"H3 (>= 90 %): named true effects' intervals holding the truth {sum(held)}/{len(held)}:"
    f" {verdict(sum(held), len(held), 0.9, len(ok) >= 6)}"
)
print(
    f"reported: both named {sum(both)}/{len(both)} pairs; singles' effect named"
    f" {sum(single_hit)}/{len(single_hit)}; a follow-up drive in {follow}/{len(ok)}"
)

if work is not None:  # reported, not judged: where stop 105's rule acted
    asked = read = 0
    for r in ok:
        truth = r["truth"]
        for res in sorted((work / r["case"]).glob("*/result.json")):
            dr = json.load(open(res)).get("dead_reckoning") or {}
            lead = dr.get("slip_lead")
            if not lead:
                continue
            asked += 1
            read += bool(lead["read_beside"])
            t = (truth.get("rolling_radius") or {}).get("fraction")
            print(
                f"   {r['case']} {res.parent.name}: beside unnamed {lead['effect']}"
                f" ({lead['fit']}): {'read beside it' if lead['read_beside'] else lead['why_not']};"
                f" radius named {dr.get('named')} {dr.get('fraction')}; truth {t}"
            )
    print(f"reported: diagnoses asking the lead {asked}, reading the radius beside it {read}")
