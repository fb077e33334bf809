"""Study 72000's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py OUT/*/independent.json`` (the merged rows of each run's shards,
``bench_independent.py --merge``)."""

import json
import math
import sys

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error")]
print(len(rows), "cases;", len(rows) - len(ok), "with an error")
assert all(r.get("pose") == "end" for r in ok), "every case must have run with --pose end"
read = above = hit_above = 0
held: list[bool] = []
below_named = below = 0
for r in sorted(ok, key=lambda r: r["case"]):
    odo = r.get("odometry") or {}
    diff = odo.get("difference")
    readable = diff is not None and math.isfinite(diff)
    read += readable
    named = r["named"]
    if r["kind"] != "single":
        print(f"   {r['case']}: clean, read {readable} ({diff}), named {named}, odometry {odo}")
        continue
    f = r["fits"].get("rolling_radius") or {}
    t = f.get("truth")
    bar = f.get("nameable")
    hit = "rolling_radius" in named
    big = readable and bar is not None and t is not None and abs(t) >= 2 * bar
    above += big
    hit_above += big and hit
    if readable and not big:
        below += 1
        below_named += hit
    if hit and odo.get("named"):
        _, lo, hi = odo["fraction"]
        held.append(lo <= t <= hi)
    elif hit:
        lo, hi = f.get("lo"), f.get("hi")
        held.append(lo is not None and hi is not None and lo <= t <= hi)
    print(
        f"   {r['case']}: truth {t:.4g}, named from {bar}, read {readable} ({diff}),"
        f" named {named}, odometry named {odo.get('named')} {odo.get('fraction')},"
        f" why not: {odo.get('why_not')}, fitted {f.get('value')} [{f.get('lo')}, {f.get('hi')}]"
    )
verdict = (
    "not decided (fewer than 4)"
    if above < 4
    else ("passed" if hit_above >= math.ceil(0.75 * above) else "failed")
)
print(
    f"H1 (primary, >= 75 %): radius singles read, >= 2 x named-from: {above};"
    f" named {hit_above}: {verdict}"
)
clean = [r for r in ok if r["kind"] == "clean"]
false = [r["case"] for r in clean if (r.get("odometry") or {}).get("named")]
print(
    f"H2 (no clean radius from odometry): {len(false)} of {len(clean)} clean:"
    f" {'passed' if not false else 'failed'} {false}"
)
print(
    f"reported: cases read {read}/{len(ok)}; named radii's intervals holding the truth"
    f" {sum(held)}/{len(held)}; radius singles read below 2 x named-from named"
    f" {below_named}/{below}"
)
print(
    "reported: anything else named:",
    {
        r["case"]: [n for n in r["named"] if n != "rolling_radius"]
        for r in ok
        if any(n != "rolling_radius" for n in r["named"])
    },
)
secs = sorted(r["diagnose_s"] + r["followup_s"] for r in ok)
if secs:
    print(
        f"reported: seconds per case (diagnose + follow-up) median {secs[len(secs) // 2]:.0f},"
        f" range {secs[0]:.0f}-{secs[-1]:.0f}"
    )
