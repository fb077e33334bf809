"""Block 53100's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py independent.json`` (the rows of plan 53100: ``bench_independent.py
--strong-pairs 0 --strong-singles 30 --strong-from loose_soil --seed0 53100 --workers 2``)."""

import json
import math
import statistics
import sys

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error")]
print(len(rows), "cases;", len(rows) - len(ok), "with an error")
soils = [r for r in ok if r["kind"] == "single" and next(iter(r["truth"])) == "loose_soil"]


def fit(r):
    return r["fits"].get("loose_soil") or {}


def within(v, t):
    return bool(v and t) and 0.5 <= v / t <= 2.0


def ratio(r):
    v, t = fit(r).get("value"), fit(r).get("truth")
    return v / t if v and t else float("nan")


right = [
    r
    for r in soils
    if r["named"] == ["loose_soil"] and within(fit(r).get("value"), fit(r).get("truth"))
]
n, k = len(soils), len(right)
verdict = (
    "not decided (fewer than 10)" if n < 10 else ("passed" if k >= math.ceil(0.9 * n) else "failed")
)
print(
    f"H1 (primary, >= 90 %): soil singles named loose_soil alone, k_phi within 2 x: {k}/{n}: {verdict}"
)

# H2: the joints' straight reading against the pose's, paired, on the named soils whose
# straight read ran (both readings recorded); a group without a reading leaves the fit over
# every signal, as the shipped rule does.
named = [r for r in soils if "loose_soil" in r["named"]]
paired = [r for r in named if fit(r).get("reads")]


def rule_value(r, group):
    f = fit(r)
    got = (f.get("reads") or {}).get(group)
    if got is not None:
        return got
    return f["replaced"] if f.get("replaced") is not None else f.get("value")


jw = [within(rule_value(r, "joints"), fit(r)["truth"]) for r in paired]
pw = [within(rule_value(r, "pose"), fit(r)["truth"]) for r in paired]
j_only = sum(a and not b for a, b in zip(jw, pw, strict=True))
p_only = sum(b and not a for a, b in zip(jw, pw, strict=True))
v2 = (
    "not decided (fewer than 10 paired)"
    if len(paired) < 10
    else ("passed" if sum(jw) >= sum(pw) else "failed")
)
print(
    f"H2 (joints >= pose): named soils within 2 x by the joints' straight reading {sum(jw)}/{len(paired)},"
    f" by the pose's {sum(pw)}/{len(paired)} (joints only {j_only}, pose only {p_only}): {v2}"
)
cov = []
for r in named:
    f = fit(r)
    lo = f["lo"] if f["lo"] is not None else -math.inf
    hi = f["hi"] if f["hi"] is not None else math.inf
    cov.append(lo <= f["truth"] <= hi)
m, c = len(cov), sum(cov)
v3 = "not decided (none named)" if m == 0 else ("passed" if c >= math.ceil(0.85 * m) else "failed")
print(f"H3 (>= 85 %): named soils whose 95 % interval holds the true k_phi: {c}/{m}: {v3}")
print(f"reported: soil singles named loose_soil at all: {len(named)}/{n}")
other = [r for r in soils if set(r["named"]) - {"loose_soil"}]
print(f"reported: soil singles with another effect named: {len(other)}/{n}")
for r in other:
    print("   other:", r["case"], r["named"])
fw = [within(fit(r).get("replaced") or fit(r).get("value"), fit(r)["truth"]) for r in paired]
print(
    f"reported: named soils within 2 x by the fit over every signal (before any read): {sum(fw)}/{len(paired)}"
)
for sand in (0.0, 1.0):
    part = [r for r in soils if r["effects"]["loose_soil"].get("sand") == sand]
    hit = sum(r in right for r in part)
    print(
        f"reported: {'dry sand' if sand else 'regolith'} preset: {hit}/{len(part)} named with k_phi within 2 x"
    )
acted = [r for r in soils if any(p for p in (r.get("passed_over") or []))]
print(f"reported: soil singles where a fit at its range's end was passed over: {len(acted)}/{n}")
ds = [r["diagnose_s"] for r in ok if r.get("diagnose_s")]
if ds:
    allin = [r["make_logs_s"] + r["diagnose_s"] + r["followup_s"] for r in ok]
    print(
        f"reported: diagnose seconds (first diagnosis) median {statistics.median(ds):.1f};"
        f" whole case median {statistics.median(allin):.1f}"
    )
print(
    "reported, every soil single (truth k_phi, preset, named, fitted / truth, fit, read, each reading / truth):"
)
for r in soils:
    f = fit(r)
    t = f.get("truth")
    fol = ",".join(p["plan"] for p in r.get("followup") or [])
    reads = f.get("reads") or {}
    parts = [f"{g} {v / t:.2f}" if v else f"{g} none" for g, v in reads.items()]
    if f.get("replaced"):
        parts.append(f"every signal {f['replaced'] / t:.2f}")
    print(
        f"   {r['case']}: truth {t:.4g}, {'sand' if r['effects']['loose_soil'].get('sand') else 'regolith'},"
        f" named {r['named']}, x {ratio(r):.2f}, fit {f.get('value')} [{f.get('lo')}, {f.get('hi')}],"
        f" read {f.get('read_from')} ({', '.join(parts)})" + (f", follow-up {fol}" if fol else "")
    )
