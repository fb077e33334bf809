"""Study 73400's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py independent.json`` (the merged rows of both shards,
``bench_independent.py --merge``)."""

import json
import math
import statistics
import sys
from collections import defaultdict

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error") and r["kind"] == "single"]
print(len(rows), "cases;", len(rows) - len(ok), "with an error or not a single")


def size(name, truth):
    """The truth's magnitude in the units diagnose reports its bar in (a soil: 1e6 / k_phi)."""
    return 1e6 / truth if name == "loose_soil" else abs(truth)


def covers(f):
    lo = f["lo"] if f["lo"] is not None else -math.inf  # as bench_diagnose.covers
    hi = f["hi"] if f["hi"] is not None else math.inf
    return lo <= f["truth"] <= hi


above, covering, others, all_hit = [], [], [], defaultdict(list)
soil = []
for r in ok:
    ((name, _),) = r["truth"].items()
    f = r["fits"].get(name) or {}
    bar = f.get("nameable")
    hit = name in r["named"]
    other = sorted(set(r["named"]) - {name})
    others.append(bool(other))
    all_hit[name].append(hit)
    ratio = size(name, f["truth"]) / bar if bar and f.get("truth") is not None else None
    tag = "no bar" if ratio is None else f"x {ratio:.2f}"
    print(
        f"   {r['case']} {name}: truth {f.get('truth')}, named from {bar} ({tag}),"
        f" named {r['named']} (first pass {r.get('first_named')}), fitted {f.get('value')}"
        f" [{f.get('lo')}, {f.get('hi')}]{'' if not hit else ', holds the truth' if covers(f) else ', MISSES the truth'}"
        f", followup {bool(r.get('followup'))}, diagnose {r.get('diagnose_s') or 0:.0f} s"
    )
    if hit:
        covering.append(covers(f))
    if name == "loose_soil" and hit and f.get("value"):
        soil.append(0.5 <= f["value"] / f["truth"] <= 2.0)
    if ratio is not None and ratio >= 2:
        above.append(hit)
n, k = len(above), sum(above)
verdict = (
    "not decided (fewer than 10)" if n < 10 else ("passed" if k >= math.ceil(0.9 * n) else "failed")
)
print(f"H1 (primary, >= 90 %): singles at >= 2 x named-from named right {k}/{n}: {verdict}")
m, c = len(covering), sum(covering)
v2 = (
    "not decided (fewer than 5 named)"
    if m < 5
    else ("passed" if c >= math.ceil(0.9 * m) else "failed")
)
print(f"H2 (>= 90 %): of the true effects named, the 95 % interval holding the truth {c}/{m}: {v2}")
o, t = sum(others), len(others)
v3 = (
    "not decided (fewer than 10)"
    if t < 10
    else ("passed" if o <= math.floor(0.1 * t) else "failed")
)
print(f"H3 (<= 10 %): another effect named {o}/{t}: {v3}")
print(
    "reported: every strong single named right "
    f"{sum(sum(v) for v in all_hit.values())}/{sum(len(v) for v in all_hit.values())}; "
    + ", ".join(f"{e} {sum(v)}/{len(v)}" for e, v in all_hit.items())
)
print(f"reported: named soils with k_phi within 2 x {sum(soil)}/{len(soil)}")
ds = [r["diagnose_s"] for r in ok if r.get("diagnose_s")]
if ds:
    print(
        f"reported: diagnose seconds median {statistics.median(ds):.1f} over {len(ds)}"
        f" (min {min(ds):.0f}, max {max(ds):.0f}; two shards side by side)"
    )
