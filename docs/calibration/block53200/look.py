"""Block 53200's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py independent.json`` (the rows of plan 53200: ``bench_independent.py
--strong-pairs 0 --strong-singles 30 --strong-from slope,rolling_resistance,loose_soil
--seed0 53200 --workers 2``)."""

import json
import math
import statistics
import sys

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error")]
print(len(rows), "cases;", len(rows) - len(ok), "with an error")
KINDS = ("slope", "rolling_resistance", "loose_soil")
WORLD, DRAG = {"slope"}, {"rolling_resistance", "loose_soil"}
singles = [r for r in ok if r["kind"] == "single" and next(iter(r["truth"])) in KINDS]


def truth(r):
    return next(iter(r["truth"]))


def verdict(k, n, share, least=10):
    if n < least:
        return f"not decided (fewer than {least})"
    return "passed" if k >= math.ceil(share * n) else "failed"


def cross(r, names):
    """A slope named on a drag single, or a drag named on a slope single."""
    t = truth(r)
    return bool(set(names) & (DRAG if t in WORLD else WORLD))


right = [r for r in singles if r["named"] == [truth(r)]]
n = len(singles)
print(
    f"H1 (primary, >= 90 %): singles named their true effect alone: {len(right)}/{n}: {verdict(len(right), n, 0.9)}"
)
crossed = [r for r in singles if cross(r, r["named"])]
v2 = (
    "not decided (fewer than 10)"
    if n < 10
    else ("passed" if len(crossed) <= math.floor(0.05 * n) else "failed")
)
print(
    f"H2 (<= 5 %): singles named an effect of the other kind (a slope for a drag, a drag for a slope): {len(crossed)}/{n}: {v2}"
)
for r in crossed:
    print("   crossed:", r["case"], r["named"])
cov = []
for r in singles:
    t = truth(r)
    if t not in r["named"]:
        continue
    f = r["fits"].get(t) or {}
    lo = f["lo"] if f.get("lo") is not None else -math.inf
    hi = f["hi"] if f.get("hi") is not None else math.inf
    cov.append(lo <= f["truth"] <= hi)
m, c = len(cov), sum(cov)
print(
    f"H3 (>= 90 %): named true effects whose 95 % interval holds the truth: {c}/{m}: {verdict(c, m, 0.9, 1)}"
)
for k in KINDS:
    part = [r for r in singles if truth(r) == k]
    print(f"reported: {k} singles named it alone {sum(r in right for r in part)}/{len(part)}")
first_crossed = [r for r in singles if cross(r, r["first_named"])]
print(
    f"reported: first diagnosis (before any follow-up drive) named the other kind: {len(first_crossed)}/{n}"
)
rule = [r for r in singles if r.get("tie_unseparated")]
print(
    f"reported: ties declared because the held-out drive never reversed (reversal_tie): {len(rule)}/{n}"
)
for r in rule:
    print(f"   {r['case']}: tie {r['tie']}, first named {r['first_named']}, final {r['named']}")
other = [r for r in singles if set(r["named"]) - {truth(r)}]
print(f"reported: singles with another effect named: {len(other)}/{n}")
soils = [r for r in singles if truth(r) == "loose_soil" and "loose_soil" in r["named"]]
w2 = [
    r
    for r in soils
    if 0.5 <= r["fits"]["loose_soil"]["value"] / r["fits"]["loose_soil"]["truth"] <= 2.0
]
print(f"reported: named soils with k_phi within 2 x: {len(w2)}/{len(soils)}")
ds = [r["diagnose_s"] for r in ok if r.get("diagnose_s")]
if ds:
    allin = [r["make_logs_s"] + r["diagnose_s"] + r["followup_s"] for r in ok]
    print(
        f"reported: diagnose seconds (first diagnosis) median {statistics.median(ds):.1f};"
        f" whole case median {statistics.median(allin):.1f}"
    )
print("reported, every single (truth, first named, final named, tie, fit [interval], follow-up):")
for r in singles:
    t = truth(r)
    f = r["fits"].get(t) or {}
    fol = ",".join(p["plan"] for p in r.get("followup") or [])
    print(
        f"   {r['case']}: truth {r['truth'][t]}, first {r['first_named']}, final {r['named']},"
        f" tie {r.get('tie')}{' (unseparated)' if r.get('tie_unseparated') else ''},"
        f" fit {f.get('value')} [{f.get('lo')}, {f.get('hi')}]"
        + (f", follow-up {fol}" if fol else "")
    )
