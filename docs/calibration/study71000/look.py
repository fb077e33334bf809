"""Study 71000's registered hypotheses (one look, after the stop).

Usage: ``python look.py ROWS.jsonl ...``: the rows of ``benchmarks/few_drives.py`` of both
streams (two drives from plan 71000, one drive from plan 71100)."""

import json
import sys

rows = [json.loads(x) for p in sys.argv[1:] for x in open(p).read().splitlines() if x]
ok = [r for r in rows if "error" not in r]
for r in rows:
    if "error" in r:
        print("   error:", r["case"], r["error"])
print(len(rows), "cases;", len(rows) - len(ok), "with an error")


def truth(r):
    return set(r["truth"]) if isinstance(r["truth"], dict) else set()


lost = sum(len((set(r["named_off"]) & truth(r)) - set(r["named"])) for r in ok)
print(
    f"H1 (primary, right names the rule removes <= 1): {lost} -> {'passed' if lost <= 1 else 'FAILED'}"
)
pairs_off = [r for r in ok if len(r["named_off"]) >= 2]
w_off = sum(len(set(r["named_off"]) - truth(r)) for r in pairs_off)
w_gone = sum(len((set(r["named_off"]) - truth(r)) - set(r["named"])) for r in pairs_off)
if w_off < 2:
    h2 = "undecided (fewer than 2)"
else:
    h2 = "passed" if w_gone >= w_off / 2 else "FAILED"
print(f"H2 (primary, wrong names beside a winner removed >= 50 %): {w_gone}/{w_off} -> {h2}")
h1_ok = lost <= 1
print("decision:", "on" if h1_ok and not h2.startswith("FAILED") else "off")

for drives in sorted({r["drives"] for r in ok}):
    rs = [r for r in ok if r["drives"] == drives]
    print(f"-- {drives} drive(s): {len(rs)} cases, the rule acted in {sum(r['acted'] for r in rs)}")
    for kind in ("single", "pair", "clean", "outside"):
        k = [r for r in rs if r["kind"] == kind]
        if not k:
            continue
        for key in ("named", "named_off"):
            right = sum(len(set(r[key]) & truth(r)) for r in k)
            wrong = sum(len(set(r[key]) - truth(r)) for r in k)
            none = sum(not r[key] for r in k)
            print(
                f"   {kind:8s} {key:9s} n {len(k):3d}  right {right:3d}  wrong {wrong:3d}  nothing {none:3d}"
            )
    secs = sorted(r["diagnose_s"] for r in rs)
    print(f"   diagnose seconds median {secs[len(secs) // 2]:.0f} (max {secs[-1]:.0f})")
for r in ok:
    if r["acted"] or r["named"] != r["named_off"]:
        print(
            "  ",
            r["case"],
            r["drives"],
            "truth",
            sorted(truth(r)),
            "on",
            r["named"],
            "off",
            r["named_off"],
            "limits",
            r["partner_limits"],
        )
