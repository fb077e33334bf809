"""Rules registered before a block scores them (docs/calibration/method.md): each reads what
a case's ``result.json`` stored, so a block run with the code that registered it scores it
without a rerun. Stop 57's rotor rule is not applied by ``diagnose`` (stop 62's rotor test
is, and :func:`rotor_test_line` scores it); the evidence rule is, since
stop 59 (``Options.strong_bic``), and on rows of that code lists only what the cap on
drives (``Options.evidence``) left without one."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rover_env.calibration.diagnosis.state import Options

STRONG_BIC = -6.0
"""Training ΔBIC at or below which the evidence is "strong" (Kass & Raftery's scale)."""


def rotor_rule(row: dict[str, Any]) -> bool | None:
    """Stop 57: a named torque limit is withdrawn when the rotor inertia alone has a training
    dBIC at or below the torque limit's. None where no torque limit was named."""
    alt = row.get("rotor_alternative")
    if not alt or "torque_limit" not in row["named"]:
        return None
    return bool(alt["rotor"]["d_bic"] <= alt["torque_limit"]["d_bic"])


def rotor_line(rows: list[dict[str, Any]]) -> str:
    """What the registered rotor rule would do, per kind of case."""
    unrecorded = sum("torque_limit" in r["named"] and not r.get("rotor_alternative") for r in rows)
    parts = []
    for kind, label in (("clean", "clean"), ("single", "singles"), ("pair", "pairs")):
        got = [rotor_rule(r) for r in rows if r["kind"] == kind]
        judged = [g for g in got if g is not None]
        truth = [r for r in rows if r["kind"] == kind and "torque_limit" in r.get("truth", {})]
        parts.append(
            f"{label} {sum(judged)} of {len(judged)} named (true torque cuts among them:"
            f" {sum(rotor_rule(r) is not None for r in truth)})"
        )
    return (
        "- Registered rotor rule (stop 57, not applied): a named torque limit withdrawn in "
        + "; ".join(parts)
        + f"; torque limits named by code before stop 57 (no comparison stored): {unrecorded}"
    )


def rotor_test_line(rows: list[dict[str, Any]]) -> str:
    """Stop 62's rotor test as ``diagnose`` applied it (``Options.rotor_alpha``): the cases
    where it withdrew a torque limit, on the first diagnosis or the final one, against the
    truth, and the torque limits that stood it."""
    stored = [r for r in rows if "rotor_withdrawn" in r]

    def tally(got: list[dict[str, Any]]) -> str:
        true = sum("torque_limit" in (r.get("truth") or {}) for r in got)
        other = sum(r["kind"] in ("clean", "outside") for r in got)
        return f"{len(got)} (true torque cuts {true}; clean or outside {other})"

    withdrawn = [r for r in stored if any(r["rotor_withdrawn"])]
    kept = [r for r in stored if "torque_limit" in r["named"]]
    partner = [r for r in withdrawn if any((w or {}).get("kept") for w in r["rotor_withdrawn"])]
    partner_right = sum(  # a clean build's truth is not a dict of effects
        isinstance(r.get("truth"), dict)
        and any((w or {}).get("kept") in r["truth"] for w in r["rotor_withdrawn"])
        for r in partner
    )
    return (
        f"- Rotor test (stop 62, applied), in {len(stored)} cases that stored it: a torque limit"
        f" withdrawn in {tally(withdrawn)}; its partner named alone (stop 63) in {len(partner)}"
        f" ({partner_right} the truth); a torque limit named in the end in {tally(kept)}"
    )


def strong_unconfirmed(first: dict[str, Any]) -> list[str]:
    """Stop 58: the candidates of a first diagnosis (its ``result.json``) that the rule would
    give an evidence drive: not named and not already given one, training ΔBIC at or below
    :data:`STRONG_BIC`, the held-out drive better but the window test not passed. Why: a
    torque cut of -0.66 (case 47603) fitted -0.742 with ΔBIC -6.7 and held-out 8.5 % better
    at p 0.3 got neither a name nor a drive, since its held-out drive excites the limit."""
    named = set(first.get("named", []))
    have = {e.get("effect") for e in first.get("evidence", [])}
    return sorted(
        name
        for name, f in first.get("fits", {}).items()
        if name not in named | have
        and not f.get("significant")
        and f.get("d_bic") is not None
        and f["d_bic"] <= STRONG_BIC
        and (f.get("held_gain") or 0.0) > 0.0
    )


def evidence_line(rows: list[dict[str, Any]]) -> str:
    """What the registered evidence rule would add, and how often the truth is among it."""
    got = [r for r in rows if r.get("strong_unconfirmed")]
    truth = [
        r
        for r in got
        if isinstance(r.get("truth"), dict) and set(r["truth"]) & set(r["strong_unconfirmed"])
    ]
    clean = [r for r in got if r["kind"] == "clean"]
    stored = sum("strong_unconfirmed" in r for r in rows)
    return (
        "- Evidence rule (registered stop 58, applied since stop 59): a drive for a strong but"
        f" unconfirmed candidate left without one in {len(got)} of {stored} cases that stored it (the true"
        f" effect among them in {len(truth)}; clean cases {len(clean)})"
    )


def untested_torque(first: dict[str, Any], resolution: float = 0.05) -> list[dict[str, Any]]:
    """Stop 59's untested-limit drive (``diagnose``'s ``untested``) as a first diagnosis of
    older code would have got it, from its ``result.json``: no torque limit named or given
    an evidence drive, and its cut threshold beyond ``resolution``
    (``Options.limit_resolution``). Without the simulation: effect, plan and reason only."""
    named = set(first.get("named", []))
    asked = {e.get("effect") for e in first.get("evidence", [])}
    tl = first.get("fits", {}).get("torque_limit")
    if tl is None or "torque_limit" in named | asked:
        return []
    thr = (tl.get("threshold") or {}).get("-")
    if thr is not None and thr <= resolution:
        return []
    seen = "no cut" if thr is None else f"only cuts beyond {100 * thr:.0f} %"
    return [{"effect": "torque_limit", "plan": "accel", "reason": f"{seen} (backfilled)"}]


TRADE_SHARE = 0.1
"""Stop 61's rule (``Options.trade_share``): a trade refuses a naming only at this share."""


def trades(result: dict[str, Any]) -> dict[str, Any]:
    """What the trade test did in a diagnosis (its ``result.json``): ``excused``, the effects
    named despite a small trade, and ``refused``, those left unnamed, each with the worsened
    signals' RMS ratio and share (no share on rows of code before stop 61)."""

    def brief(t: dict[str, Any] | None) -> dict[str, Any] | None:
        if not t:
            return None
        worse = {
            k: {"rms_ratio": v.get("rms_ratio"), "share": v.get("share")}
            for k, v in t["worse"].items()
        }
        return {"effects": t["effects"], "worse": worse}

    return {
        "excused": brief(result.get("trade_excused")),
        "refused": brief(result.get("not_named")),
    }


def trade_line(rows: list[dict[str, Any]]) -> str:
    """How often the trade test refused a naming and how often stop 61's share excused one,
    and whether the effect there was the truth."""

    def effects(t: dict[str, Any]) -> set[str]:
        e = t["effects"]
        return set(e) if isinstance(e, list) else set(e.split(" + "))

    def tally(key: str) -> str:
        got = [r for r in rows if (r.get("trades") or {}).get(key)]
        true = [r for r in got if effects(r["trades"][key]) & set(r.get("truth") or {})]
        other = sum(r["kind"] in ("clean", "outside") for r in got)
        return f"{len(got)} (the truth among its effects in {len(true)}; clean or outside {other})"

    stored = sum("trades" in r for r in rows)
    return (
        f"- Trade test, in {stored} cases that stored it: a naming refused in {tally('refused')};"
        f" a trade under {TRADE_SHARE:g} of what the rest gained excused (named) in"
        f" {tally('excused')}"
    )


def below_limit(result: dict[str, Any]) -> list[str]:
    """The candidates stop 73's detection-limit rule (``Options.name_above_limit``) refused
    to name in a diagnosis (its ``result.json``): their test says so."""
    fits = result.get("fits") or {}
    return sorted(
        k for k, f in fits.items() if "below its detection limit" in (f.get("test") or "")
    )


def limit_line(rows: list[dict[str, Any]]) -> str:
    """What the detection-limit rule refused, per case (first diagnosis or follow-up): the
    case's truth (a cost) or another effect (what it was for)."""
    got = [(r, e) for r in rows for e in r.get("below_limit") or []]
    truth = sum(e in (r.get("truth") or {}) for r, e in got)
    stored = sum("below_limit" in r for r in rows)
    return (
        f"- Detection-limit rule, in {stored} cases that stored it: {len(got)} effects refused"
        f" in {len({r['case'] for r, _ in got})} cases; the case's truth {truth}, another"
        f" effect {len(got) - truth}"
    )


def odometry(result: dict[str, Any]) -> dict[str, Any] | None:
    """Diagnose's odometry stage in a diagnosis (stop 75): whether it named a rolling
    radius, the difference it read (both free wheels) and its fit; None before it."""
    dr = result.get("dead_reckoning")
    if not dr or "band" not in dr:  # stop 74 reported it without a decision
        return None
    diff = dr.get("difference") or {}
    return {
        "form": dr.get("form", "intervals"),
        "named": bool(dr.get("named")),
        "difference": diff.get("both"),
        "split": (
            diff["3L"] - diff["3R"]
            if diff.get("3L") is not None and diff.get("3R") is not None
            else None  # NaN is written as null: nothing read
        ),
        "driven": diff.get("driven"),
        "fraction": dr.get("fraction"),
        "why_not": dr.get("why_not"),
        "after_withdrawn": dr.get("after_withdrawn"),
    }


def odometry_line(rows: list[dict[str, Any]]) -> str:
    """Where the odometry stage named a rolling radius in the final diagnosis: the truth
    a radius (its interval holding it) or not."""
    got = [r for r in rows if (r.get("odometry") or {}).get("named")]
    radius = [r for r in got if "rolling_radius" in (r.get("truth") or {})]
    held = 0
    for r in radius:
        _, lo, hi = r["odometry"]["fraction"]
        held += lo <= r["fits"]["rolling_radius"]["truth"] <= hi
    stored = sum("odometry" in r for r in rows)
    return (
        f"- Odometry (stop 75), in {stored} cases that stored it: a rolling radius named by"
        f" dead reckoning in {len(got)}; the truth a radius in {len(radius)} (interval holding"
        f" it {held}); no radius in the truth {len(got) - len(radius)}"
        + (f" ({', '.join(r['case'] for r in got if r not in radius)})" if got != radius else "")
    )


def allowance_line(rows: list[dict[str, Any]]) -> str:
    """What the clean-fit allowance withdrew (stop 77, ``Options.name_beyond_allowance``),
    first diagnosis or follow-up: the case's truth (a cost) or another effect (what it is
    for)."""
    got = {
        (r["case"], e)
        for r in rows
        for w in r.get("allowance_withdrawn") or []
        for e in (w or {}).get("effects", [])
    }
    truths = {r["case"]: r.get("truth") for r in rows if r.get("allowance_withdrawn")}
    truth = sum(isinstance(truths[c], dict) and e in truths[c] for c, e in got)
    stored = sum("allowance_withdrawn" in r for r in rows)
    line = (
        f"- Clean-fit allowance as a naming condition, in {stored} cases that stored it:"
        f" {len(got)} names withdrawn in {len({c for c, _ in got})} cases; the case's truth"
        f" {truth}, another effect {len(got) - truth}"
    )
    return line + _partner_clause(rows)


def _partner_clause(rows: list[dict[str, Any]]) -> str:
    """A pair that lost one effect to the allowance (stop 78): its other effect named by its
    own fit (``kept``) or not named (``beside``), each against the case's truth; final
    diagnosis only, where the names are."""
    out: dict[str, list[bool]] = {"kept": [], "beside": []}
    for r in rows:
        w = (r.get("allowance_withdrawn") or [None])[-1] or {}
        truth = r.get("truth")
        kept = [w["kept"]] if w.get("kept") else []
        for key, names in (("kept", kept), ("beside", w.get("beside") or [])):
            out[key] += [isinstance(truth, dict) and e in truth for e in names]
    if not (out["kept"] or out["beside"]):
        return ""
    return "; a pair's other effect " + ", ".join(
        f"{key} {len(v)} (the truth {sum(v)})" for key, v in out.items()
    )


def named_fits(final: dict[str, Any]) -> dict[str, dict[str, list[float]]]:
    """Every named effect's fitted parameters (value, 95 % interval) in the final diagnosis,
    truth or not: what a false alarm claimed, for the clean and outside tables."""
    out: dict[str, dict[str, list[float]]] = {}
    for key, f in final.get("final", {}).items():
        for name in key.split(" + "):
            if name in f.get("params", {}):
                out[name] = {k: list(v) for k, v in f["params"][name].items()}
    return out


def backfill(rows: list[dict[str, Any]], work: Path) -> None:
    """Rows of older code lack :func:`named_fits` and the registered rules' inputs: read
    them from the case's result.json under ``work`` where it is still there (rows whose
    files are gone stay without)."""
    for r in rows:
        paths = (
            work / r["case"] / "out" / "result.json",
            work / r["case"] / "out_followup" / "result.json",
        )
        first, fu = (json.loads(p.read_text()) if p.is_file() else None for p in paths)
        last = fu or first
        if first is not None:
            r.setdefault("strong_unconfirmed", strong_unconfirmed(first))
            r.setdefault("untested", untested_torque(first))
            r.setdefault("below_limit", sorted({*below_limit(first), *below_limit(fu or {})}))
        if last is not None:
            r.setdefault("trades", trades(last))
            if odometry(last) is not None:
                r.setdefault("odometry", odometry(last))
            if "named_fits" not in r and r.get("named"):
                r["named_fits"] = named_fits(last)
            for name, f in (r.get("fits") or {}).items():
                raw = raw_interval(last, name)
                if "lo_raw" not in f and raw is not None:
                    f["lo_raw"], f["hi_raw"] = raw
                if "test" not in f and name in last.get("fits", {}):
                    f["test"] = window_test(last["fits"][name])


def raw_interval(result: dict[str, Any], name: str) -> tuple[float, float] | None:
    """A named effect's interval before the clean-fit allowance (stop 74), or None."""
    for key, f in (result.get("final") or {}).items():
        raw = (f.get("params_without_allowance") or {}).get(name)
        if name in key.split(" + ") and raw:
            v = raw["deg"] if name == "slope" else next(iter(raw.values()))
            return v[1], v[2]
    return None


def without_allowance(f: dict[str, Any]) -> dict[str, Any]:
    """A truth fit row (``bench_independent.fits``) with the interval diagnose gave before
    the clean-fit allowance widened it (rows before stop 74: the interval as it is)."""
    return {**f, "lo": f.get("lo_raw", f["lo"]), "hi": f.get("hi_raw", f["hi"])}


def window_test(f: dict[str, Any]) -> dict[str, Any]:
    """What the window test saw of one candidate's single fit (result.json's ``fits``)."""
    return {k: f.get(k) for k in ("significant", "held_gain", "p", "d_bic")}


def why_missed(row: dict[str, Any], name: str) -> str:
    """Why a single's true effect is not among its final names: the clean-fit allowance (it
    withdraws what passed every other rule), else the first reason that holds in the order
    diagnose applies them: the window test (final diagnosis), a tie (the first diagnosis's,
    which proposes the follow-up drive), another effect named; what is left is a later rule
    (trade, rotor test, detection limit) or another effect that won the window test and was
    then withdrawn (a torque limit the rotor test took back, spent case 52106)."""
    opts, test = Options(), (row["fits"].get(name) or {}).get("test") or {}
    last = (row.get("allowance_withdrawn") or [None])[-1] or {}
    if name in last.get("effects", []):
        return "the allowance"
    if not test:
        return "not stored"
    if not test["significant"]:
        if (test["held_gain"] or 0.0) < opts.min_gain:
            return f"held-out gain under {opts.min_gain:.0%}"
        return (
            f"held-out p ≥ {opts.alpha:g}" if (test["p"] or 1.0) >= opts.alpha else "training BIC"
        )
    if name in (row.get("tie") or []):
        return "a tie"
    return "another effect named" if row["named"] else "a later rule or a withdrawn winner"


def missed_line(singles: list[dict[str, Any]], ratio: Callable[..., float | None]) -> str:
    """Why singles whose truth is at least 2 x its threshold (``ratio(name, fit)``, the
    bench's truth over threshold) were not named."""
    strong = [(r, e) for r in singles for e in r["truth"] if (ratio(e, r["fits"].get(e)) or 0) >= 2]
    why = Counter(why_missed(r, e) for r, e in strong if e not in r["named"])
    parts = ", ".join(f"{k} {n}" for k, n in why.most_common()) or "none missed"
    return f"- Singles ≥ 2 × threshold not named, first reason (final diagnosis): {parts}"


def rule_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The registered rules' lines of a block's acceptance figures, in the order they were
    registered."""
    return [
        rotor_line(rows),
        rotor_test_line(rows),
        evidence_line(rows),
        trade_line(rows),
        limit_line(rows),
        odometry_line(rows),
        allowance_line(rows),
    ]
