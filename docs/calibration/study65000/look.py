"""Study 65000's registered hypotheses from its rows (one look, after the stop).

python docs/calibration/study65000/look.py ROWS.json [ROWS.json ...]
"""

import json
import statistics
import sys

ALLOWANCE = 0.0316  # the clean-fit allowance's 95 % quantile for c_rr (form_allowance)
LARGE = 0.05

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
rr = [
    r
    for r in rows
    if r["kind"] == "single"
    and "rolling_resistance" in (r["truth"] if isinstance(r["truth"], dict) else {})
]
print(len(rows), "rows,", len(rr), "rolling-resistance singles")


def c_rr(r):
    return r["truth"]["rolling_resistance"]["c_rr"]


def named(r):
    return "rolling_resistance" in r["named"]


for r in sorted(rr, key=c_rr):
    f = r["fits"].get("rolling_resistance") or {}
    print(
        f"   {r['case']}: c_rr {c_rr(r):.4g} named {r['named']} fit {f.get('value')}"
        f" [{f.get('lo')}, {f.get('hi')}] test {f.get('test')} withdrawn {bool(any(r.get('allowance_withdrawn') or []))}"
        f" {r['diagnose_s']:.0f} s"
    )
low = [r for r in rr if c_rr(r) < ALLOWANCE]
mid = [r for r in rr if ALLOWANCE <= c_rr(r) < LARGE]
high = [r for r in rr if c_rr(r) >= LARGE]
print(f"H1: under {ALLOWANCE}: named rolling resistance {sum(map(named, low))}/{len(low)}")
print(f"H2: at {LARGE} or more: named rolling resistance {sum(map(named, high))}/{len(high)}")
print(f"H3: {ALLOWANCE} to {LARGE}: named {sum(map(named, mid))}/{len(mid)}")
other = [(r["case"], r["named"]) for r in rr if any(n != "rolling_resistance" for n in r["named"])]
print(f"H4: another effect named on {len(other)}/{len(rr)}: {other}")
cover = []
for r in rr:
    if named(r):
        f = r["fits"]["rolling_resistance"]
        lo = f["lo"] if f["lo"] is not None else -float("inf")  # one-sided: as the bench's
        hi = f["hi"] if f["hi"] is not None else float("inf")  # covers()
        cover.append(lo <= c_rr(r) <= hi)
print(f"H5: named intervals holding the truth {sum(cover)}/{len(cover)}")
ds = [r["diagnose_s"] for r in rr]
print(f"seconds: diagnose median {statistics.median(ds):.1f} (max {max(ds):.0f}) over {len(ds)}")
