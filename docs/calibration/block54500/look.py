"""Block 54500's registered hypotheses from its rows (one look, after the stop).

Usage: ``python look.py independent.json`` (the rows of plan 54500: ``bench_independent.py
--balance-cases 24 --seed0 54500 --balance-others ... --headings unlogged --frames fit
--drive-kinds reversals --rounds 2 --workers 2``, no torque logged, the pose at 1 Hz, each
case's logs along one line each, every drive started facing a drawn way its YAML does not
give, diagnosed with ``--frames fit``, up to two rounds of proposed drives). Run from the
repository (it reads the generator's drawn start headings,
``rover_env.independent.generate.start_heading``)."""

import json
import math
import statistics
import sys

from rover_env.independent.generate import start_heading

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
ok = [r for r in rows if not r.get("error")]
print(len(rows), "cases;", len(rows) - len(ok), "with an error")
print("poses logged:", sorted({r.get("pose") for r in rows}))  # the block's: "as-logged" only
print("start headings:", sorted({r.get("headings") for r in rows}))  # the block's: "unlogged" only
print("frames:", sorted({r.get("frames") for r in rows}))  # the block's: "fit" only
print("drive kinds:", sorted({tuple(r.get("drive_kinds") or ()) for r in rows}))  # ("reversals",)
print("rounds:", sorted({r.get("rounds_asked") for r in rows}))  # the block's: 2 only
TWICE = 0.6  # degrees: 2 x the slip balance's clean tilt (0.3)


def truth(r):
    return next(iter(r["truth"])) if isinstance(r["truth"], dict) else "none"


def deg(r):
    return r["effects"]["slope"]["deg"]


def balance(r, which):
    """The balance record of the first (0) or final (1) diagnosis, or {}."""
    b = r.get("balance") or [None, None]
    return b[which] or {}


def covers(r, name):
    f = r["fits"].get(name) or {}
    lo = f["lo"] if f.get("lo") is not None else -math.inf
    hi = f["hi"] if f.get("hi") is not None else math.inf
    return lo <= f["truth"] <= hi


slopes = [r for r in ok if r["kind"] == "single" and truth(r) == "slope"]
big = [r for r in slopes if deg(r) >= TWICE]
right = [r for r in big if r["named"] == ["slope"]]
n, k = len(big), len(right)
v1 = "not decided (fewer than 6)" if n < 6 else ("passed" if k >= math.ceil(0.9 * n) else "failed")
print(f"H1 (primary, >= 90 %): slopes of >= {TWICE} deg named slope alone {k}/{n}: {v1}")
named = [r for r in slopes if "slope" in r["named"]]
cov = [covers(r, "slope") for r in named]
m, c = len(cov), sum(cov)
v2 = "not decided (none named)" if m == 0 else ("passed" if c >= math.ceil(0.9 * m) else "failed")
print(f"H2 (>= 90 %): named slopes whose 95 % interval holds the truth {c}/{m}: {v2}")
clean = [r for r in ok if r["kind"] == "clean"]
allowed = max(1, len(clean) // 20)
cn = sum(bool(r["named"]) for r in clean)
print(
    f"H3 (primary, at most {allowed} with a name): clean {len(clean)}: something named {cn}:"
    f" {'passed' if cn <= allowed else 'failed'}"
)
others = [r for r in ok if truth(r) != "slope"]
by_balance = [r for r in others if balance(r, 0).get("named") or balance(r, 1).get("named")]
print(
    f"H4 (at most 1): clean builds and other effects' cases where the balance named a slope"
    f" {len(by_balance)}/{len(others)}: {'passed' if len(by_balance) <= 1 else 'failed'}"
)
gapped = sum(bool(r["unexplained"]) for r in clean)
print(
    f"H5 (at most {allowed} with a gap): clean {len(clean)}: a gap reported {gapped}:"
    f" {'passed' if gapped <= allowed else 'failed'}"
)


def frames(r, which):
    """The frames record of the first (0) or final (1) diagnosis, or {}."""
    f = r.get("frames_fit") or [None, None]
    return f[which] or {}


def ref_log(fr):
    """The log whose frame the fitted frames are in: the first with a steady straight run."""
    return next((i for i, n in enumerate(fr["runs"]) if n), 0)


def holds(b, t):
    """Whether the balance record's interval for the truth (less the allowance; None an
    open end) holds ``t``."""
    lo, hi = b["truth_interval"]
    return (lo is None or lo <= t) and (hi is None or t <= hi)


FACTOR = 1.5  # H9: a named slope's value within this factor of the truth
SPREAD = 3.0  # balance_stage.SPREAD at registration: a named reading this wide asks the drive
valued = [r for r in named if (r["fits"].get("slope") or {}).get("value")]
near = [r for r in valued if 1 / FACTOR <= r["fits"]["slope"]["value"] / deg(r) <= FACTOR]
v9 = (
    "not decided (fewer than 6)"
    if len(valued) < 6
    else ("passed" if len(near) >= math.ceil(0.9 * len(valued)) else "failed")
)
print(
    f"H9 (primary, >= 90 %): named slopes (final) whose value lies within {FACTOR} x of the truth"
    f" {len(near)}/{len(valued)}: {v9}"
)
print(
    "reported: each named slope (case, truth, value, ratio)"
    f" {[(r['case'], round(deg(r), 2), round(r['fits']['slope']['value'], 2), round(r['fits']['slope']['value'] / deg(r), 2)) for r in valued]}"
)


def spread(b):
    """A named balance reading's interval ends' ratio (None where not named or open)."""
    lo, hi = b.get("tilt_interval") or (None, None)
    return hi / lo if b.get("action") == "name" and lo and hi else None


for which, label in ((0, "first"), (1, "final")):
    wide = [
        (r["case"], round(s, 1))
        for r in ok
        if (s := spread(balance(r, which))) is not None and s > SPREAD
    ]
    asked_named = [r["case"] for r in ok if balance(r, which).get("why_drive")]
    print(
        f"reported: {label} named readings spanning more than {SPREAD} x {wide};"
        f" those that asked for the drive {asked_named}"
    )
final_wide = [r for r in named if (s := spread(balance(r, 1))) is not None and s > SPREAD]
print(
    f"H10 (at most 2): named slopes whose final balance reading still spans more than"
    f" {SPREAD} x {len(final_wide)}/{len(named)}:"
    f" {'passed' if len(final_wide) <= 2 else 'failed'}"
)

read_fitted = [r for r in slopes if frames(r, 1).get("fitted") and balance(r, 1).get("read")]
h8 = [holds(balance(r, 1), deg(r)) for r in read_fitted]
v8 = (
    "not decided (fewer than 5)"
    if len(h8) < 5
    else ("passed" if sum(h8) >= math.ceil(0.9 * len(h8)) else "failed")
)
print(
    f"H8 (>= 90 %): slopes read by the balance in fitted frames (final diagnosis) whose"
    f" interval for the truth holds it {sum(h8)}/{len(h8)}: {v8}"
)
print(
    "reported: each (case, truth, read [interval for the truth], action)"
    f" {[(r['case'], round(deg(r), 2), round(balance(r, 1)['tilt'], 2), balance(r, 1)['truth_interval'], balance(r, 1).get('action')) for r in read_fitted]}"
)
opened = [r for r in ok for w in (0, 1) if balance(r, w).get("action") == "open"]
print(f"reported: readings left open above (either diagnosis) {[r['case'] for r in opened]}")
fitted_named = [r for r in named if frames(r, 1).get("fitted")]
known = [
    r["case"] for r in fitted_named if (r["fits"].get("slope") or {}).get("heading_known", True)
]
print(
    f"reported: named slopes in fitted frames whose record gives the heading as known"
    f" {len(known)}/{len(fitted_named)} {known}"
)

turned_others = [r for r in others if frames(r, 0).get("fitted") or frames(r, 1).get("fitted")]
print(
    f"H7 (at most 1): clean builds and other effects' cases whose frames were fitted (first or"
    f" final diagnosis) {len(turned_others)}/{len(others)}:"
    f" {'passed' if len(turned_others) <= 1 else 'failed'}"
)
unfitted = [r for r in named if not frames(r, 1).get("fitted")]


def plain_error(r):
    """A named slope's heading less the truth's in drive 0's frame (frames not fitted: every
    log read as facing drive 0's way), or None."""
    f = r["fits"].get("slope") or {}
    h = f.get("heading")
    if not h or h[0] is None or (isinstance(h[0], float) and math.isnan(h[0])):
        return None
    return math.remainder(h[0] - (f["truth_heading"] - start_heading(r["seed"], 0)), 360.0)


print(
    f"reported: named slopes read in frames not fitted {len(unfitted)}/{len(named)}, heading"
    f" errors in drive 0's frame {[(r['case'], None if (e := plain_error(r)) is None else round(e, 1)) for r in unfitted]}"
)
for which, label in ((0, "first"), (1, "final")):
    fs = [r for r in slopes if frames(r, which).get("fitted")]
    print(f"reported: slopes whose frames the {label} diagnosis fitted {len(fs)}/{len(slopes)}")
print(
    "reported, each slope's frames (final diagnosis): F, runs per log, turn errors (deg) of logs with runs:"
)
for r in slopes:
    fr = frames(r, 1)
    if not fr:
        print(f"   {r['case']}: no frames record")
        continue
    if not fr.get("fitted"):
        print(f"   {r['case']}: not fitted, {fr.get('why_not')}")
        continue
    k = ref_log(fr)
    true = [
        start_heading(r["seed"], i) - start_heading(r["seed"], k) for i in range(len(fr["runs"]))
    ]
    err = [
        round(math.remainder(t - u, 360.0), 1)
        for t, u, n in zip(fr["turns_deg"], true, fr["runs"], strict=True)
        if n
    ]
    print(f"   {r['case']}: F {fr['f']:.1f}, runs {fr['runs']}, turn errors {err}")
small = [r for r in slopes if deg(r) < TWICE]
print(
    f"reported: slopes under {TWICE} deg named slope alone {sum(r['named'] == ['slope'] for r in small)}/{len(small)}"
)
src = sorted({balance(r, w).get("source", "-") for r in ok for w in (0, 1)})
print(f"reported: balance sources seen {src}")
fb = [r for r in slopes if balance(r, 1).get("named")]
print(f"reported: slopes named by the balance (final diagnosis) {len(fb)}/{len(slopes)}")
unsep = [r for r in slopes if balance(r, 1).get("read") and not balance(r, 1).get("separated")]
print(f"reported: slopes whose runs left the tilt unseparated (final) {len(unsep)}/{len(slopes)}")
wrong = [r for r in ok if r["kind"] == "single" and set(r["named"]) - set(r["truth"])]
print(
    f"reported: singles with another effect named {len(wrong)}/{len([r for r in ok if r['kind'] == 'single'])}"
)
moved = [
    (r["case"], k, w["deg"], w["interval"])
    for r in ok
    for which in (0, 1)
    for k in ("withdrew", "replaced")
    for w in balance(r, which).get(k) or []
]
print(f"reported: the windows' slopes alone withdrawn or replaced by the balance {moved}")
kept = [r for r in slopes if "slope" in r["named"] and not balance(r, 1).get("named")]
print(f"reported: slopes named, not by the balance (final) {len(kept)}/{len(slopes)}")
for kind in (
    "rolling_resistance",
    "loose_soil",
    "command_lag",
    "command_delay",
    "torque_limit",
    "friction",
):
    part = [r for r in ok if truth(r) == kind]
    print(
        f"reported: {kind} singles named it alone {sum(r['named'] == [kind] for r in part)}/{len(part)}"
    )
acts = {}
for r in ok:
    a = balance(r, 0).get("action", "-")
    acts[a] = acts.get(a, 0) + 1
print(f"reported: the first diagnosis' balance actions {dict(sorted(acts.items()))}")
heads = {}
for r in ok:
    for w in (0, 1):
        h = balance(r, w).get("heading_from", "-") if balance(r, w).get("read") else "not read"
        heads[(w, h)] = heads.get((w, h), 0) + 1
print(
    f"reported: the runs' heading sources (0 first, 1 final diagnosis) {dict(sorted(heads.items()))}"
)
asked = [r for r in ok if balance(r, 0).get("plan")]
print(f"reported: cases whose first balance asked for its drive {len(asked)}/{len(ok)}")
first = [r for r in big if r["first_named"] == ["slope"]]
print(
    f"reported: slopes of >= {TWICE} deg named slope alone at the first diagnosis {len(first)}/{len(big)}"
)
ds = [r["diagnose_s"] for r in ok if r.get("diagnose_s")]
if ds:
    allin = [r["make_logs_s"] + r["diagnose_s"] + r["followup_s"] for r in ok]
    print(
        f"reported: diagnose seconds (first diagnosis) median {statistics.median(ds):.1f};"
        f" whole case median {statistics.median(allin):.1f}"
    )


def held_seeds(rd, plan):
    """The seeds of ``plan`` a diagnosis's logs held."""
    return {h["seed"] for h in (rd.get("plans_held") or {}).get(plan, [])}


repeats, asks, would = [], 0, []
for r in ok:
    for i, rd in enumerate(r.get("rounds") or []):
        for a in (rd.get("asked") or []) + (rd.get("untested") or []):
            asks += 1
            if a["seed"] in held_seeds(rd, a["plan"]):
                repeats.append((r["case"], i, a["plan"], a["seed"]))
            if i > 0 and 0 in held_seeds(rd, a["plan"]):  # the code before: always seed 0
                would.append((r["case"], i, a["plan"]))
print(
    f"H11 (primary, 0): proposals that ask for a draw their diagnosis's logs hold"
    f" {len(repeats)} of {asks} {repeats}: {'passed' if not repeats else 'failed'}"
)
print(
    f"reported: proposals the code before would have asked again (seed 0 held) {len(would)} {would}"
)
diags = [len(r.get("rounds") or []) for r in ok]
print(
    "reported: diagnoses per case (1: none driven, 2: one round, 3: two rounds)"
    f" {dict(sorted((k, diags.count(k)) for k in set(diags)))}"
)
left = [r["case"] for r in ok if len(r.get("rounds") or []) == 3 and r["rounds"][2]["asked"]]
print(f"reported: cases still asking after the second round {left}")
first_named = [r for r in slopes if balance(r, 0).get("action") == "name"]
first_near = [r for r in first_named if 1 / FACTOR <= balance(r, 0)["tilt"] / deg(r) <= FACTOR]
print(
    f"reported: first balance-named slope values within {FACTOR} x of the truth"
    f" {len(first_near)}/{len(first_named)}"
    f" {[(r['case'], round(deg(r), 2), round(balance(r, 0)['tilt'], 2), [round(x, 2) if x is not None else None for x in balance(r, 0)['tilt_interval']]) for r in first_named]}"
)
print(
    "reported, every case (truth, first named, final named, balance tilt [interval] separated, fit [interval]):"
)
for r in ok:
    t = truth(r)
    b = balance(r, 1)
    bt = (
        f"{b['tilt']:.2f} {b['tilt_interval']}"
        f" {'separated' if b.get('separated') else 'unseparated'}, headed by {b.get('heading_from')}"
        if b.get("read")
        else "not read"
    )
    f = r["fits"].get(t) or {}
    fol = "; ".join(
        ",".join(f"{a['plan']}/{a['seed']}" for a in rd.get("asked") or [])
        for rd in r.get("rounds") or []
    )
    print(
        f"   {r['case']}: truth {r['truth'] if t != 'none' else 'none'}, first {r['first_named']},"
        f" final {r['named']}, balance {bt}, fit {f.get('value')} [{f.get('lo')}, {f.get('hi')}]"
        + (f", gap {r['unexplained']}" if r.get("unexplained") else "")
        + (f", asked per diagnosis {fol}" if fol.strip("; ") else "")
    )


# Block 54500's own lines: drives no answer could come from are not asked for.
last_asks = [r["case"] for r in ok if (r.get("rounds") or [{}])[-1].get("asked")]
print(
    f"H12 (primary, at most 3): cases whose last diagnosis still asks for a drive"
    f" {len(last_asks)}/{len(ok)} {last_asks}: {'passed' if len(last_asks) <= 3 else 'failed'}"
)
untested = [
    (r["case"], i, u["plan"], u["seed"])
    for r in ok
    for i, rd in enumerate(r.get("rounds") or [])
    for u in rd.get("untested") or []
]
print(
    f"H13 (primary, at most 2): untested-limit proposals over every diagnosis {len(untested)}"
    f" {untested}: {'passed' if len(untested) <= 2 else 'failed'}"
)
if ds:
    whole = statistics.median(allin)
    print(
        f"H14 (under 150 s): a whole case's median seconds {whole:.1f}:"
        f" {'passed' if whole < 150 else 'failed'}"
    )
driven = sum(len(rd.get("asked") or []) for r in ok for rd in (r.get("rounds") or [])[:-1])
print(f"reported: drives asked and driven (every round but each case's last diagnosis) {driven}")
by_plan = {}
for r in ok:
    for rd in r.get("rounds") or []:
        for a in rd.get("asked") or []:
            k = (",".join(a.get("for") or []), a["plan"])
            by_plan[k] = by_plan.get(k, 0) + 1
print(f"reported: proposals by effect and plan {dict(sorted(by_plan.items()))}")
why = {}
for r in ok:
    for rd in r.get("rounds") or []:
        for j in rd.get("judged") or []:
            k = (j["effect"], j["why"])
            why[k] = why.get(k, 0) + 1
print(f"reported: drives not asked for, by effect and why {dict(sorted(why.items()))}")
