"""Block 52500's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py independent.json`` (the merged rows of both shards of plan 52500,
``bench_independent.py --merge``)."""

import json
import math
import statistics
import sys

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error")]
print(len(rows), "cases;", len(rows) - len(ok), "with an error")


def size(name, truth):
    """The truth's magnitude in the units diagnose reports its bar in (a soil: 1e6 / k_phi)."""
    return 1e6 / truth if name == "loose_soil" else abs(truth)


above, covering = [], []
for r in ok:
    if r["kind"] != "single":
        continue
    ((name, _),) = r["truth"].items()
    f = r["fits"].get(name) or {}
    bar = f.get("nameable")
    if not bar or f.get("truth") is None:
        print("   no bar:", r["case"])
        continue
    ratio = size(name, f["truth"]) / bar
    if ratio < 2:
        continue
    hit = name in r["named"]
    above.append(hit)
    if hit:
        lo = f["lo"] if f["lo"] is not None else -math.inf  # as bench_diagnose.covers
        hi = f["hi"] if f["hi"] is not None else math.inf
        covering.append(lo <= f["truth"] <= hi)
    print(
        f"   {r['case']}: truth {f['truth']:.4g}, named from {bar:.4g} (x {ratio:.2f}),"
        f" named {r['named']}, fitted {f.get('value')} [{f.get('lo')}, {f.get('hi')}]"
    )
n, k = len(above), sum(above)
verdict = (
    "not decided (fewer than 5)" if n < 5 else ("passed" if k >= math.ceil(0.9 * n) else "failed")
)
print(f"H1 (primary, >= 90 %): singles at >= 2 x named-from named right {k}/{n}: {verdict}")
m, c = len(covering), sum(covering)
v2 = "not decided (none named)" if m == 0 else ("passed" if c >= math.ceil(0.9 * m) else "failed")
print(f"H2 (>= 90 %): of those named, the 95 % interval holding the truth {c}/{m}: {v2}")
clean = [r for r in ok if r["kind"] == "clean"]
named = sum(bool(r["named"]) for r in clean)
allowed = max(1, len(clean) // 20)
print(
    f"H3 (at most {allowed} with a name): clean {len(clean)}: something named {named}:"
    f" {'passed' if named <= allowed else 'failed'}"
)
for r in clean:
    if r["named"] or r["unexplained"]:
        print("   clean:", r["case"], r["named"], r["unexplained"])
ds = [r["diagnose_s"] for r in ok if r.get("diagnose_s")]
if ds:
    print(
        f"reported: diagnose seconds median {statistics.median(ds):.1f} over {len(ds)}"
        f" (min {min(ds):.0f}, max {max(ds):.0f}; two shards side by side)"
    )
