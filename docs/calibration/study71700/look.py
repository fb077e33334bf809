"""Study 71700's registered hypothesis from its rows (one look, after the stop).

Usage: ``python look.py OUT/71700/independent.json OUT/71800/independent.json ...`` (the merged
rows of each plan's shards, ``bench_independent.py --merge``)."""

import json
import math
import sys

CLEAN_HIGH = 0.041722  # the lag's clean spread (q95) in the table this study ran with

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error")]
print(len(rows), "cases;", len(rows) - len(ok), "with an error")
held, held_clean, above_bar, right_above = [], [], 0, 0
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
    others = [n for n in r["named"] if n != "command_lag"]
    print(
        f"   {r['case']}: truth {t:.4g}, named from {bar}, named {r['named']},"
        f" fitted {f.get('value')} [{f.get('lo')}, {f.get('hi')}] raw [{f.get('lo_raw')},"
        f" {f.get('hi_raw')}]" + (f"; also named {others}" if others else "")
    )
    if not hit:
        continue
    lo = f["lo"] if f["lo"] is not None else -math.inf
    hi = f["hi"] if f["hi"] is not None else math.inf
    held.append(lo <= t <= hi)
    if f.get("lo_raw") is not None:
        held_clean.append(f["lo_raw"] - CLEAN_HIGH <= t <= f["hi_raw"])
m, c = len(held), sum(held)
verdict = (
    "not decided (fewer than 5)" if m < 5 else ("passed" if c >= math.ceil(0.9 * m) else "failed")
)
print(f"H1 (primary, >= 90 %): lags named right {m}, interval holding the truth {c}/{m}: {verdict}")
print(f"reported: with the clean spread alone {sum(held_clean)}/{len(held_clean)}")
print(f"reported: lag singles at >= 2 x named-from named right {right_above}/{above_bar}")
