"""Block 52300's registered hypotheses from its rows (one look, after the stop)."""

import json
import statistics
import sys

rows = json.load(open(sys.argv[1]))
print(len(rows), "cases")
names = right = 0
other = []
for r in rows:
    truth = r["truth"] if isinstance(r["truth"], dict) else {}
    eq = r.get("equivalent") or {}
    for n in r["named"]:
        names += 1
        if n in truth:
            right += 1
        else:
            other.append((r["case"], n, list(truth), list(eq)))
print(
    f"H1: final names that are the truth {right}/{names}"
    + (f" ({right / names:.1%})" if names else "")
)
for o in other:
    print("   other name:", o)
clean = [r for r in rows if r["kind"] == "clean"]
nothing = sum(not r["named"] for r in clean)
gap = sum(bool(r["unexplained"]) for r in clean)
print(f"H2: clean nothing named {nothing}/{len(clean)}, gap {gap}/{len(clean)}")
rr = [
    r
    for r in rows
    if r["kind"] == "single"
    and "rolling_resistance" in (r["truth"] if isinstance(r["truth"], dict) else {})
]
for r in rr:
    c = r["truth"]["rolling_resistance"]["c_rr"]
    f = r["fits"].get("rolling_resistance") or {}
    print(
        f"   RR {r['case']}: c_rr {c:.4g} named {r['named']} fit {f.get('value')} [{f.get('lo')}, {f.get('hi')}] test {f.get('test')}"
    )
low = [r for r in rr if r["truth"]["rolling_resistance"]["c_rr"] < 0.0316]
print(
    f"H3: RR singles under 0.0316 named RR: {sum('rolling_resistance' in r['named'] for r in low)}/{len(low)};"
    f" at >= 0.05 named: {sum('rolling_resistance' in r['named'] for r in rr if r['truth']['rolling_resistance']['c_rr'] >= 0.05)}/"
    f"{sum(r['truth']['rolling_resistance']['c_rr'] >= 0.05 for r in rr)}"
)
ds = [r["diagnose_s"] for r in rows if r.get("diagnose_s")]
print(
    f"H4: diagnose seconds median {statistics.median(ds):.1f} over {len(ds)} (min {min(ds):.0f}, max {max(ds):.0f});"
    f" case seconds median {statistics.median([r['make_logs_s'] + r['diagnose_s'] + (r.get('followup_s') or 0) for r in rows]):.0f}"
)
