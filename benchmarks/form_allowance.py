"""What the model's form puts into an effect's fit: the clean-fit allowance (issue 47).

On clean logs of another implementation every candidate's fit still finds something: a
delay of about 16 ms where none was injected, a torque cut, a slope of a degree. That is the
model's form mismatch seen through the effect (the form bias b); on logs that hold the
effect, the fit finds about truth + b, and an interval that holds only the noise misses the
truth whenever b is larger than its width. This script measures b's spread per effect from
the clean cases of ``bench_independent.py`` blocks (every candidate's fit in each clean
case's first diagnosis, ``result.json``) as its 5 % and 95 % quantiles, and asks on other
blocks what an interval for the truth widened by it, [lo - q95, hi - q05] (a slope's tilt
[lo - q95, hi + q95], at least 0), would do: how often it covers the truth of a right name,
and which names it would refuse (the widened interval reaching "off"). It reads stored
results only (no replay). ``--write`` writes the table diagnose widens its intervals by
(:mod:`rover_env.calibration.form_allowance`; the shipped one is
``configs/calibration/form_allowance.yaml``).

    python benchmarks/form_allowance.py --calibrate /tmp/b50800 /tmp/b50900 \\
        --evaluate /tmp/b51500 --out docs/calibration/block51500
    python benchmarks/form_allowance.py --calibrate /tmp/b50800 ... /tmp/b51500 \\
        --write configs/calibration/form_allowance.yaml

A table for another procedure (diagnose run with other options, or on another rover) is
measured on clean drives diagnosed that way: ``--runs`` takes their output folders, and
``--options`` and ``--rover`` record how they were made, which diagnose compares with its own
run (:mod:`rover_env.calibration.diagnosis.procedure`):

    python benchmarks/option_ab.py --option torque-forms --seed0 74064 --torque 0 \\
        --others 0 --clean 20 --work out/clean_forms
    python benchmarks/form_allowance.py --runs out/clean_forms/case_*/on \\
        --options torque_forms=true --write out/clean_forms/allowance.yaml

A block directory is ``bench_independent.py``'s ``--out`` with its ``--work`` under
``work/`` (regenerable: ``bench_independent.py --seed0 SEED``). Writes ``allowance.md`` and
``allowance.png`` to ``--out``.

A soil's stiffness has no clean fit (clean drives fit hard ground): its entry is the spread of
fitted over true k_phi on the named soils of stored blocks (``--soil``, each block's
``independent.json``), a factor diagnose divides the interval by
(:data:`rover_env.calibration.form_allowance.FACTOR`). With ``--soil`` and no
``--calibrate``, ``--write`` keeps the table's other entries:

    python benchmarks/form_allowance.py --soil docs/calibration/block[0-9]* \\
        --write configs/calibration/form_allowance.yaml

An effect that is there is sometimes fitted off the other way than clean drives push it (a
lag fitted short by a few ms, where clean drives only add lag). ``--named`` measures, on
the right names of stored singles (each block's ``independent.json``), how far the truth
sat below and above the name's own interval before any widening (95 % quantiles; effects
with at least ``--min-named`` such names); diagnose pads each side by the larger of that
and the clean spread (:class:`rover_env.calibration.form_allowance.Bias`). Like ``--soil``,
``--named`` alone updates an existing table. ``--evaluate`` with ``--named`` (and
``--calibrate``) reports what the combined pad covers on other blocks' right singles, from
their stored intervals before widening:

    python benchmarks/form_allowance.py --calibrate B1 ... --named B1 ... \\
        --evaluate B9 ... --out out/allowance
"""

from __future__ import annotations

import argparse
import json
import math
import os
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
from _report import write_report

from rover_env.calibration.form_allowance import (
    FACTOR,
    Bias,
    FormAllowance,
    load_allowance,
    widen,
)
from rover_env.config import ConfigError
from rover_env.effects import CATALOGUE

SKIP = {"combined_slip", "loose_soil"}
"""A switch has no size; the soil's fit is a stiffness (its own acceptance line)."""


def clean_fits(blocks: list[Path]) -> dict[str, list[float]]:
    """Every candidate's fitted size on the clean cases of ``blocks`` (effect -> values;
    a slope's tilt in degrees)."""
    return run_fits(
        [p.parent for b in blocks for p in sorted((b / "work").glob("clean_*/out/result.json"))]
    )


def run_fits(runs: list[Path]) -> dict[str, list[float]]:
    """Every candidate's fitted size in the diagnoses written to ``runs`` (``diagnose``'s
    output folders, each with its ``result.json``): effect -> values."""
    out: dict[str, list[float]] = defaultdict(list)
    for run in runs:
        p = run / "result.json"
        if not p.is_file():
            raise SystemExit(f"{run}: no result.json (not a diagnose output folder)")
        for name, f in (json.loads(p.read_text()).get("fits") or {}).items():
            params = (f.get("params") or {}).get(name) or {}
            if name in SKIP or not params:
                continue
            v = params["deg" if name == "slope" else next(iter(params))][0]
            if v is not None:
                out[name].append(float(v))
    return dict(out)


def parse_options(items: list[str]) -> dict[str, Any]:
    """``KEY=VALUE`` pairs (values read as YAML scalars: ``true``, ``4``, ``0.01``) as the
    table's ``options``, checked as diagnose checks a table's."""
    import yaml

    from rover_env.calibration.diagnosis.procedure import check_options

    out: dict[str, Any] = {}
    for item in items:
        key, eq, value = item.partition("=")
        if not eq or not key:
            raise SystemExit(f"--options: expected KEY=VALUE, got {item!r}")
        out[key.replace("-", "_")] = yaml.safe_load(value)
    try:
        check_options(FormAllowance(effects={}, options=out), Path("--options"))
    except ConfigError as e:
        raise SystemExit(str(e)) from None
    return out


def allowance(fits: dict[str, list[float]]) -> dict[str, tuple[float, float, int]]:
    """Per effect (q05, q95, n) of its clean fits."""
    return {
        k: (float(np.quantile(v, 0.05)), float(np.quantile(v, 0.95)), len(v))
        for k, v in sorted(fits.items())
        if v
    }


def soil_ratios(blocks: list[Path]) -> list[float]:
    """Fitted over true k_phi of each case of ``blocks`` (their stored rows) whose truth
    holds loose soil and whose final names include it."""
    out = []
    for b in blocks:
        for r in json.loads((b / "independent.json").read_text()):
            f = (r.get("fits") or {}).get("loose_soil") or {}
            v, t = f.get("value"), f.get("truth")
            if "loose_soil" not in (r.get("named") or []) or v is None or t is None:
                continue
            if 0.0 < v < math.inf and t > 0.0:
                out.append(float(v) / float(t))
    return out


def raw_interval(fit: dict[str, Any]) -> tuple[float, float] | None:
    """A stored fit's 95 % interval before the allowance widened it (``lo_raw``, ``hi_raw``
    stored since block 51600; the blocks before the allowance stored only that one, as ``lo``,
    ``hi``)."""
    lo, hi = (
        (fit.get("lo_raw"), fit.get("hi_raw"))
        if "lo_raw" in fit
        else (fit.get("lo"), fit.get("hi"))
    )
    if lo is None or hi is None:
        return None
    return float(lo), float(hi)


def misses(blocks: list[Path]) -> dict[str, list[tuple[float, float, float, bool]]]:
    """Per effect, (lo - truth, truth - hi, far, up) of each right single name of ``blocks``'
    stored rows: its interval before widening (positive: the truth sat outside), how far
    beyond the fitted value, away from "off", the truth sat (``far``; negative: towards
    "off"), and whether the value sat above "off" (``up``: the far end is the upper one)."""
    out: dict[str, list[tuple[float, float, float, bool]]] = defaultdict(list)
    for b in blocks:
        for r in json.loads((b / "independent.json").read_text()):
            truth = r["truth"] if isinstance(r["truth"], dict) else {}
            if r["kind"] != "single" or len(truth) != 1:
                continue
            (name,) = truth
            f = (r.get("fits") or {}).get(name) or {}
            raw = raw_interval(f)
            if name in SKIP or name not in (r.get("named") or []) or f.get("truth") is None:
                continue
            if raw is None:
                continue
            t = abs(f["truth"]) if name == "slope" else float(f["truth"])
            v, off = float(f["value"]), CATALOGUE[name].params[0].off
            up = v >= off
            out[name].append((raw[0] - t, t - raw[1], (t - v) if up else (v - t), up))
    return dict(out)


def beyond(
    found: dict[str, list[tuple[float, float, float, bool]]], least: int = 10
) -> dict[str, tuple[float, float, int, float]]:
    """Per effect with at least ``least`` right names, (below, above, n, reach): the 95 %
    quantiles of how far the truth sat below and above the name's interval and beyond the
    fitted value away from "off" (each 0 where it never did)."""
    return {
        k: (
            max(0.0, float(np.quantile([m[0] for m in v], 0.95))),
            max(0.0, float(np.quantile([m[1] for m in v], 0.95))),
            len(v),
            max(0.0, float(np.quantile([m[2] for m in v], 0.95))),
        )
        for k, v in sorted(found.items())
        if len(v) >= least
    }


def factor(ratios: list[float]) -> tuple[float, float, int]:
    """(q05, q95, n) of ``ratios``, taken on their logarithms (a factor either way counts
    alike)."""
    logs = np.log(ratios)
    return (
        float(np.exp(np.quantile(logs, 0.05))),
        float(np.exp(np.quantile(logs, 0.95))),
        len(ratios),
    )


def widened(
    name: str,
    lo: float,
    hi: float,
    q: tuple[float, float, int],
    out: tuple[float, float, int, float] = (0.0, 0.0, 0, 0.0),
) -> tuple[float, float]:
    """The interval for the truth with the form bias's spread in it, as diagnose widens it
    (:meth:`rover_env.calibration.form_allowance.FormAllowance.pad`: never narrower); ``out``
    (below, above, n, reach) from :func:`beyond` (its reach is not applied here: that needs
    the fitted value)."""
    q05, q95, n = q
    pad = FormAllowance({name: Bias(q05, q95, n, *out)}).pad(name) or (0.0, 0.0)
    return widen(name, lo, hi, pad, (-math.inf, math.inf))


def named(rows: list[dict[str, Any]], allow: dict[str, tuple[float, float, int]]) -> list[dict]:
    """Each named effect of ``rows`` (final diagnosis) with its stored and widened interval,
    whether it is the truth, and the truth where it is a single's."""
    out = []
    for r in rows:
        truth = r["truth"] if isinstance(r["truth"], dict) else {}
        for name in r.get("named") or []:
            params = (r.get("named_fits") or {}).get(name)
            if name not in allow or not params:
                continue
            v, lo, hi = params["deg" if name == "slope" else next(iter(params))]
            if lo is None or hi is None:
                continue
            wlo, whi = widened(name, lo, hi, allow[name])
            t = (r.get("fits") or {}).get(name, {}).get("truth")
            if t is not None and name == "slope":
                t = abs(t)
            out.append(
                {
                    "case": r["case"],
                    "kind": r["kind"],
                    "effect": name,
                    "right": name in truth,
                    "truth": t if r["kind"] == "single" else None,
                    "fit": (v, lo, hi),
                    "widened": (wlo, whi),
                    "refused": wlo <= 0.0 <= whi,  # a slope's tilt: its lower end at level
                }
            )
    return out


def _label(block: Path) -> str:
    """A block folder's name, with its study's where it sits in one (study71700/plan71700)."""
    return block.name if block.parent.name == "calibration" else "/".join(block.parts[-2:])


def write_table(
    allow: dict[str, tuple[float, float, int]],
    blocks: list[Path],
    soils: list[Path],
    path: Path,
    out: dict[str, tuple[float, float, int, float]] | None = None,
    named_blocks: list[Path] | None = None,
    runs: list[Path] | None = None,
    options: dict[str, Any] | None = None,
    rover: str = "proto_explorer",
) -> None:
    """The allowance as diagnose reads it (:func:`rover_env.calibration.form_allowance.load_allowance`).
    Without ``blocks`` the clean entries and their source are kept from the table at ``path``;
    without ``out`` (from :func:`beyond`, measured on ``named_blocks``) its named-side
    entries too. ``runs``: the clean diagnoses measured instead of blocks' (``--runs``),
    made with ``options`` (those that differ from the defaults) on logs naming ``rover``; the
    table then holds their entries only (and ``soils``' and ``out``'s where given), nothing
    kept from the one at ``path``."""
    import yaml

    source = (
        "benchmarks/form_allowance.py on the independent generator's clean cases of blocks"
        f" {', '.join(b.name for b in blocks)} (first diagnosis of each)"
    )
    # A table of --runs holds what they measured: another procedure's named-side and soil
    # entries are not this one's.
    fresh = runs or not path.exists()
    old = {"effects": {}, "source": ""} if fresh else yaml.safe_load(path.read_text())
    old_named = {
        k: (v["below"], v["above"], v["named"], v.get("reach", 0.0))
        for k, v in old["effects"].items()
        if v.get("named")
    }
    if runs:
        blocks = runs
        source = f"benchmarks/form_allowance.py on {len(runs)} clean diagnoses ({_span(runs)})"
    if not blocks:
        source = old["source"].split("; ")[0]
        kept = {k: v for k, v in old["effects"].items() if k not in FACTOR}
        allow = {k: (v["low"], v["high"], v["cases"]) for k, v in kept.items()} | allow
    if soils:
        source += (
            "; loose_soil: fitted over true k_phi of the named soils of blocks"
            f" {', '.join(b.name for b in soils)}"
        )
    else:  # the soil's factor is measured apart (--soil): kept as it was
        kept = {k: v for k, v in old["effects"].items() if k in FACTOR}
        allow |= {k: (v["low"], v["high"], v["cases"]) for k, v in kept.items()}
        source += "".join(
            f"; {p}" for p in old["source"].split("; ") if p.startswith("loose_soil: ")
        )
    if out is None:
        out = {k: v for k, v in old_named.items() if k in allow}
        kept_source = [p for p in old["source"].split("; ") if p.startswith("below/above: ")]
        source += "".join(f"; {p}" for p in kept_source)
    elif out:
        source += (
            "; below/above: the truth beyond right single names' own intervals in blocks"
            f" {', '.join(_label(b) for b in named_blocks or [])}"
        )
    effects: dict[str, dict[str, float | int]] = {}
    for k, (q05, q95, n) in sorted(allow.items()):
        effects[k] = {"low": round(q05, 6), "high": round(q95, 6), "cases": n}
        if k in out and k not in FACTOR:
            below, above, m, reach = out[k]
            effects[k] |= {"below": round(below, 6), "above": round(above, 6), "named": m}
            effects[k] |= {"reach": round(reach, 6)}
    doc = {
        "description": "Clean-fit allowance: 5 % and 95 % quantiles of each effect's fit on"
        " clean drives (a slope's tilt in degrees); diagnose widens a named effect's interval"
        " for the truth to [lo - high, hi - low]. below/above (where measured): 95 % quantiles"
        " of how far the truth sat beyond right names' own intervals; each side is padded by"
        " the larger. reach (where measured): 95 % quantile of how far beyond the fitted value,"
        " away from off, the truth sat on those names; the far end is at least that far from"
        " the value. loose_soil: quantiles of fitted over true k_phi on named soils, the"
        " interval for the truth [lo / high, hi / low].",
        "source": source,
        # how the clean fits were made: bench_independent.py's blocks with the default
        # options, on logs naming the configuration the independent rover is built to
        "options": options or {},
        "rover": rover,
        "effects": effects,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        "# Written by benchmarks/form_allowance.py --write; regenerate, do not edit.\n"
        + yaml.safe_dump(doc, sort_keys=False, width=100)
    )


def _span(runs: list[Path]) -> str:
    """The runs' folders, shortly: their common folder and how many."""
    common = os.path.commonpath([str(r) for r in runs])
    return f"under {common}" if common not in ("", ".", "/") else ", ".join(map(str, runs))


def table(allow: dict[str, tuple[float, float, int]], got: list[dict]) -> list[str]:
    """The report's lines: the allowance, then coverage and refusals per effect."""
    lines = [
        "| effect | clean fits | q05 | q95 | right singles covering: stored | widened |"
        " right names refused | other names refused |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, (q05, q95, n) in allow.items():
        mine = [g for g in got if g["effect"] == name]
        singles = [g for g in mine if g["right"] and g["truth"] is not None]
        stored = sum(g["fit"][1] <= g["truth"] <= g["fit"][2] for g in singles)
        wide = sum(g["widened"][0] <= g["truth"] <= g["widened"][1] for g in singles)
        right = [g for g in mine if g["right"]]
        other = [g for g in mine if not g["right"]]
        lines.append(
            f"| {name} | {n} | {q05:.3g} | {q95:.3g} | {stored}/{len(singles)} |"
            f" {wide}/{len(singles)} | {sum(g['refused'] for g in right)}/{len(right)} |"
            f" {sum(g['refused'] for g in other)}/{len(other)} |"
        )
    return lines


def clean_or_shipped(
    allow: dict[str, tuple[float, float, int]],
) -> dict[str, tuple[float, float, int]]:
    """``allow``'s clean entries, or the shipped table's where none were calibrated here (the
    blocks in git keep their rows, not their clean cases' diagnoses)."""
    mine = {k: v for k, v in allow.items() if k not in FACTOR}
    if mine:
        return mine
    shipped = load_allowance().effects
    return {k: (b.low, b.high, b.cases) for k, b in shipped.items() if k not in FACTOR}


def beyond_table(
    allow: dict[str, tuple[float, float, int]],
    out: dict[str, tuple[float, float, int, float]],
    found: dict[str, list[tuple[float, float, float, bool]]],
    named_blocks: list[Path],
) -> list[str]:
    """Coverage of the evaluated blocks' right singles (their intervals before widening) by
    the clean pad alone, by the clean pad joined with ``out``'s below / above, and by that
    with the far end's floor (``out``'s reach) too."""
    lines = [
        f"Right single names of the evaluated blocks, their intervals before widening; the"
        f" truth beyond right names' intervals measured on {', '.join(b.name for b in named_blocks)}:",
        "",
        "| effect | named | measured on | below | above | reach | covered: clean pad |"
        " clean pad and beyond | and the reach |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, rows in sorted(found.items()):
        q = allow.get(name)
        if q is None:
            continue
        o = out.get(name, (0.0, 0.0, 0, 0.0))
        clean = FormAllowance({name: Bias(*q)}).pad(name) or (0.0, 0.0)
        both = FormAllowance({name: Bias(*q, *o)}).pad(name) or (0.0, 0.0)
        lines.append(
            f"| {name} | {len(rows)} | {o[2]} | {o[0]:.3g} | {o[1]:.3g} | {o[3]:.3g} |"
            f" {sum(covered(m, clean) for m in rows)}/{len(rows)} |"
            f" {sum(covered(m, both) for m in rows)}/{len(rows)} |"
            f" {sum(covered(m, both, o[3]) for m in rows)}/{len(rows)} |"
        )
    return [*lines, ""]


def covered(
    miss: tuple[float, float, float, bool], pad: tuple[float, float], reach: float = 0.0
) -> bool:
    """Whether the truth of a name (a :func:`misses` row) lies within its interval padded
    by ``pad`` (below, above) with the far end at least ``reach`` beyond the value, as
    :func:`rover_env.calibration.form_allowance.reach_floor` puts it."""
    below, above, far, up = miss
    low_ok = below <= pad[0] or (not up and far <= reach)
    high_ok = above <= pad[1] or (up and far <= reach)
    return low_ok and high_ok


def plot_beyond(
    allow: dict[str, tuple[float, float, int]],
    out: dict[str, tuple[float, float, int, float]],
    found: dict[str, list[tuple[float, float, float, bool]]],
    path: Path,
) -> None:
    """Per effect: how far the evaluated right names' truths sat below and above their own
    intervals (positive: outside), with the clean pad and the combined pad on each side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in sorted(found) if n in allow]
    fig, axes = plt.subplots(1, max(1, len(names)), figsize=(2.4 * max(1, len(names)), 3.2))
    for ax, name in zip(np.atleast_1d(axes), names, strict=False):
        rows = np.array([m[:2] for m in found[name]])
        clean = FormAllowance({name: Bias(*allow[name])}).pad(name) or (0.0, 0.0)
        both = FormAllowance({name: Bias(*allow[name], *out.get(name, (0, 0, 0, 0.0)))}).pad(name)
        for i in (0, 1):  # below, above
            ax.plot(np.full(len(rows), i), rows[:, i], "o", alpha=0.5, color="C3")
            ax.hlines(clean[i], i - 0.3, i + 0.3, color="C0", label="clean pad" if i else None)
            ax.hlines(
                (both or clean)[i],
                i - 0.3,
                i + 0.3,
                color="C2",
                ls="--",
                label="combined" if i else None,
            )
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xticks([0, 1], ["lo - truth", "truth - hi"])
        ax.set_title(name.replace("_", " "), fontsize=8)
    np.atleast_1d(axes)[0].legend(fontsize=6)
    fig.suptitle("Right names: the truth outside their own interval, and the pads")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot(fits: dict[str, list[float]], ratios: list[float], got: list[dict], path: Path) -> None:
    """Per effect: the clean fits (the form bias) beside fitted - truth of right singles; a
    soil's stiffness: fitted over true k_phi, the calibration's soils beside the evaluated."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in fits if n != "load_dependent_friction"] + (["loose_soil"] if ratios else [])
    fig, axes = plt.subplots(1, len(names), figsize=(2.2 * len(names), 3.2), squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        mine = [g for g in got if g["effect"] == name and g["truth"]]
        if name in FACTOR:
            ax.plot(np.zeros(len(ratios)), ratios, "o", alpha=0.4, label="calibration")
            ax.plot(
                np.ones(len(mine)),
                [g["fit"][0] / g["truth"] for g in mine],
                "s",
                alpha=0.6,
                color="C3",
            )
            ax.set_yscale("log")
            ax.axhline(1.0, color="k", lw=0.5)
            ax.set_xticks([0, 1], ["calibration", "named"])
            ax.set_title("loose soil: fit / truth", fontsize=8)
        else:
            ax.plot(np.zeros(len(fits[name])), fits[name], "o", alpha=0.4, label="clean fit")
            ax.plot(
                np.ones(len(mine)),
                [g["fit"][0] - g["truth"] for g in mine],
                "s",
                alpha=0.6,
                color="C3",
                label="fit - truth",
            )
            ax.axhline(0.0, color="k", lw=0.5)
            ax.set_xticks([0, 1], ["clean", "named"])
            ax.set_title(name.replace("_", " "), fontsize=8)
        ax.set_xlim(-0.6, 1.6)
    axes[0][0].legend(fontsize=6)
    fig.suptitle("Form bias: what clean logs fit, and how far right names sit from the truth")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calibrate", nargs="+", type=Path, default=[], help="block dirs (clean fits)")
    ap.add_argument(
        "--runs",
        nargs="+",
        type=Path,
        default=[],
        help="diagnose output folders of clean drives, in place of --calibrate's blocks",
    )
    ap.add_argument(
        "--options",
        nargs="+",
        default=[],
        metavar="KEY=VALUE",
        help="the diagnose options --runs were made with, where not the defaults",
    )
    ap.add_argument("--rover", default="proto_explorer", help="the rover --runs' logs name")
    ap.add_argument(
        "--soil", nargs="+", type=Path, default=[], help="block dirs (named soils' k_phi)"
    )
    ap.add_argument(
        "--named",
        nargs="+",
        type=Path,
        default=[],
        help="block dirs (the truth beyond right names' own intervals)",
    )
    ap.add_argument(
        "--min-named", type=int, default=10, help="right names an effect needs (default 10)"
    )
    ap.add_argument("--evaluate", nargs="+", type=Path, default=[], help="block dirs")
    ap.add_argument("--out", type=Path, help="folder for allowance.md and .png (with --evaluate)")
    ap.add_argument("--write", type=Path, help="write the allowance table diagnose reads")
    a = ap.parse_args()
    if not a.write and not (a.evaluate and a.out):
        ap.error("give --write PATH, or --evaluate BLOCK... with --out DIR")
    if a.runs and a.calibrate:
        ap.error("give --calibrate BLOCK... or --runs DIR..., not both")
    if (a.options or a.rover != "proto_explorer") and not a.runs:
        ap.error("--options and --rover describe --runs")
    if not (a.calibrate or a.runs or a.soil or a.named):
        ap.error("give --calibrate BLOCK..., --runs DIR..., --soil BLOCK..., --named BLOCK...")
    if a.write and not (a.calibrate or a.runs) and not a.write.exists():
        ap.error(
            f"--write {a.write}: --soil or --named alone updates an existing table; give --calibrate"
        )
    options = parse_options(a.options)
    fits = run_fits(a.runs) if a.runs else clean_fits(a.calibrate)
    allow = allowance(fits)
    ratios: list[float] = []
    for flag, given in (("--soil", a.soil), ("--named", a.named), ("--evaluate", a.evaluate)):
        if missing := [str(b) for b in given if not (b / "independent.json").is_file()]:
            ap.error(f"{flag}: no independent.json in {', '.join(missing)}")
    out = beyond(misses(a.named), a.min_named) if a.named else None
    if a.soil:
        ratios = soil_ratios(a.soil)
        if len(ratios) < 10:
            ap.error(f"--soil: {len(ratios)} named soils in those blocks, at least 10 needed")
        allow["loose_soil"] = factor(ratios)
    if a.write:
        write_table(allow, a.calibrate, a.soil, a.write, out, a.named, a.runs, options, a.rover)
        print(f"wrote {a.write}; below/above measured for: {', '.join(out or {}) or 'none'}")
    if not a.evaluate:
        return
    rows = [r for b in a.evaluate for r in json.loads((b / "independent.json").read_text())]
    got = named(rows, allow)
    a.out.mkdir(parents=True, exist_ok=True)
    text = [
        "# Clean-fit allowance (benchmarks/form_allowance.py)",
        "",
        f"Calibrated on the clean cases of {', '.join(b.name for b in a.calibrate) or 'none'};"
        f" evaluated on the named effects of {', '.join(b.name for b in a.evaluate)}."
        " Blocks diagnosed since stop 74 store intervals already widened by the shipped table.",
        "",
        *([*table(allow, got), ""] if allow else []),
        *(beyond_table(clean_or_shipped(allow), out, misses(a.evaluate), a.named) if out else []),
        *(["![beyond](beyond.png)", ""] if out else []),
        *(["![form bias](allowance.png)", ""] if fits or ratios else []),
    ]
    write_report(a.out / "allowance.md", "\n".join(text))
    if fits or ratios:
        plot(fits, ratios, got, a.out / "allowance.png")
    if out:
        plot_beyond(clean_or_shipped(allow), out, misses(a.evaluate), a.out / "beyond.png")
    print("\n".join(text))


if __name__ == "__main__":
    main()
