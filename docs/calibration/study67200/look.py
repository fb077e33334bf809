"""Study 67200's registered hypotheses (one look, after the stop).

Usage: ``python look.py SPLIT.jsonl BRAKE_ROWS.json ...``: stream B's split rows
(``benchmarks/one_wheel_split.py``) and the brake-drag cases' ``independent.json`` files
(``bench_independent.py --only outside_brake_drag``)."""

import json
import sys

LIMIT = 0.05
split_rows = [json.loads(x) for x in open(sys.argv[1]).read().splitlines() if x]
brake = [r for p in sys.argv[2:] for r in json.load(open(p)) if "brake_drag" in r["effects"]]
print(
    len(split_rows),
    "split cases;",
    len(brake),
    "brake-drag cases;",
    sum(bool(r.get("error")) for r in brake),
    "with an error",
)

beyond = [r for r in split_rows if abs(r["split"]) > LIMIT]
allowed = max(1, len(split_rows) // 20)
for r in beyond:
    print("   beyond:", r["case"], f"{r['split']:+.4f}")
print(
    f"H1 (primary, at most {allowed} of {len(split_rows)} beyond {LIMIT:.0%}): {len(beyond)}"
    f" -> {'passed' if len(beyond) <= allowed else 'FAILED'}"
)
for kind in ("single_rolling_resistance", "clean_none"):
    s = sorted(r["split"] for r in split_rows if r["case"].startswith(kind))
    if s:
        print(f"   {kind}: {len(s)}, {s[0]:+.4f} .. {s[-1]:+.4f}, median {s[len(s) // 2]:+.4f}")

asked = withdrew = 0
final_rr = nothing = other = 0
for r in sorted(brake, key=lambda r: r["seed"]):
    if r.get("error"):
        print("   error:", r["case"], r["error"])
        continue
    rec = (r.get("one_wheel") or [None, None])[-1]
    if rec is not None:
        asked += 1
        withdrew += bool(rec["withdrawn"])
    final_rr += "rolling_resistance" in r["named"]
    nothing += not r["named"]
    other += bool([n for n in r["named"] if n != "rolling_resistance"])
    first = (r.get("one_wheel") or [None, None])[0]
    od = r.get("odometry") or {}
    sp = (rec or first or {}).get("split", od.get("split"))
    print(
        f"   {r['case']}: torque {r['effects']['brake_drag']['torque']:.3f} wheel"
        f" {int(r['effects']['brake_drag']['wheel'])}, split"
        f" {'-' if sp is None else f'{sp:+.4f}'}, first {r['first_named']}, final {r['named']},"
        f" rule {'-' if rec is None else ('withdrew' if rec['withdrawn'] else 'kept')}"
    )
ok = asked and withdrew >= asked / 2
print(
    f"H2 (primary, withdrawn in >= 50 % of those asked): {withdrew}/{asked}"
    f" -> {'passed' if ok else 'FAILED'}"
)
n = len([r for r in brake if not r.get("error")])
print(
    f"reported: final rolling resistance {final_rr}/{n} (spent 13/24), nothing named"
    f" {nothing}/{n}, another name {other}/{n}"
)
