"""Block 54900's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py singles/independent.json clean/independent.json`` (plan 54900's
singles, then its clean builds, one stream: ``bench_independent.py --seed0 54900 --only
single_`` and ``--only clean_``, ``--workers 2``); the pooled secondary look adds block
54800's singles and block 54600's clean builds (already seen) after this block's rows.
Block 54800's look with H3, H5 and H11 added: what naming on the windows' interval
(``Options.presence_on_windows``, stop 132) named, and what it named on clean builds."""

import json
import math
import statistics
import sys

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
rows = [r for r in rows if r.get("kind") in ("single", "clean")]
ok = [r for r in rows if not r.get("error")]
print(len(rows), "singles and clean builds;", len(rows) - len(ok), "with an error")


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
singles = [r for r in ok if r["kind"] == "single"]
other = [r for r in singles if set(r["named"]) - set(r["truth"]) - set(r.get("equivalent") or [])]
print(f"reported: singles with another effect named {len(other)}/{len(singles)}")
for r in other:
    print("   other:", r["case"], r["named"])
ds = [r["diagnose_s"] for r in ok if r.get("diagnose_s")]
if ds:
    med = statistics.median(ds)
    print(
        f"H4 (<= 60 s): diagnose seconds (first diagnosis) median {med:.1f} over {len(ds)}"
        f" (min {min(ds):.0f}, max {max(ds):.0f}; one case at a time, 2 workers):"
        f" {'passed' if med <= 60 else 'failed'}"
    )
    allin = [r["make_logs_s"] + r["diagnose_s"] + r["followup_s"] for r in ok]
    print(
        f"reported: seconds per case in all (logs, diagnoses, follow-ups) median"
        f" {statistics.median(allin):.1f}"
    )
print("reported, every single by effect (truth, named from, x, named, fit):")
by = {}
for r in ok:
    if r["kind"] == "single":
        by.setdefault(next(iter(r["truth"])), []).append(r)
for name, rs in sorted(by.items()):
    hits = sum(name in r["named"] for r in rs)
    print(f"  {name}: named right {hits}/{len(rs)}")
    for r in rs:
        f = r["fits"].get(name) or {}
        bar = f.get("nameable")
        x = size(name, f["truth"]) / bar if bar and f.get("truth") is not None else float("nan")
        fol = ",".join(p["plan"] for p in r.get("followup") or [])
        print(
            f"    {r['case']}: truth {f.get('truth')}, named from {bar}, x {x:.2f},"
            f" named {r['named']}, fit {f.get('value')} [{f.get('lo')}, {f.get('hi')}]"
            + (f", follow-up {fol}" if fol else "")
        )
soils = [r for r in by.get("loose_soil", []) if "loose_soil" in r["named"]]
within = sum(
    0.5 <= r["fits"]["loose_soil"]["value"] / r["fits"]["loose_soil"]["truth"] <= 2 for r in soils
)
print(f"reported: named soils with k_phi within 2 x: {within}/{len(soils)}")
rule = [r for r in ok if r.get("tie_unseparated")]
print(
    f"reported: ties declared because no held-out window reversed (reversal_tie): {len(rule)}/{len(ok)}"
)
for r in rule:
    print(f"   {r['case']}: tie {r['tie']}, first named {r['first_named']}, final {r['named']}")
fol = [r for r in ok if r.get("followup")]
print(f"reported: cases with a follow-up drive {len(fol)}/{len(ok)}")
# Block 54600's additions: the acceptance's first line, and the drives asked (stop 129).
at_thr = []
for r in singles:
    ((name, _),) = r["truth"].items()
    f = r["fits"].get(name) or {}
    thr = f.get("threshold")
    if thr and f.get("truth") is not None and size(name, f["truth"]) / thr >= 2:
        at_thr.append(name in r["named"])
n6, k6 = len(at_thr), sum(at_thr)
v6 = (
    "not decided (fewer than 5)"
    if n6 < 5
    else ("passed" if k6 >= math.ceil(0.9 * n6) else "failed")
)
print(f"H6 (>= 90 %): singles at >= 2 x the noise threshold named right {k6}/{n6}: {v6}")
asked = {}
for r in ok:
    for p in r.get("followup") or []:
        k = (",".join(p.get("for") or []), p["plan"])
        asked[k] = asked.get(k, 0) + 1
print(f"reported: follow-up drives by effect and plan {dict(sorted(asked.items()))}")
unt = sum(bool(r.get("untested")) for r in ok)
print(f"reported: cases whose first diagnosis proposed the untested limit's drive {unt}/{len(ok)}")


# Block 54700's additions (stop 130): right names the follow-up drive took back, and the
# first diagnosis's provisional flag.
lost = [
    r
    for r in singles
    if set(r["truth"]) <= set(r["first_named"]) and not set(r["truth"]) <= set(r["named"])
]
print(
    f"H7 (at most 1): singles whose first diagnosis named the truth and the final did not"
    f" {len(lost)}/{len(singles)}: {'passed' if len(lost) <= 1 else 'failed'}"
)
for r in lost:
    print("   lost:", r["case"], "first", r["first_named"], "final", r["named"], r.get("followup"))
unflagged = [
    r
    for r in ok
    if r["first_named"]
    and set(r["first_named"]) != set(r["named"])
    and not (r.get("rounds") or [{}])[0].get("provisional")
]
changed = sum(bool(r["first_named"]) and set(r["first_named"]) != set(r["named"]) for r in ok)
print(
    f"H8 (0): cases whose first names changed with the follow-up though the first report"
    f" did not call them provisional {len(unflagged)} (of {changed} changed):"
    f" {'passed' if not unflagged else 'failed'}"
)
flagged = sum(bool((r.get("rounds") or [{}])[0].get("provisional")) for r in ok)
print(f"reported: first reports calling their names provisional {flagged}/{len(ok)}")


# Block 54800's additions (stop 131): the names the follow-up drives changed, both ways.
fol_rows = [r for r in singles if r.get("followup")]
gained = [
    r
    for r in fol_rows
    if not set(r["truth"]) <= set(r["first_named"]) and set(r["truth"]) <= set(r["named"])
]
wrong_new = [
    r
    for r in fol_rows
    if (set(r["named"]) - set(r["first_named"])) - set(r["truth"]) - set(r.get("equivalent") or [])
]
print(
    f"H9 (at most 2): singles with a follow-up whose final diagnosis added another effect's"
    f" name {len(wrong_new)}/{len(fol_rows)}: {'passed' if len(wrong_new) <= 2 else 'failed'}"
)
for r in wrong_new:
    print("   added:", r["case"], "first", r["first_named"], "final", r["named"])
print(
    f"H10 (at least as many as H7's lost): right names the follow-up gained {len(gained)},"
    f" lost {len(lost)}: {'passed' if len(gained) >= len(lost) else 'failed'}"
)
for r in gained:
    print("   gained:", r["case"], "first", r["first_named"], "final", r["named"])


# Block 54900's additions (stop 132): names made on the windows' interval, and clean builds.
clean = [r for r in ok if r["kind"] == "clean"]
named = sum(bool(r["named"]) for r in clean)
allowed = max(1, len(clean) // 20)
print(
    f"H3 (primary, at most {allowed} with a name): clean {len(clean)}: something named"
    f" {named}: {'passed' if named <= allowed else 'failed'}"
)
gapped = sum(bool(r["unexplained"]) for r in clean)
print(f"reported (H5's line, at most {allowed}): clean {len(clean)}: a gap reported {gapped}")
for r in clean:
    if r["named"] or r["unexplained"]:
        print("   clean:", r["case"], r["named"], r["unexplained"])
made = []
for r in ok:
    final = (r.get("named_on_windows") or [None, None])[-1] or []
    for name in final:
        made.append((r, name, name in r["truth"] or name in (r.get("equivalent") or [])))
wrong = [m for m in made if not m[2]]
print(
    f"H11 (primary, at most 1 wrong): final names made on the windows' interval {len(made)},"
    f" the truth {len(made) - len(wrong)}, another effect or a clean build {len(wrong)}:"
    f" {'passed' if len(wrong) <= 1 else 'failed'}"
)
for r, name, right in made:
    f = (r.get("fits") or {}).get(name) or {}
    print(
        f"   {r['case']}: {name} {'right' if right else 'WRONG'}, truth {f.get('truth')},"
        f" fit {f.get('value')} [{f.get('lo')}, {f.get('hi')}]"
    )
first_made = sum(bool((r.get("named_on_windows") or [None])[0]) for r in ok)
print(f"reported: first diagnoses with a name made on the windows' interval {first_made}/{len(ok)}")
