"""Block 52700's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py independent.json`` (the rows of plan 52700, one stream,
``bench_independent.py --effort --effort-cases 28 --seed0 52700 --workers 2``)."""

import json
import math
import statistics
import sys

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error")]
print(len(rows), "cases;", len(rows) - len(ok), "with an error")
for r in rows:
    if r.get("error"):
        print("   error:", r["case"], r["error"])


def reading(r, i=1):
    """The final (i=1) or first (i=0) diagnosis's effort record."""
    e = r.get("effort") or [None, None]
    return e[i] or {}


def fmt(e):
    if not e:
        return "no reading"
    cut = e.get("cut")
    c = "none" if cut is None else f"{cut[0]:+.3f} [{cut[1]:+.3f}, {cut[2]:+.3f}]"
    return (
        f"level {e.get('level')}, events {e.get('events')}, spread {e.get('spread', 0):.2f},"
        f" largest {e.get('largest', 0):.3f}, cut {c}, named {e.get('named')}"
        f" ({e.get('why_not', '')})"
    )


cuts = [r for r in ok if r["kind"] == "single" and "torque_limit" in r["truth"]]
hits, covering = [], []
print("torque cuts (truth as the bench writes it; the final diagnosis):")
for r in cuts:
    truth = r["truth"]["torque_limit"]["fraction"]
    hit = "torque_limit" in r["named"]
    hits.append(hit)
    iv = (r.get("named_fits") or {}).get("torque_limit", {}).get("fraction")
    if hit and iv:
        covering.append(iv[1] <= truth <= iv[2])
    print(
        f"   {r['case']}: truth {truth:+.4f}, named {r['named']}, interval {iv},"
        f" reading: {fmt(reading(r))}"
    )
n, k = len(hits), sum(hits)
v1 = "not decided (fewer than 5)" if n < 5 else ("passed" if k >= math.ceil(0.9 * n) else "failed")
print(f"H1 (primary, >= 90 %): torque cuts named right {k}/{n}: {v1}")
m, c = len(covering), sum(covering)
v2 = "not decided (none named)" if m == 0 else ("passed" if c >= math.ceil(0.9 * m) else "failed")
print(f"H2 (>= 90 %): of those named, the 95 % interval holding the truth {c}/{m}: {v2}")
rest = [r for r in ok if r not in cuts]
false = [r for r in rest if "torque_limit" in r["named"]]
allowed = max(1, len(rest) // 20)
print(
    f"H3 (at most {allowed}): clean and other-effect cases naming a torque limit"
    f" {len(false)}/{len(rest)}: {'passed' if len(false) <= allowed else 'failed'}"
)
print("reported: clean and other-effect cases (named, gap, reading):")
for r in rest:
    truth = "none" if r["kind"] == "clean" else sorted(r["truth"])
    print(f"   {r['case']}: truth {truth}, named {r['named']}, gap {r['unexplained']}")
    print(f"      reading: {fmt(reading(r))}")
clean = [r for r in ok if r["kind"] == "clean"]
print(
    f"reported: clean cases with anything named {sum(bool(r['named']) for r in clean)}/{len(clean)},"
    f" a gap {sum(bool(r['unexplained']) for r in clean)}/{len(clean)}"
)
others = [r for r in rest if r["kind"] == "single"]
right = sum(next(iter(r["truth"])) in r["named"] for r in others)
print(f"reported: other singles named right {right}/{len(others)}")
ds = [r["diagnose_s"] for r in ok if r.get("diagnose_s")]
if ds:
    allin = [r["make_logs_s"] + r["diagnose_s"] + r["followup_s"] for r in ok]
    print(
        f"reported: first diagnosis seconds median {statistics.median(ds):.1f}"
        f" (min {min(ds):.0f}, max {max(ds):.0f}); a whole case {statistics.median(allin):.1f}"
    )
