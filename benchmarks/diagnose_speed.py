"""Seconds per diagnose case, this code against a previous commit, in one run (issue 47).

The same logs are diagnosed by both trees, alternately (previous, current, previous, ...), each
in its own process with the same ``--workers``; the reference tree is a ``git worktree`` of
``--against`` (default ``HEAD~1``). Cases are drawn from the independent generator with build
tolerances (:mod:`rover_env.independent`), seeds from ``--seed0``: clean and one effect each.

    python benchmarks/diagnose_speed.py --against 512b331 --cases 4 --workers 2
    python benchmarks/diagnose_speed.py --effects command_lag,clean --cases 2

Prints each case's seconds, what each tree named and whether the two ``result.json`` agree
to the bit (timings aside), then the median ratio previous/current.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from rover_env.independent import make_independent_logs

EFFECTS: list[dict[str, dict[str, float]]] = [
    {},
    {"torque_limit": {"fraction": -0.6}},
    {"command_delay": {"delay": 0.12}},
    {"slope": {"deg": 6.0, "heading_deg": 40.0}},
    {"rolling_resistance": {"c_rr": 0.05}},
    {"loose_soil": {"k_phi": 1.0}},
    {"command_lag": {"tau": 0.2}},
]


PAIRS: list[dict[str, dict[str, float]]] = [
    {"command_lag": {"tau": 0.3}, "command_delay": {"delay": 0.1}},
]
"""Cases run only when named (``--effects command_lag+command_delay``): a lag with a delay,
the pair :mod:`rover_env.calibration.diagnosis.shared` fits together."""


def chosen(names: str | None) -> list[dict[str, dict[str, float]]]:
    """The cases of ``names`` (comma-separated: effect names, ``clean`` for none, or a pair
    of :data:`PAIRS` joined by ``+``), in that order; all of :data:`EFFECTS` when None."""
    if names is None:
        return EFFECTS
    by_name = {"+".join(e) or "clean": e for e in [*EFFECTS, *PAIRS]}
    out = []
    for n in names.split(","):
        if n.strip() not in by_name:
            raise SystemExit(f"--effects: unknown case {n.strip()!r}; known: {', '.join(by_name)}")
        out.append(by_name[n.strip()])
    return out


ROOT = Path(__file__).resolve().parents[1]


def case_effect(effects: list[dict[str, dict[str, float]]], i: int) -> dict[str, dict[str, float]]:
    """Case ``i``'s effects: ``effects`` in turn, the cycle shifted by one each time round.
    Why (stop 110): the generator's drive kinds follow the seed with period 7
    (:func:`rover_env.independent.drive.drive_kind`), so cycling seven effects over
    consecutive seeds gave every case of an effect the same three drives (study 73800's
    torque cuts: steps, turns, stop-and-go each time)."""
    n = len(effects)
    return effects[(i + i // n) % n]


def reference_tree(ref: str, work: Path) -> Path:
    """A worktree of ``ref`` under ``work`` (reused when it is already at ``ref``)."""
    sha = subprocess.check_output(["git", "rev-parse", ref], cwd=ROOT, text=True).strip()
    tree = work / f"ref_{sha[:10]}"
    if not tree.exists():
        subprocess.check_call(
            ["git", "worktree", "add", "--detach", str(tree), sha], cwd=ROOT, stdout=sys.stderr
        )
    return tree


def diagnose_seconds(
    tree: Path, logs: list[Path], out: Path, workers: int
) -> tuple[float, list[str]]:
    """Wall seconds of one ``rover-env diagnose`` run with ``tree`` first on the path."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    cmd = [sys.executable, "-m", "rover_env.cli", "diagnose", *map(str, logs)]
    cmd += ["--out", str(out), "--workers", str(workers), "--quiet"]
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, cwd=tree, stdout=subprocess.DEVNULL)
    dt = time.perf_counter() - t0
    named = json.loads((out / "result.json").read_text())["named"]
    return dt, named


def named_params(out: Path) -> dict[str, Any]:
    """The named effects' parameters, each [value, 95 % low, 95 % high], from ``out``."""
    final = json.loads((out / "result.json").read_text()).get("final") or {}
    return {k: v.get("params") for k, v in final.items()}


TIMING = frozenset({"seconds", "replay_seconds", "replays", "stage_seconds"})
"""``result.json`` keys that hold a run's own cost (seconds, replays made), not what it
found."""


def findings(out: Path) -> Any:
    """``out/result.json`` without its timings, its own folder's name written ``OUT``: what two
    runs on the same logs must agree on to the bit (a speed change must not change them)."""

    def strip(x: Any) -> Any:
        if isinstance(x, dict):
            return {k: strip(v) for k, v in x.items() if k not in TIMING}
        if isinstance(x, list):
            return [strip(v) for v in x]
        return x.replace(str(out), "OUT") if isinstance(x, str) else x

    return strip(json.loads((out / "result.json").read_text()))


def summarise(against: str, workers: int, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The medians over ``rows`` (cases run so far) and the rows themselves."""
    ratios = [r["previous_s"] / r["current_s"] for r in rows]
    return {
        "against": against,
        "workers": workers,
        "cpus": os.cpu_count(),
        "cases": len(rows),
        "median_previous_s": statistics.median(r["previous_s"] for r in rows),
        "median_current_s": statistics.median(r["current_s"] for r in rows),
        "median_ratio": statistics.median(ratios),
        "same_named": sum(set(r["previous_named"]) == set(r["current_named"]) for r in rows),
        "same_result": sum(r["same_result"] for r in rows),
        "rows": rows,
    }


def run(
    against: str,
    cases: int,
    workers: int,
    work: Path,
    seed0: int,
    out: Path | None = None,
    effects: list[dict[str, dict[str, float]]] = EFFECTS,
) -> dict[str, Any]:
    """Every case diagnosed by both trees; the summary is written to ``out`` after each case
    (a run stopped early keeps the cases it finished)."""
    work.mkdir(parents=True, exist_ok=True)
    ref = reference_tree(against, work)
    rows: list[dict[str, Any]] = []
    summary: dict[str, Any] = {}
    for i in range(cases):
        eff = case_effect(effects, i)
        d = work / f"case_{seed0 + i}"
        logs = make_independent_logs(d / "logs", eff, drives=3, seed=seed0 + i)
        prev, prev_named = diagnose_seconds(ref, logs, d / "prev", workers)
        cur, cur_named = diagnose_seconds(ROOT, logs, d / "cur", workers)
        rows.append(
            {
                "case": seed0 + i,
                "effects": eff,
                "previous_s": prev,
                "current_s": cur,
                "previous_named": prev_named,
                "current_named": cur_named,
                "same_result": findings(d / "prev") == findings(d / "cur"),
                "previous_params": named_params(d / "prev"),
                "current_params": named_params(d / "cur"),
            }
        )
        print(
            f"case {seed0 + i} {'+'.join(eff) or 'clean'}: previous {prev:.0f} s"
            f" {prev_named}, current {cur:.0f} s {cur_named}, ratio {prev / cur:.2f},"
            f" result.json {'the same' if rows[-1]['same_result'] else 'DIFFERS'}",
            flush=True,
        )
        summary = summarise(against, workers, rows)
        if out is not None:
            out.write_text(json.dumps(summary, indent=2))
    print(
        f"median seconds per case: previous {summary['median_previous_s']:.0f},"
        f" current {summary['median_current_s']:.0f}; median ratio {summary['median_ratio']:.2f};"
        f" the same named in {summary['same_named']} of {len(rows)}, the same result.json"
        f" (timings aside) in {summary['same_result']}"
    )
    return summary


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--against", default="HEAD~1", help="the previous code: a git ref")
    ap.add_argument("--cases", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed0", type=int, default=47900)
    ap.add_argument("--work", default="out/diagnose_speed")
    ap.add_argument("--json", default=None, help="write the summary here (after every case)")
    ap.add_argument(
        "--effects",
        default=None,
        help="cases to cycle through, comma-separated (e.g. command_lag,clean); default: all",
    )
    a = ap.parse_args(argv)
    run(
        a.against,
        a.cases,
        a.workers,
        Path(a.work).resolve(),
        a.seed0,
        Path(a.json) if a.json else None,
        chosen(a.effects),
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
