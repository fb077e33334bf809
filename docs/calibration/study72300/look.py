"""Study 72300's registered hypothesis from its rows (one look, after the stop).

Usage: ``python look.py OUT/72300/independent.json OUT/72400/independent.json ...`` (the merged
rows of each plan's shards, ``bench_independent.py --merge``)."""

import json
import math
import statistics
import sys

CLEAN_HIGH = 0.041722  # the lag's clean spread (q95) in the table this study ran with
ABOVE = 0.002683  # the lag's named-side pad above (stop 99's table, unchanged)

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error")]
print(len(rows), "cases;", len(rows) - len(ok), "with an error")
held, held_before, moved, above_bar, right_above, others = [], [], [], 0, 0, 0
for r in ok:
    if r["kind"] != "single" or "command_lag" not in r["truth"]:
        continue
    f = r["fits"].get("command_lag") or {}
    t = f.get("truth")
    bar = f.get("nameable")
    hit = "command_lag" in r["named"]
    if bar and t is not None and t >= 2 * bar:
        above_bar += 1
        right_above += hit
    also = [n for n in r["named"] if n != "command_lag"]
    others += bool(also)
    print(
        f"   {r['case']}: truth {t:.4g}, named from {bar}, named {r['named']},"
        f" fitted {f.get('value')} [{f.get('lo')}, {f.get('hi')}] raw [{f.get('lo_raw')},"
        f" {f.get('hi_raw')}]" + (f"; also named {also}" if also else "")
    )
    if not hit:
        continue
    lo = f["lo"] if f["lo"] is not None else -math.inf
    hi = f["hi"] if f["hi"] is not None else math.inf
    held.append(lo <= t <= hi)
    if f.get("lo_raw") is not None:
        before = (f["lo_raw"] - CLEAN_HIGH, f["hi_raw"] + ABOVE)
        held_before.append(before[0] <= t <= before[1])
        moved.append(hi - before[1])
m, c = len(held), sum(held)
verdict = (
    "not decided (fewer than 5)" if m < 5 else ("passed" if c >= math.ceil(0.9 * m) else "failed")
)
print(f"H1 (primary, >= 90 %): lags named right {m}, interval holding the truth {c}/{m}: {verdict}")
print(
    f"reported: without the far end's floor (stop 99's pads) {sum(held_before)}/{len(held_before)}"
)
if moved:
    print(
        f"reported: the floor moved the upper end by median {1000 * statistics.median(moved):.1f} ms"
        f" (max {1000 * max(moved):.1f}); moved at all in {sum(x > 1e-9 for x in moved)}"
    )
print(f"reported: lag singles at >= 2 x named-from named right {right_above}/{above_bar}")
print(f"reported: lag singles with anything else named {others}")
