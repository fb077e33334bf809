"""Random-magnitude matrix of the model-discrepancy workflow (issues 8, 16): logs, then diagnose.

Each case: a generator writes 3 drives of 50 s (2 training, 1 held out) from a truth model
with hidden effects; ``diagnose`` sees only the logs. Two generators: ``make-logs`` (this
project's simulator) and ``foreign`` (:mod:`rover_env.generators.foreign_logs`, a
deliberately different implementation of the same rover). The table, the per-effect
detection curves and the acceptance figures go to ``docs/calibration/matrix.md`` (and
``matrix.json``).

Magnitudes are drawn, not chosen: each single-effect case draws its magnitude log-uniform
over the effect's documented range (``RANGES``), with a random sign where the parameter has
one, from a generator seeded by the case seed; nobody picks the values diagnose is tested
at. The detection curves put each case's magnitude over that effect's noise threshold as
diagnose reports it for those drives (the magnitude at which the effect moves its most
sensitive signal by one replay floor, :func:`rover_env.calibration.diagnosis.fit_stage.noise_threshold`).

    python benchmarks/bench_diagnose.py --quick   # 8 seeded cases over both generators
    # the full matrix (~110 cases, many hours): one shard per core, resumable, then merge
    python benchmarks/bench_diagnose.py --shard 0/2 --resume & \
        python benchmarks/bench_diagnose.py --shard 1/2 --resume; wait
    python benchmarks/bench_diagnose.py --merge
    python benchmarks/bench_diagnose.py --case-workers 2           # cases side by side
    python benchmarks/bench_diagnose.py --executor ray --ray-address HOST:6379  # on a cluster

When a case ends in a tie that includes a true effect, the separating drive the report
proposes is generated (``make-logs --plan``) and the case diagnosed again with it.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from _report import write_report

from rover_env.calibration.diagnose import Options, diagnose
from rover_env.config import JointSpec, RoverConfig
from rover_env.executor import add_executor_args, make_executor, run_study
from rover_env.generators.foreign_logs import FOREIGN_EFFECTS, make_foreign_logs
from rover_env.generators.make_logs import make_logs

# effect -> (parameter, smallest magnitude, largest magnitude, signs drawn from)
INERT_ON_SOIL = frozenset(
    {"rolling_resistance", "rolling_radius", "friction", "load_dependent_friction"}
)
"""Tire effects that do not act where the ground is loose soil (the soil replaces the tire,
in both generators): a pair of one of them with ``loose_soil`` has one effect nobody can
see, so it is never drawn (stop 29 drew rolling resistance + loose soil, seed 9081)."""

RANGES: dict[str, tuple[str, float, float, tuple[int, ...]]] = {
    "rolling_resistance": ("c_rr", 0.004, 0.08, (1,)),
    "slope": ("deg", 0.5, 10.0, (1,)),  # heading uniform over the circle
    "rolling_radius": ("fraction", 0.005, 0.1, (-1, 1)),  # clipped to [-0.2, 0.1]
    "torque_limit": ("fraction", 0.05, 0.7, (-1,)),  # a raised limit is invisible unless
    # the nominal one is reached: only lowered limits are drawn
    "command_lag": ("tau", 0.01, 0.5, (1,)),
    "command_delay": ("delay", 0.005, 0.3, (1,)),
    "friction": ("fraction", 0.03, 0.5, (-1, 1)),
    "combined_slip": ("on", 1.0, 1.0, (1,)),  # a switch: no magnitude
    "load_dependent_friction": ("fall", 0.03, 0.6, (1,)),
    # Bekker's k_phi from a sand far looser than dune sand (1.5e6) to a stiff one, whose wheel
    # sinks 1.6 mm at rest (both generators; the second one has its own soil since stop 29).
    "loose_soil": ("k_phi", 2e5, 1e7, (1,)),
}
BOUNDS = {"rolling_radius": (-0.2, 0.1), "friction": (-0.7, 1.0)}
# The 16 weak fixed-magnitude cases of issue 8 (seeds 200, 201), kept for comparison.
WEAK: dict[str, tuple[str, float]] = {
    "rolling_resistance": ("c_rr", 0.02),
    "slope": ("deg", 2.0),
    "rolling_radius": ("fraction", -0.03),
    "torque_limit": ("fraction", -0.25),
    "command_lag": ("tau", 0.1),
    "command_delay": ("delay", 0.05),
    "friction": ("fraction", -0.15),
    "load_dependent_friction": ("fall", 0.15),
}
OUTSIDE = ("mass +20 %", "leaf springs x2", "joint damping x3", "slip stiffness x0.5")
SEED0 = 2000
"""Case seeds from the validation range (rover_env.benchmark.seeds): never tuned on."""


def draw(effect: str, seed: int) -> dict[str, float]:
    """The effect's parameters for case ``seed``: log-uniform magnitude, random sign."""
    param, lo, hi, signs = RANGES[effect]
    rng = np.random.default_rng([seed, 16, len(effect)])
    if effect == "combined_slip":
        return {"on": 1.0}
    mag = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    sign = int(rng.choice(signs))
    v = sign * mag
    if effect in BOUNDS:
        v = float(np.clip(v, *BOUNDS[effect]))
    out = {param: round(v, 5)}
    if effect == "slope":
        out["heading_deg"] = round(float(rng.uniform(-180.0, 180.0)), 1)
    return out


def _heavier() -> RoverConfig:
    c = RoverConfig()
    m = c.masses
    masses = replace(
        m,
        wheel=m.wheel * 1.2,
        motor=m.motor * 1.2,
        battery=m.battery * 1.2,
        chassis=tuple(x * 1.2 for x in m.chassis),
    )
    return replace(c, masses=masses)


def _joints(stiff: float, damp: float) -> RoverConfig:
    c = RoverConfig()
    joints = {
        k: JointSpec(v.stiffness * stiff, v.damping * damp, v.limit) for k, v in c.joints.items()
    }
    return replace(c, joints=joints)


def _slip_stiffness() -> RoverConfig:
    c = RoverConfig()
    return replace(c, tire=replace(c.tire, C_s=c.tire.C_s * 0.5, C_alpha=c.tire.C_alpha * 0.5))


TRUTH_ROVERS = {
    "mass +20 %": _heavier,
    "leaf springs x2": lambda: _joints(2.0, 1.0),
    "joint damping x3": lambda: _joints(1.0, 3.0),
    "slip stiffness x0.5": _slip_stiffness,
}


def cases(quick: bool = False, seed0: int = SEED0) -> list[dict[str, Any]]:
    """Every planned case (generator "own" = make-logs, "foreign" = the second generator),
    seeds counted from ``seed0`` (another ``seed0``: a fresh set of draws and drives)."""
    out: list[dict[str, Any]] = []
    seed = seed0
    for gen, per_effect, n_clean, n_pairs, outside in (
        ("own", 7, 10, 6, OUTSIDE),
        ("foreign", 2, 3, 2, OUTSIDE[:2]),
    ):
        drawn = [n for n in RANGES if gen == "own" or n in FOREIGN_EFFECTS]
        for _ in range(per_effect):
            for name in drawn:
                out.append(
                    {
                        "kind": "single",
                        "gen": gen,
                        "effects": {name: draw(name, seed)},
                        "seed": seed,
                    }
                )
                seed += 1
        for _ in range(n_clean):
            out.append({"kind": "clean", "gen": gen, "effects": {}, "seed": seed})
            seed += 1
        names = [n for n in drawn if n != "combined_slip"]
        for _ in range(n_pairs):
            rng = np.random.default_rng([seed, 16])
            while True:  # a pair both of whose effects act (redrawn, same seeded stream)
                a, b = (str(x) for x in rng.choice(names, 2, replace=False))
                if not ("loose_soil" in (a, b) and {a, b} & INERT_ON_SOIL):
                    break
            eff = {a: draw(a, seed), b: draw(b, seed + 50_000)}
            out.append({"kind": "pair", "gen": gen, "effects": eff, "seed": seed})
            seed += 1
        for truth in outside:
            out.append({"kind": "outside", "gen": gen, "effects": {}, "truth": truth, "seed": seed})
            seed += 1
    for name, (param, v) in WEAK.items():
        for s in (200, 201):
            out.append({"kind": "weak", "gen": "own", "effects": {name: {param: v}}, "seed": s})
    if quick:
        want = [
            ("own", "single", "rolling_resistance"),
            ("foreign", "single", "rolling_resistance"),
            ("own", "clean", None),
            ("foreign", "clean", None),
            ("own", "single", "friction"),
            ("foreign", "single", "slope"),
            ("own", "single", "command_lag"),
            ("foreign", "single", "command_delay"),
        ]
        picked = []
        for gen, kind, name in want:
            for c in out:
                if c["gen"] == gen and c["kind"] == kind and (name is None or name in c["effects"]):
                    picked.append(c)
                    break
        return picked
    return out


def _group(c: dict[str, Any]) -> tuple[str, str, str]:
    """A case's group for the run order: generator, kind and (singles, weak) the effect."""
    eff = next(iter(c["effects"]), "") if c["kind"] in ("single", "weak") else ""
    return (c["gen"], c["kind"], eff)


def planned(quick: bool, seed0: int = SEED0) -> list[dict[str, Any]]:
    """The cases to run: the quick subset first, then (full matrix) the rest round-robin over
    the groups (generator x kind x effect), so that a matrix stopped early has cases on every
    acceptance line and every effect rather than all of the first kinds."""
    first = cases(True, seed0)
    if quick:
        return first
    key = {json.dumps(c, sort_keys=True) for c in first}
    rest = [c for c in cases(False, seed0) if json.dumps(c, sort_keys=True) not in key]
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for c in rest:  # cases() order: by generator, kind, then seed
        groups.setdefault(_group(c), []).append(c)
    out = list(first)
    for i in range(max((len(g) for g in groups.values()), default=0)):
        out.extend(g[i] for g in groups.values() if i < len(g))
    return out


def _truth_value(effects: dict[str, dict[str, float]], name: str) -> tuple[str, float]:
    param = RANGES[name][0]
    return param, effects[name][param]


def _same_case(row: dict[str, Any], case: dict[str, Any]) -> bool:
    """Whether a result row is the planned ``case`` (for --resume and --merge)."""
    return (
        row["seed"] == case["seed"]
        and row.get("gen", "own") == case["gen"]
        and row["truth"] == (case["effects"] or case.get("truth", "none"))
    )


def _logs(case: dict[str, Any], d: Path, **kw: Any) -> list[Path]:
    truth_rover = TRUTH_ROVERS[case["truth"]]() if case.get("truth") in TRUTH_ROVERS else None
    if case["gen"] == "foreign":
        plan = kw.pop("plan", "test")
        return make_foreign_logs(
            d / "logs", case["effects"], truth_rover=truth_rover, plan=plan, progress=False, **kw
        )
    return make_logs(d / "logs", case["effects"], truth_rover=truth_rover, progress=False, **kw)


def run_case(case: dict[str, Any], root: Path, workers: int = 1) -> dict[str, Any]:
    eff = case["effects"]
    tag = case["kind"] + "_" + ("+".join(eff) or case.get("truth", "none").replace(" ", ""))
    d = root / f"{case['gen']}_{tag}_{case['seed']}"
    opts = Options(progress=False, workers=workers)
    t0 = time.perf_counter()
    paths = _logs(case, d, drives=3, seed=case["seed"])
    t1 = time.perf_counter()
    res = diagnose([str(p) for p in paths], d / "out", opts)
    t2 = time.perf_counter()
    followed = None
    tie = res.get("tie")
    asked = [e for e in res.get("evidence", []) if e["separates"]]
    plan = None
    if tie and any(e in tie["effects"] for e in eff):
        plan = tie["plan"]
    elif asked:  # the drive the report asks for, as a test engineer would drive it next
        plan = asked[0]["plan"]
    if plan is not None:
        extra = _logs(case, d, drives=1, seed=case["seed"] + 1000, plan=plan, first_index=3)
        followed = diagnose([str(p) for p in [*paths, *extra]], d / "out_followup", opts)
    t3 = time.perf_counter()
    final = followed or res
    row: dict[str, Any] = {
        "case": tag,
        "gen": case["gen"],
        "kind": case["kind"],
        "seed": case["seed"],
        "truth": eff or case.get("truth", "none"),
        "named": final["named"],
        "tie": tie["effects"] if tie else None,
        "followup_plan": plan if followed else None,
        "first_named": res["named"],
        "main_signal": final["main_signal"],
        "main_reduction": final["main_reduction"],
        "main_gap_reduction": final.get("main_gap_reduction"),
        "unexplained": final["unexplained"],
        "evidence": [
            {k: e[k] for k in ("effect", "plan", "reason", "best_signal", "best_floor_units")}
            for e in res.get("evidence", [])
        ],
        "make_logs_s": t1 - t0,
        "diagnose_s": t2 - t1,
        "followup_s": t3 - t2,
        "fits": {},
    }
    for name in eff:
        if name == "combined_slip":
            continue
        param, truth = _truth_value(eff, name)
        side = "deg" if name == "slope" else ("+" if truth > 0 else "-")
        single = final["fits"].get(name, {})
        thr = (single.get("threshold") or {}).get(side)
        for src in (final["final"], final["fits"]):
            for key, f in src.items():
                if name in key.split(" + ") and name in f["params"] and name not in row["fits"]:
                    v, lo, hi = f["params"][name][param]
                    row["fits"][name] = {
                        "truth": truth,
                        "value": v,
                        "lo": lo,
                        "hi": hi,
                        "side": (f.get("sides") or {}).get(name, {}).get(param, ""),
                        "threshold": thr,
                    }
    return row


def magnitude(name: str, truth: float) -> float:
    """The truth in the variable diagnose fits and states its noise threshold in: the
    parameter's size, but 1e6 / k_phi for the loose soil (fitted as u = 1/k_phi, 0 next to
    hard ground: a stiffer soil is a smaller effect)."""
    if name == "loose_soil":
        return 1e6 / truth
    return abs(truth)


def _above(r: dict[str, Any], name: str) -> bool:
    """Whether the case's ``name`` is at least twice the noise threshold diagnose reported."""
    f = r["fits"].get(name)
    if name == "combined_slip":
        return True
    if f is None or not f.get("threshold"):
        return False
    return bool(magnitude(name, f["truth"]) >= 2 * f["threshold"])


def _bins(rows: list[dict[str, Any]], name: str) -> list[str]:
    """Detection curve of one effect: named rate, fitted/true, coverage by magnitude/threshold."""
    pts = []
    for r in rows:
        f = r["fits"].get(name)
        if f is None or not f.get("threshold"):
            continue
        pts.append((magnitude(name, f["truth"]) / f["threshold"], r, f))
    if not pts:
        return []
    out = []
    for lo, hi in ((0, 1), (1, 2), (2, 4), (4, math.inf)):
        sel = [(x, r, f) for x, r, f in pts if lo <= x < hi]
        if not sel:
            continue
        named = sum(name in r["named"] for _, r, _ in sel)
        ratio = [f["value"] / f["truth"] for _, r, f in sel if name in r["named"]]
        cov = sum(covers(f) for _, r, f in sel if name in r["named"])
        label = f"{lo:g}–{hi:g}" if math.isfinite(hi) else f"≥ {lo:g}"
        out.append(
            f"| {name} | {label} | {named}/{len(sel)} |"
            f" {f'{np.median(ratio):.2f}' if ratio else '—'} | {cov}/{len(ratio)} |"
            f" {np.median([f['threshold'] for _, _, f in sel]):.3g} |"
        )
    return out


def covers(f: dict[str, Any]) -> bool:
    lo = f["lo"] if f["lo"] is not None else -math.inf
    hi = f["hi"] if f["hi"] is not None else math.inf
    return bool(lo <= f["truth"] <= hi)


def _acceptance(rows: list[dict[str, Any]], gen: str) -> list[str]:
    def share(xs: list[bool]) -> str:
        return f"{sum(xs)}/{len(xs)}" if xs else "–"

    g = [r for r in rows if r.get("gen", "own") == gen and "error" not in r]
    single = [r for r in g if r["kind"] == "single"]
    above, cov, below = [], [], []
    for r in single:
        (name,) = r["truth"]
        if name == "combined_slip":
            above.append(name in r["named"])
            continue
        f = r["fits"].get(name)
        if f is None or not f.get("threshold"):
            continue
        ok = name in r["named"]
        if magnitude(name, f["truth"]) >= 2 * f["threshold"]:
            above.append(ok)
            if ok:
                cov.append(covers(f))
        else:
            below.append(ok)
    wrong = [bool(set(r["named"]) - set(r["truth"])) for r in single]
    clean = [not r["named"] for r in g if r["kind"] == "clean"]
    pairs = [all(e in r["named"] for e in r["truth"]) for r in g if r["kind"] == "pair"]
    # Pairs both of whose effects reach 2 x their threshold: the acceptance's population.
    pairs_above = [
        all(e in r["named"] for e in r["truth"])
        for r in g
        if r["kind"] == "pair" and all(_above(r, e) for e in r["truth"])
    ]
    # Each effect of a pair named, its 95 % interval (from the pair's fit) against the truth.
    pair_cov = [
        covers(r["fits"][e])
        for r in g
        if r["kind"] == "pair"
        for e in r["truth"]
        if e in r["named"] and e in r["fits"]
    ]
    outside = [not r["named"] and bool(r["unexplained"]) for r in g if r["kind"] == "outside"]
    secs = [r["diagnose_s"] + r["followup_s"] for r in g]
    logs_s = [r["make_logs_s"] for r in g]
    return [
        f"### Generator `{gen}` ({len(g)} cases)",
        "",
        f"- Single effect, magnitude ≥ 2 × its noise threshold: named right {share(above)};"
        f" 95 % interval covering the truth {share(cov)} (of those named)",
        f"- Single effect below 2 × threshold: named {share(below)}",
        f"- Single effect: another effect named besides or instead {share(wrong)}",
        f"- Clean: nothing named {share(clean)}",
        f"- Pairs: both named {share(pairs)}; of those whose effects are both ≥ 2 × their"
        f" threshold {share(pairs_above)}; named effects' 95 % intervals covering the truth"
        f" {share(pair_cov)}",
        "- Outside the catalogue (passes only when nothing is named and a gap is reported):"
        f" {share(outside)}",
        f"- Seconds per case: diagnose median {np.median(secs) if secs else float('nan'):.0f} s,"
        f" mean {np.mean(secs) if secs else float('nan'):.0f} s"
        f" (min {min(secs, default=float('nan')):.0f}, max {max(secs, default=float('nan')):.0f}),"
        f" logs {np.mean(logs_s) if logs_s else float('nan'):.0f} s",
        "",
    ]


def summarise(rows: list[dict[str, Any]], total_s: float, quick: bool, planned_n: int) -> str:
    weak = [all(e in r["named"] for e in r["truth"]) for r in rows if r["kind"] == "weak"]
    L = [
        "# Random-magnitude matrix of `rover-env diagnose`",
        "",
        f"Run by `benchmarks/bench_diagnose.py{' --quick' if quick else ''}`: each case 3 drives of"
        " 50 s (2 training, 1 held out) with hidden effects at drawn magnitudes (`RANGES`);"
        " `diagnose` sees only the logs. Generators: `own` (make-logs) and `foreign`"
        " (`rover_env.generators.foreign_logs`, a deliberately different implementation)."
        f" {len(rows)} of the {planned_n} planned cases run (the full matrix has"
        f" {len(cases(False))}); {total_s / 60:.1f} min summed over cases.",
        "",
        "## Acceptance figures",
        "",
    ]
    for gen in ("own", "foreign"):
        L += _acceptance(rows, gen)
    L += [f"- Weak fixed-magnitude cases of issue 8: named {sum(weak)}/{len(weak)}", ""]
    L += [
        "## Detection curves (single-effect cases, both generators)",
        "",
        "Magnitude over the effect's noise threshold (the magnitude at which it moves its most"
        " sensitive signal by one replay floor on those drives, reported by diagnose).",
        "",
        "| effect | magnitude / threshold | named | fitted / true (median) | 95 % covers | threshold |",
        "|---|---|---|---|---|---|",
    ]
    singles = [r for r in rows if r["kind"] == "single" and "error" not in r]
    for name in RANGES:
        L += _bins(singles, name)
    L += [
        "",
        "## Cases",
        "",
        "| gen | case | seed | truth | named | fitted (95 %) | threshold | unexplained after | evidence asked | diagnose s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        fits = "; ".join(
            (
                f"{n}: < {f['hi']:.3g}"
                if f.get("side") == "upper"
                else f"{n}: {f['value']:.3g} [{f['lo']:.3g}, {f['hi']:.3g}]"
            )
            for n, f in r["fits"].items()
            if f["value"] is not None and f["lo"] is not None and f["hi"] is not None
        )
        thr = "; ".join(
            f"{n} {f['threshold']:.3g}" for n, f in r["fits"].items() if f.get("threshold")
        )
        truth = json.dumps(r["truth"]) if isinstance(r["truth"], dict) else r["truth"]
        ev = "; ".join(
            e.get("plan", "") + f" ({e.get('effect', '')})" for e in r.get("evidence", [])
        )
        L.append(
            f"| {r.get('gen', 'own')} | {r['case']} | {r['seed']} | {truth} |"
            f" {', '.join(r['named']) or '—'} | {fits} | {thr} | {', '.join(r['unexplained']) or '—'} |"
            f" {ev or '—'} | {r['diagnose_s'] + r['followup_s']:.0f} |"
            + (f" error: {r['error']}" if "error" in r else "")
        )
    return "\n".join(L) + "\n"


def case_row(shared: tuple[Path, int], c: dict[str, Any]) -> dict[str, Any]:
    """``run_case``, or a row recording its error: one broken case must not stop the matrix."""
    root, workers = shared
    try:
        return run_case(c, root, workers=workers)
    except Exception as exc:  # record and go on: one broken case must not stop the matrix
        return {
            "case": "+".join(c["effects"]) or c.get("truth", "none"),
            "gen": c["gen"],
            "kind": c["kind"],
            "seed": c["seed"],
            "truth": c["effects"] or c.get("truth", "none"),
            "named": [],
            "tie": None,
            "followup_plan": None,
            "first_named": [],
            "main_signal": "error",
            "main_reduction": 0.0,
            "unexplained": [],
            "make_logs_s": 0.0,
            "diagnose_s": 0.0,
            "followup_s": 0.0,
            "fits": {},
            "error": f"{type(exc).__name__}: {exc}",
        }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--work", default="out/bench_diagnose")
    ap.add_argument("--out", default="docs/calibration")
    ap.add_argument("--only", default=None, help="run cases whose tag contains this text")
    ap.add_argument("--resume", action="store_true", help="keep the cases in OUT/matrix.json")
    ap.add_argument(
        "--shard",
        default=None,
        help="K/N: run every N-th planned case starting at K (one process per core), rows to"
        " OUT/matrix_shard_K.json; --merge then writes matrix.md from all shards",
    )
    ap.add_argument("--merge", action="store_true", help="combine OUT/matrix_shard_*.json")
    ap.add_argument(
        "--seed0",
        type=int,
        default=SEED0,
        help=f"first case seed (default {SEED0}); another value draws a fresh set of cases,"
        " e.g. for a generator whose earlier cases were looked at while building diagnose",
    )
    ap.add_argument("--workers", type=int, default=1, help="diagnose's worker processes per case")
    ap.add_argument(
        "--case-workers",
        type=int,
        default=1,
        help="cases side by side through the executor (default 1: this process)",
    )
    add_executor_args(ap)
    args = ap.parse_args()
    if args.merge:
        return merge(Path(args.out), args.quick, args.seed0)
    shard_k, shard_n = 0, 1
    if args.shard:
        try:
            shard_k, shard_n = (int(x) for x in args.shard.split("/"))
        except ValueError:
            ap.error(f"--shard {args.shard!r}: expected K/N with integers, e.g. 0/2")
        if not 0 <= shard_k < shard_n:
            ap.error(f"--shard {args.shard!r}: need 0 <= K < N")
    json_name = f"matrix_shard_{shard_k}.json" if args.shard else "matrix.json"
    root = Path(args.work)
    rows: list[dict[str, Any]] = []
    if args.resume and (Path(args.out) / json_name).is_file():
        rows = json.loads((Path(args.out) / json_name).read_text())
    t_prev = sum(r["make_logs_s"] + r["diagnose_s"] + r["followup_s"] for r in rows)
    t0 = time.perf_counter() - t_prev
    todo = planned(args.quick, args.seed0)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    mine = [
        c
        for i, c in enumerate(todo, 1)
        if (i - 1) % shard_n == shard_k
        and not (args.only and args.only not in json.dumps(c))
        and not any(_same_case(r, c) for r in rows)  # --resume: done already
    ]
    rank = {json.dumps(c, sort_keys=True): i for i, c in enumerate(todo)}

    def finished(key: str, row: dict[str, Any]) -> None:
        from tqdm import tqdm

        rows.append(row)
        rows.sort(key=lambda r: next((i for i, c in enumerate(todo) if _same_case(r, c)), 0))
        tqdm.write(
            f"[{rank[key] + 1}/{len(todo)} {time.perf_counter() - t0:6.0f}s] {row['case']} seed"
            f" {row['seed']}: named {row['named'] or 'nothing'}, tie {row['tie']},"
            f" {row['diagnose_s']:.0f}s"
        )
        total = time.perf_counter() - t0
        (out / json_name).write_text(json.dumps(rows, indent=1, default=finite))
        if not args.shard:
            write_report(out / "matrix.md", summarise(rows, total, args.quick, len(todo)))

    with make_executor(args.executor, args.case_workers, args.ray_address) as ex:
        run_study(
            ex,
            case_row,
            mine,
            [json.dumps(c, sort_keys=True) for c in mine],
            shared=(root, args.workers),
            desc="matrix",
            unit="case",
            done_before=len(rows),
            on_result=finished,
        )
    return 0


def merge(out: Path, quick: bool, seed0: int = SEED0) -> int:
    """matrix.json and matrix.md from the shards' rows, in the planned order."""
    rows: list[dict[str, Any]] = []
    for f in sorted(out.glob("matrix_shard_*.json")):
        rows.extend(json.loads(f.read_text()))
    if not rows:
        raise SystemExit(f"--merge: no matrix_shard_*.json in {out}")
    todo = planned(quick, seed0)

    def rank(r: dict[str, Any]) -> int:
        return next((i for i, c in enumerate(todo) if _same_case(r, c)), len(todo))

    rows.sort(key=rank)
    # Shards ran side by side, so this sum is CPU time, not the matrix's wall time.
    total = sum(r["make_logs_s"] + r["diagnose_s"] + r["followup_s"] for r in rows)
    (out / "matrix.json").write_text(json.dumps(rows, indent=1, default=finite))
    write_report(out / "matrix.md", summarise(rows, total, quick, len(todo)))
    print(f"merged {len(rows)} cases into {out / 'matrix.md'}")
    return 0


def finite(x: Any) -> Any:
    v = float(x)
    return v if math.isfinite(v) else None


if __name__ == "__main__":
    raise SystemExit(main())
