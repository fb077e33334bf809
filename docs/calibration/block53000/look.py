"""Block 53000's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py independent.json`` (the rows of plan 53000: ``bench_independent.py
--strong-pairs 0 --strong-singles 30 --strong-from loose_soil --seed0 53000 --workers 2``)."""

import json
import math
import statistics
import sys

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error")]
print(len(rows), "cases;", len(rows) - len(ok), "with an error")
soils = [r for r in ok if r["kind"] == "single" and next(iter(r["truth"])) == "loose_soil"]


def ratio(r):
    f = r["fits"].get("loose_soil") or {}
    v, t = f.get("value"), f.get("truth")
    return v / t if v and t else float("nan")


right = [r for r in soils if r["named"] == ["loose_soil"] and 0.5 <= ratio(r) <= 2.0]
n, k = len(soils), len(right)
verdict = (
    "not decided (fewer than 10)" if n < 10 else ("passed" if k >= math.ceil(0.9 * n) else "failed")
)
print(
    f"H1 (primary, >= 90 %): soil singles named loose_soil alone, k_phi within 2 x: {k}/{n}: {verdict}"
)
rr = [r for r in soils if "rolling_resistance" in r["named"]]
print(
    f"H2 (none): soil singles with rolling_resistance named: {len(rr)}/{n}: {'passed' if not rr else 'failed'}"
)
for r in rr:
    print("   rolling resistance named:", r["case"], r["named"])
named = [r for r in soils if "loose_soil" in r["named"]]
cov = []
for r in named:
    f = r["fits"]["loose_soil"]
    lo = f["lo"] if f["lo"] is not None else -math.inf
    hi = f["hi"] if f["hi"] is not None else math.inf
    cov.append(lo <= f["truth"] <= hi)
m, c = len(cov), sum(cov)
v3 = "not decided (none named)" if m == 0 else ("passed" if c >= math.ceil(0.85 * m) else "failed")
print(f"H3 (>= 85 %): named soils whose 95 % interval holds the true k_phi: {c}/{m}: {v3}")
acted = [r for r in soils if any(p for p in (r.get("passed_over") or []))]
print(
    f"reported: soil singles where a fit at its range's end was passed over (first or final diagnosis): {len(acted)}/{n}"
)
for r in acted:
    print(
        "   passed over:",
        r["case"],
        [p and (p["effect"], p["value"], p["named_first"]) for p in r["passed_over"]],
        "named",
        r["named"],
    )
print(f"reported: soil singles named loose_soil at all: {len(named)}/{n}")
other = [r for r in soils if set(r["named"]) - {"loose_soil"}]
print(f"reported: soil singles with another effect named: {len(other)}/{n}")
for r in other:
    print("   other:", r["case"], r["named"])
for sand in (0.0, 1.0):
    part = [r for r in soils if r["effects"]["loose_soil"].get("sand") == sand]
    hit = sum(r in right for r in part)
    print(
        f"reported: {'dry sand' if sand else 'regolith'} preset: {hit}/{len(part)} named with k_phi within 2 x"
    )
ds = [r["diagnose_s"] for r in ok if r.get("diagnose_s")]
if ds:
    allin = [r["make_logs_s"] + r["diagnose_s"] + r["followup_s"] for r in ok]
    print(
        f"reported: diagnose seconds (first diagnosis) median {statistics.median(ds):.1f};"
        f" whole case median {statistics.median(allin):.1f}"
    )
print(
    "reported, every soil single (truth k_phi, preset, named, fitted / truth, fit, read from, follow-up):"
)
for r in soils:
    f = r["fits"].get("loose_soil") or {}
    fol = ",".join(p["plan"] for p in r.get("followup") or [])
    print(
        f"   {r['case']}: truth {f.get('truth'):.4g}, {'sand' if r['effects']['loose_soil'].get('sand') else 'regolith'},"
        f" named {r['named']}, x {ratio(r):.2f}, fit {f.get('value')} [{f.get('lo')}, {f.get('hi')}],"
        f" read {(f.get('read_from') or {}).get('rule') if isinstance(f.get('read_from'), dict) else f.get('read_from')}"
        + (f", follow-up {fol}" if fol else "")
    )
