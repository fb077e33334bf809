"""``rover-env diagnose`` on fewer drives than the acceptance matrix gives it (issue 47): one
or two logs of a rover, as a user with a short field day has, on the independent generator.

Each case of ``bench_independent.py``'s plan (the same seeds, effects and builds) is driven
``--drives`` times (50 s each; the last held out, or with one drive its odd windows) and
diagnosed once, first diagnosis only (no follow-up drive). Where the diagnosis judged a
second effect beside its winner (``partner_limits`` in ``result.json``, the second effect's
detection limit beside the winner, :func:`rover_env.calibration.diagnosis.select.partner_limits`),
the case is diagnosed again with ``--no-partner-limit``, so each row holds what the rule
named and what the code without it names (elsewhere the two are the same run: the rule
acts only there). Rows go to ``--out`` as JSON lines, one per case, resumable; ``--report``
writes the summary table.

    python benchmarks/few_drives.py --seed0 71000 --drives 2 --out /tmp/few/rows.jsonl \\
        --work /tmp/few/work --workers 2
    python benchmarks/few_drives.py --report /tmp/few/rows.jsonl --md /tmp/few/few.md

``--rule odometry_noise`` (study 71200) scores odometry's band widened for the pose's own
noise instead (:attr:`rover_env.calibration.diagnosis.state.OdometryBand.noise_z`): one
diagnosis per case, whose ``dead_reckoning`` also records what the clean band alone decided
(``without_noise``), so the names without the rule are the same run's with that decision.
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path
from typing import Any

from _independent_plan import DURATION, planned, tag

from rover_env.calibration.diagnose import diagnose
from rover_env.calibration.diagnosis.state import Options
from rover_env.independent import make_independent_logs


def truth_names(case: dict[str, Any]) -> set[str]:
    """The catalogue effects a diagnosis of ``case`` may name (none: clean or outside)."""
    return set(case["truth"]) if isinstance(case["truth"], dict) else set()


RULES = ("partner_limit", "odometry_noise")
"""The rules this script scores: study 71000's and study 71200's."""


def without_noise(named: list[str], dr: dict[str, Any] | None) -> list[str]:
    """The names a diagnosis would have given with odometry's clean band alone: the same
    run's names with the rolling radius as that band decided (``dr``: its dead reckoning)."""
    if not dr or "without_noise" not in dr:
        return list(named)
    rest = [n for n in named if n != "rolling_radius" or not dr.get("named")]
    return rest + (["rolling_radius"] if dr["without_noise"] == "named" else [])


def odometry_row(dr: dict[str, Any] | None) -> dict[str, Any] | None:
    """What a case's dead reckoning read and decided, for the rows."""
    if not dr:
        return None
    keys = ("named", "without_noise", "why_not", "noise_se", "noise_samples", "band_with_noise")
    keys += ("fraction", "sensitivity", "interval_with_noise")
    return {"difference": (dr.get("difference") or {}).get("both")} | {k: dr.get(k) for k in keys}


def run_case(
    case: dict[str, Any], root: Path, drives: int, workers: int, rule: str = "partner_limit"
) -> dict[str, Any]:
    """One case: its logs, the diagnosis with the rule, and without it where it acted."""
    d = root / tag(case)
    if d.exists():
        shutil.rmtree(d)
    t0 = time.perf_counter()
    paths = [
        str(p)
        for p in make_independent_logs(
            d / "logs", case["effects"], drives=drives, seed=case["seed"], duration=DURATION
        )
    ]
    t1 = time.perf_counter()
    opts = Options(progress=False, workers=workers, partner_limit=rule == "partner_limit")
    on = diagnose(paths, d / "out", opts)
    t2 = time.perf_counter()
    if rule == "odometry_noise":
        off = {"named": without_noise(on["named"], on.get("dead_reckoning"))}
        acted = sorted(off["named"]) != sorted(on["named"])
    else:
        acted = on.get("partner_limits") is not None
        off = (
            diagnose(
                paths, d / "out_off", Options(progress=False, workers=workers, partner_limit=False)
            )
            if acted
            else on
        )
    pairs = {
        k: {"significant": bool(v.get("significant")), "test": v.get("test", "")}
        for k, v in (on.get("second_tried") or {}).items()
    }
    return {
        "case": tag(case),
        "kind": case["kind"],
        "seed": case["seed"],
        "effects": case["effects"],
        "truth": case["truth"],
        "drives": drives,
        "named": on["named"],
        "named_off": off["named"],
        "acted": acted,
        "partner_limits": on.get("partner_limits"),
        "pairs": pairs,
        **(
            {"rule": rule, "odometry": odometry_row(on.get("dead_reckoning"))}
            if rule != RULES[0]
            else {}
        ),
        "make_logs_s": t1 - t0,
        "diagnose_s": t2 - t1,
        "off_s": time.perf_counter() - t2 if acted and rule == RULES[0] else 0.0,
    }


def run(args: argparse.Namespace) -> None:
    out = Path(args.out)
    done = set()
    if out.exists() and args.resume:
        done = {json.loads(line)["case"] for line in out.read_text().splitlines() if line}
    todo = [c for c in planned(False, args.seed0) if tag(c) not in done][: args.limit]
    for i, case in enumerate(todo, 1):
        t = time.perf_counter()
        try:
            row = run_case(case, Path(args.work), args.drives, args.workers, args.rule)
        except Exception as exc:  # recorded, the study goes on
            row = {"case": tag(case), "kind": case["kind"], "error": f"{type(exc).__name__}: {exc}"}
        with out.open("a") as fh:
            fh.write(json.dumps(row) + "\n")
        print(
            f"[{i}/{len(todo)}] {tag(case)}: named {row.get('named')} (off:"
            f" {row.get('named_off')}) {time.perf_counter() - t:.0f} s",
            flush=True,
        )


def score(row: dict[str, Any], key: str) -> tuple[set[str], set[str]]:
    """(right, wrong) names of ``row`` under ``key`` ("named": the rule on, "named_off")."""
    truth = truth_names(row)
    named = set(row.get(key) or [])
    return named & truth, named - truth


def odometry_text(o: dict[str, Any] | None) -> str:
    """A row's dead reckoning in a table cell."""
    if not o or o.get("difference") is None:
        return "-"
    se = o.get("noise_se")
    se_text = f"{100 * se:.2f}" if isinstance(se, float) and se == se else "-"
    return (
        f"{100 * o['difference']:+.2f} % (se {se_text} %, {o.get('noise_samples')} intervals):"
        f" {o.get('why_not') or 'named'}"
    )


def report(rows_path: Path, md: Path) -> str:
    rows = [json.loads(line) for line in rows_path.read_text().splitlines() if line]
    ok = [r for r in rows if "error" not in r]
    lines = [
        f"# diagnose on {ok[0]['drives'] if ok else '?'} drive(s): {len(ok)} cases"
        f" ({len(rows) - len(ok)} failed)",
        "",
        "| kind | cases | right names on / off | wrong names on / off | nothing named on / off |",
        "|---|---|---|---|---|",
    ]
    for kind in ("single", "pair", "clean", "outside", "all"):
        rs = [r for r in ok if kind in ("all", r["kind"])]
        if not rs:
            continue
        cnt = {
            k: (
                sum(len(score(r, k)[0]) for r in rs),
                sum(len(score(r, k)[1]) for r in rs),
                sum(not r[k] for r in rs),
            )
            for k in ("named", "named_off")
        }
        lines.append(
            f"| {kind} | {len(rs)} | {cnt['named'][0]} / {cnt['named_off'][0]}"
            f" | {cnt['named'][1]} / {cnt['named_off'][1]}"
            f" | {cnt['named'][2]} / {cnt['named_off'][2]} |"
        )
    # per case: (right, wrong) names named without the rule and not with it
    gone = [
        tuple(len(a - b) for a, b in zip(score(r, "named_off"), score(r, "named"), strict=True))
        for r in ok
    ]
    odo = bool(ok) and ok[0].get("rule") == "odometry_noise"
    acted = "its decision differed" if odo else "a second effect judged beside the winner"
    lines += [
        "",
        f"cases where the rule acted ({acted}): {sum(r['acted'] for r in ok)}",
        f"right names the rule removed (H1): {sum(g[0] for g in gone)}"
        f" in {sum(g[0] > 0 for g in gone)} cases",
        f"wrong names the rule removed: {sum(g[1] for g in gone)}"
        f" in {sum(g[1] > 0 for g in gone)} cases",
        "",
        f"| case | truth | named (rule) | named (without) | {'odometry' if odo else 'partner limits'} |",
        "|---|---|---|---|---|",
    ]
    for r in ok:
        if r["acted"] or r["named"] != r["named_off"]:
            lim: Any = {
                k: {s: round(v, 4) for s, v in (x or {}).items()}
                for k, x in (r["partner_limits"] or {}).items()
            }
            if odo:
                lim = odometry_text(r.get("odometry"))
            lines.append(
                f"| {r['case']} | {r['truth']} | {', '.join(r['named']) or '-'}"
                f" | {', '.join(r['named_off']) or '-'} | {lim} |"
            )
    secs = sorted(r["diagnose_s"] for r in ok)
    if secs:
        lines += ["", f"diagnose seconds median {secs[len(secs) // 2]:.0f} (max {secs[-1]:.0f})"]
    text = "\n".join(lines) + "\n"
    md.parent.mkdir(parents=True, exist_ok=True)
    md.write_text(text)
    return text


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--seed0", type=int, default=71000, help="the plan's first seed")
    ap.add_argument("--drives", type=int, default=2, help="drives per case (1 or more)")
    ap.add_argument("--limit", type=int, default=None, help="run at most N cases")
    ap.add_argument("--workers", type=int, default=2, help="diagnose's workers")
    ap.add_argument("--resume", action="store_true", help="skip the cases --out holds")
    ap.add_argument("--out", default="out/few_drives.jsonl", help="rows, one per case")
    ap.add_argument("--work", default="out/few_drives", help="logs and reports per case")
    ap.add_argument("--rule", choices=RULES, default=RULES[0], help="the rule scored")
    ap.add_argument("--report", type=Path, default=None, help="summarise these rows")
    ap.add_argument("--md", type=Path, default=Path("out/few_drives.md"))
    args = ap.parse_args()
    if args.report is not None:
        print(report(args.report, args.md), end="")
    else:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        run(args)


if __name__ == "__main__":
    main()
