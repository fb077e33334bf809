"""Could the truth itself be named? The naming test at the true effect, on the independent generator.

``diagnose`` names an effect when its fit beats the nominal model on the held-out drive
(typical gain per window >= ``Options.min_gain``, Wilcoxon p < ``Options.alpha``) and on the
training drives (ΔBIC < 0), all in units of each signal's replay floor. This script gives
that test the *answer*: for every single-effect case of a ``bench_independent.py`` block it
replays the case's windows with the model forms ``diagnose`` fits before any effect, once
nominal and once at the catalogue's truth (``truth`` in the block's JSON), and applies the
same test. A case whose truth fails it cannot be named right by any search or any decision
rule over this model: what is left is the model's form against the logs' implementation.
The per-drive gains say where the truth loses (a turning drive, a straight one).

Loose soil is left out (its truth is one k_phi under a soil whose other constants the
candidate chooses among its forms). Nothing in ``diagnose`` reads the truth; this is a
diagnostic of the model, not a method.

    python benchmarks/truth_ceiling.py --block docs/calibration/block51200 \\
        --work out/bench_independent --workers 2

Writes ``OUT/truth_ceiling.md``, ``.json`` and ``.png`` (OUT defaults to the block folder).
``--make-logs`` drives a case's logs again where its work folder lacks them (the generator
is deterministic in the case's seed).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from _independent_plan import DRIVES, DURATION
from _independent_tables import truth_ratio
from _motor import add_motor_argument, motors, with_motor

from rover_env.calibration import residuals as rs
from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis import floor, form, split
from rover_env.calibration.diagnosis.form_ladder import reprepare
from rover_env.calibration.diagnosis.judge import gain, p_improved, training_criteria
from rover_env.calibration.diagnosis.state import Diagnosis, Options
from rover_env.independent.generate import make_independent_logs

SKIPPED = ("loose_soil",)


def test_at_truth(
    logs_dir: Path, truth: dict[str, dict[str, float]], motor: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The naming test of the truth against the nominal model (after the model forms);
    ``motor`` scales the configuration's motor fields first (:func:`_motor.with_motor`),
    so the forms and both replays are those of a model with another motor."""
    logs = sorted(str(p) for p in logs_dir.glob("*.csv"))
    kinds = [d["kind"] for d in yaml.safe_load((logs_dir / "truth.yaml").read_text())["drives"]]
    opts = Options(progress=False, workers=1)
    with tempfile.TemporaryDirectory() as tmp:
        d = Diagnosis(logs, Path(tmp), opts)
        split.split(d)
        if motor:
            d.base = with_motor(d.base, motor)
            d.prepared = reprepare(d.prepared, d.base, d.st)
        form.fit_model_form(d)
        floor.baseline(d)
        ev = d.ev
        held0, held1 = ev.run({}, "held"), ev.run(truth, "held")
        train0, train1 = ev.run({}, "train"), ev.run(truth, "train")
    h0, h1 = rs.window_losses(held0, d.noise), rs.window_losses(held1, d.noise)
    k = sum(c.k for c in catalogue(list(truth)))  # an equivalent effect counts as a parameter
    _, d_bic = training_criteria(train0, train1, d.noise, len(train0), k)
    per_drive: dict[str, float] = {}
    for name, r0, r1 in (("train", train0, train1), ("held", held0, held1)):
        t0, t1 = rs.window_losses(r0, d.noise), rs.window_losses(r1, d.noise)
        li = np.array([r.window.log_index for r in r0])
        for i in sorted(set(li.tolist())):
            per_drive[f"{name}:{kinds[i]}"] = gain(t0[li == i], t1[li == i])
    g, p = gain(h0, h1), p_improved(h0, h1)
    return {
        "held_gain": g,
        "p": p,
        "d_bic": d_bic,
        "passes": bool(g >= opts.min_gain and p < opts.alpha and d_bic < 0),
        "per_drive": per_drive,
    }


def case_row(case: dict[str, Any]) -> dict[str, Any]:
    """A single's row head: its effect, truth, strength (truth over the reported noise
    threshold) and what diagnose named."""
    ((name, _),) = case["truth"].items()
    row = {"case": case["case"], "truth": case["truth"], "effect": name}
    row["strength"] = truth_ratio(name, case["fits"].get(name))
    row["named_right"] = name in case["named"]
    row["named"] = case["named"]
    return row


def truth_ext(
    case: dict[str, Any], motor: dict[str, Any] | None = None
) -> dict[str, dict[str, float]]:
    """The case's truth as model extensions (with its equivalent effect, if any). A torque
    cut is a fraction of the configured limit: under ``motor``'s factor on ``torque_limit``
    the same limit in N m is the fraction ``(1 + f) / factor - 1``."""
    ext = {**case["truth"], **(case.get("equivalent") or {})}
    s = (motor or {}).get("torque_limit")
    if "torque_limit" in ext and isinstance(s, float):
        ext["torque_limit"] = {"fraction": (1 + ext["torque_limit"]["fraction"]) / s - 1}
    return ext


def single_cases(
    blocks: list[str], works: list[str], only: str | None = None, make: bool = False
) -> list[tuple[dict[str, Any], str]]:
    """(case, work folder) of every non-soil single of the blocks (``only``: one effect's);
    a case whose logs are missing stops the run with its name, or with ``make`` is driven
    again (:func:`make_case_logs`)."""
    jobs = []
    for block, work in zip(blocks, works, strict=True):
        for case in json.loads((Path(block) / "independent.json").read_text()):
            if case["kind"] != "single" or set(case["truth"]) & set(SKIPPED):
                continue
            if only and only not in case["truth"]:
                continue
            if not make and not (Path(work) / case["case"] / "logs").is_dir():
                raise SystemExit(f"{work}: no logs for case {case['case']} (block {block})")
            jobs.append((case, work))
    print(f"{len(jobs)} single-effect cases", flush=True)
    return jobs


def make_case_logs(case: dict[str, Any], work: str) -> None:
    """The case's logs as ``bench_independent.py`` drove them (its seed, effects, drives and
    duration: the generator is deterministic), where they are missing."""
    logs = Path(work) / case["case"] / "logs"
    if not logs.is_dir():
        make_independent_logs(
            logs, case["effects"], drives=DRIVES, seed=case["seed"], duration=DURATION
        )


def _one(args: tuple[dict[str, Any], str, dict[str, Any]]) -> dict[str, Any]:
    case, work, motor = args
    row = case_row(case)
    try:
        make_case_logs(case, work)
        row.update(test_at_truth(Path(work) / case["case"] / "logs", truth_ext(case, motor), motor))
    except Exception as exc:  # a case that cannot be replayed is reported, not skipped
        row["error"] = f"{type(exc).__name__}: {exc}"
    print(f"{row['case']}: {row.get('passes', row.get('error'))}", flush=True)
    return row


def strong(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The cases replayed whose truth is at least twice its reported noise threshold."""
    return [r for r in rows if (r["strength"] or 0) >= 2 and "error" not in r]


def table(rows: list[dict[str, Any]]) -> list[str]:
    """Markdown: per effect, strong singles whose truth passes the test, and named right."""
    tot, ok, named, both = Counter(), Counter(), Counter(), Counter()
    for r in strong(rows):
        e = r["effect"]
        tot[e] += 1
        ok[e] += r["passes"]
        named[e] += r["named_right"]
        both[e] += r["passes"] and r["named_right"]
    out = [
        "| effect | singles >= 2 x threshold | truth passes the naming test | named right"
        " | named right where the truth fails |",
        "|---|---|---|---|---|",
    ]
    for e in sorted(tot, key=lambda e: ok[e] / tot[e]):
        out.append(f"| {e} | {tot[e]} | {ok[e]} | {named[e]} | {named[e] - both[e]} |")
    n = sum(tot.values())
    out.append(
        f"| all | {n} | {sum(ok.values())} | {sum(named.values())}"
        f" | {sum(named.values()) - sum(both.values())} |"
    )
    return out


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = strong(rows)
    effects = sorted({r["effect"] for r in cases})
    fig, ax = plt.subplots(figsize=(8, 4))
    x = np.arange(len(effects))
    for j, (key, label) in enumerate((("passes", "truth passes"), ("named_right", "named right"))):
        share = [np.mean([r[key] for r in cases if r["effect"] == e]) for e in effects]
        ax.bar(x + (j - 0.5) * 0.38, share, 0.38, label=label)
    counts = [sum(r["effect"] == e for r in cases) for e in effects]
    ax.set_xticks(x, [f"{e}\n(n={c})" for e, c in zip(effects, counts, strict=True)], fontsize=7)
    ax.set_ylabel("share of singles >= 2 x threshold")
    ax.set_ylim(0, 1.05)
    ax.legend()
    ax.set_title("The naming test at the true effect vs diagnose's result")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--block", action="append", required=True, help="folder with independent.json")
    ap.add_argument("--work", action="append", required=True, help="its bench work folder")
    ap.add_argument("--out", default=None, help="where to write (default: the first block)")
    add_motor_argument(ap)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument(
        "--make-logs", action="store_true", help="drive a case's logs again where missing"
    )
    a = ap.parse_args()
    if len(a.block) != len(a.work):
        ap.error("give one --work per --block")
    motor = motors(a)
    jobs = [(case, w, motor) for case, w in single_cases(a.block, a.work, make=a.make_logs)]
    with ProcessPoolExecutor(max(1, a.workers)) as pool:
        rows = list(pool.map(_one, jobs))
    out = Path(a.out or a.block[0])
    out.mkdir(parents=True, exist_ok=True)
    (out / "truth_ceiling.json").write_text(json.dumps(rows, indent=1, default=float))
    lines = ["# The naming test at the true effect", "", f"Blocks: {', '.join(a.block)}."]
    lines += [f"Motor: {', '.join(a.motor)} (factors on the configuration's)."] if a.motor else []
    lines += [""]
    lines += [*table(rows), "", "| case | x threshold | held gain | p | ΔBIC | passes | named |"]
    lines += ["|---|---|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: (r["effect"], r["case"])):
        if "error" in r:
            lines.append(f"| {r['case']} | | | | | {r['error']} | |")
            continue
        s = "" if r["strength"] is None else f"{r['strength']:.1f}"
        lines.append(
            f"| {r['case']} | {s} | {r['held_gain']:+.2f} | {r['p']:.2g} | {r['d_bic']:+.1f}"
            f" | {'yes' if r['passes'] else 'no'} | {', '.join(r['named']) or '—'} |"
        )
    (out / "truth_ceiling.md").write_text("\n".join(lines) + "\n")
    plot(rows, out / "truth_ceiling.png")
    print("\n".join(table(rows)))
    return 1 if any("error" in r for r in rows) else 0


if __name__ == "__main__":
    raise SystemExit(main())
