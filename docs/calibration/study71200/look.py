"""Study 71200's registered hypothesis (one look, after 18:45 UTC).

Usage: ``python look.py ROWS.jsonl ...``: the rows of ``benchmarks/few_drives.py --rule
odometry_noise`` of both streams (two drives from plan 71200, one drive from plan 71300)."""

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


R = "rolling_radius"
gone = [r for r in ok if R in r["named_off"] and R not in r["named"]]
w = sum(R not in truth(r) for r in gone)
rr = sum(R in truth(r) for r in gone)
print(f"H1 (primary, W > R): W {w}, R {rr} -> {'passed' if w > rr else 'FAILED'}")
print("decision:", "on (noise_z 3)" if w >= rr else "off (noise_z 0)")

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
    se = sorted(
        o["noise_se"]
        for r in rs
        if (o := r.get("odometry"))
        and isinstance(o.get("noise_se"), float)
        and o["noise_se"] == o["noise_se"]
    )
    nan = sum(1 for r in rs if (o := r.get("odometry")) and o.get("difference") is not None) - len(
        se
    )
    if se:
        print(
            f"   standard error: median {100 * se[len(se) // 2]:.2f} %, max {100 * se[-1]:.2f} %;"
            f" too few intervals to measure it: {nan}"
        )
    secs = sorted(r["diagnose_s"] for r in rs)
    print(f"   diagnose seconds median {secs[len(secs) // 2]:.0f} (max {secs[-1]:.0f})")
print("-- radius names (with the rule: its interval; the clean band's from the same statistic)")
for r in ok:
    o = r.get("odometry") or {}
    if R in r["named_off"] or R in truth(r):
        t = (r["truth"].get(R) or {}).get("fraction") if isinstance(r["truth"], dict) else None
        f = o.get("fraction")
        print(
            "  ",
            r["case"],
            r["drives"],
            "truth",
            None if t is None else round(t, 4),
            "on",
            r["named"],
            "off",
            r["named_off"],
            "diff",
            None if o.get("difference") is None else round(o["difference"], 4),
            "se",
            o.get("noise_se") and round(o["noise_se"], 4),
            "fraction",
            f and [round(v, 4) for v in f],
            "why",
            o.get("why_not"),
        )
