"""Does the model's effect look like the generator's? The effect's change to the logs, measured
on a clean twin, against the model's change at the true magnitude.

For every single-effect case of a ``bench_independent.py`` block the same rover (seed: the
same build, plans and sensor noise) is driven again by the independent generator *without*
the effect: the twin. The model replays every window (forms fitted as ``diagnose`` fits
them before any effect) against the case's logs and against the twin's, and once more at the
catalogue's truth against the case's logs. Residuals are ``sim - log`` in units of each
signal's replay floor, so

- the generator's change, ``Δgen = resid(nominal, twin) - resid(nominal, logs)``, is what
  the effect did to the logged signals (the model's own replay cancels up to the small
  difference of the windows' starting states);
- the model's change, ``Δmodel = resid(truth, logs) - resid(nominal, logs)``, is what the
  model's effect does at the true magnitude.

A model whose effect has the generator's form gives ``Δmodel = Δgen``: the same size and a
cosine of 1. The table gives both norms, their cosine, and ``|resid(nominal, twin)|``, what
the model leaves on the clean twin (the form mismatch an effect must stand out from), per
signal group and per drive. Why: the truth-ceiling script (``truth_ceiling.py``) says *that*
the truth fails the naming test; this says *why*: the effect is not in the logs (small
``Δgen``), the model's effect is too weak or too strong (size ratio), or it points
elsewhere (cosine near 0). A diagnostic that knows the answer: nothing in ``diagnose``
reads it. Loose soil is left out (its truth is one k_phi under a soil whose other
constants the candidate chooses among its forms).

    python benchmarks/effect_twin.py --block docs/calibration/block51300 \\
        --work out/bench_independent --workers 2

Writes ``OUT/effect_twin.md``, ``.json`` and ``.png`` (OUT defaults to the first block).
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from _independent_plan import DRIVES, DURATION
from _motor import add_motor_argument, motors, with_motor
from truth_ceiling import case_row, single_cases, truth_ext

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnosis import floor, form, split
from rover_env.calibration.diagnosis.form_ladder import reprepare
from rover_env.calibration.diagnosis.state import Diagnosis, Options
from rover_env.calibration.fit import SIGNAL_GROUPS
from rover_env.calibration.replay import Replayer, WindowResult, prepare
from rover_env.calibration.residuals import SIGNALS
from rover_env.independent.generate import make_independent_logs
from rover_env.logs import read_log

VISIBLE = math.sqrt(Options.min_gain / (1.0 - Options.min_gain))
"""The generator's change over what the model leaves on the twin at which a perfect model
of the effect could pass the naming test's held-out gain (``Options.min_gain``, 10 %): with
the change orthogonal to the rest, it is then that share of the loss, ``Δ² / (Δ² + R²)``."""


def entry_labels(results: list[WindowResult]) -> tuple[np.ndarray, np.ndarray]:
    """Per entry of :func:`~rover_env.calibration.residuals.residual_vector`: its signal
    group and its log (drive) index, in the vector's order."""
    group_of = {s: g for g, sigs in SIGNAL_GROUPS.items() for s in sigs}
    row = np.array([group_of[s] for s in SIGNALS[:11]], dtype=object)
    pose = np.array([group_of[s] for s in SIGNALS[11:]], dtype=object)
    groups, logs = [], []
    for r in results:
        n, m = r.resid.shape[0], r.pose_resid.shape[0]
        groups += [np.tile(row, n), np.tile(pose, m)]
        logs.append(np.full(11 * n + 3 * m, r.window.log_index))
    if not groups:
        return np.zeros(0, dtype=object), np.zeros(0, dtype=int)
    return np.concatenate(groups), np.concatenate(logs)


def compare(gen: np.ndarray, model: np.ndarray) -> dict[str, float]:
    """Norms of the two changes and their cosine (0 where either is zero)."""
    ng, nm = float(np.linalg.norm(gen)), float(np.linalg.norm(model))
    cos = float(gen @ model) / (ng * nm) if ng > 0 and nm > 0 else 0.0
    return {"gen": ng, "model": nm, "cos": cos}


def changes(
    nominal: list[WindowResult],
    twin: list[WindowResult],
    truth: list[WindowResult],
    scale: dict[str, float],
    kinds: list[str],
) -> dict[str, Any]:
    """The generator's and the model's changes, overall, per signal group and per drive
    (``kinds[i]``: log i's drive kind), and what the model leaves on the twin."""
    a = rs.residual_vector(nominal, scale)
    b = rs.residual_vector(twin, scale)
    t = rs.residual_vector(truth, scale)
    if not a.shape == b.shape == t.shape:
        raise ValueError("the three replays must score the same windows and samples")
    dg, dm = b - a, t - a
    groups, logs = entry_labels(nominal)
    out: dict[str, Any] = {"all": compare(dg, dm), "twin_left": float(np.linalg.norm(b))}
    out["groups"] = {g: compare(dg[groups == g], dm[groups == g]) for g in SIGNAL_GROUPS}
    out["drives"] = {
        f"{i}:{kinds[i]}": {
            **compare(dg[logs == i], dm[logs == i]),
            "twin_left": float(np.linalg.norm(b[logs == i])),
        }
        for i in sorted(set(logs.tolist()))
    }
    return out


def measure(
    logs_dir: Path,
    seed: int,
    truth: dict[str, dict[str, float]],
    motor: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """:func:`changes` for one case: its logs, a clean twin driven here, the truth. ``motor``:
    numbers that scale the model's motor fields (strings set them: ``anti_windup``), after
    the forms, to ask what another loop would make of the effect."""
    logs: list[str | Path] = sorted(str(p) for p in logs_dir.glob("*.csv"))
    kinds = [d["kind"] for d in yaml.safe_load((logs_dir / "truth.yaml").read_text())["drives"]]
    with tempfile.TemporaryDirectory() as tmp:
        twin = make_independent_logs(
            Path(tmp) / "twin", {}, drives=DRIVES, seed=seed, duration=DURATION
        )
        d = Diagnosis(logs, Path(tmp) / "diagnosis", Options(progress=False, workers=1))
        split.split(d)
        form.fit_model_form(d)
        if motor:
            d.base = with_motor(d.base, motor)
            d.prepared = reprepare(d.prepared, d.base, d.st)
        floor.baseline(d)
        by_name = {Path(p).name: p for p in twin}  # the twin's drive i is the logs' drive i
        twin_prep = [prepare(read_log(by_name[p.name]), d.base, p.name, d.st) for p in d.prepared]
        nominal = Replayer(d.base, d.st).run(d.prepared, d.all_w)
        twin_res = Replayer(d.base, d.st).run(twin_prep, d.all_w)
        truth_res = Replayer(d.ev.config(truth), d.st).run(d.prepared, d.all_w)
    return changes(nominal, twin_res, truth_res, d.noise, kinds)


def _one(args: tuple[dict[str, Any], str, dict[str, Any]]) -> dict[str, Any]:
    case, work, motor = args
    row = case_row(case)
    try:
        row.update(
            measure(Path(work) / case["case"] / "logs", case["seed"], truth_ext(case), motor)
        )
    except Exception as exc:  # a case that cannot be replayed is reported, not skipped
        row["error"] = f"{type(exc).__name__}: {exc}"
    print(f"{row['case']}: {row.get('all', row.get('error'))}", flush=True)
    return row


def visible_ratio(row: dict[str, Any]) -> float:
    """The generator's change over what the model leaves on the clean twin."""
    return float(row["all"]["gen"] / max(row["twin_left"], 1e-12))


def size_ratio(row: dict[str, Any]) -> float:
    """The model's change at the truth over the generator's."""
    return float(row["all"]["model"] / max(row["all"]["gen"], 1e-12))


def summary(rows: list[dict[str, Any]]) -> list[str]:
    """Markdown, per effect: cases, median generator change over what the model leaves on
    the twin, median size ratio (model / generator), median cosine, cosines >= 0.9."""
    by: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        if "error" not in r:
            by[r["effect"]].append(r)
    out = [
        "| effect | cases | Δgen / twin left (median) | model / gen size (median) | cosine (median)"
        " | cosine >= 0.9 |",
        "|---|---|---|---|---|---|",
    ]
    for e in sorted(by, key=lambda e: float(np.median([r["all"]["cos"] for r in by[e]]))):
        rs_ = by[e]
        vis = np.median([visible_ratio(r) for r in rs_])
        size = np.median([size_ratio(r) for r in rs_])
        cos = [r["all"]["cos"] for r in rs_]
        out.append(
            f"| {e} | {len(rs_)} | {vis:.2f} | {size:.2f} | {np.median(cos):+.2f}"
            f" | {sum(c >= 0.9 for c in cos)} |"
        )
    return out


def visibility(rows: list[dict[str, Any]]) -> list[str]:
    """Markdown: cases whose generator change reaches :data:`VISIBLE` times what the model
    leaves on the twin against those below it, and how many of each were named right."""
    ok = [r for r in rows if "error" not in r]
    out = ["| the effect's change / the model's mismatch on the twin | cases | named right |"]
    out.append("|---|---|---|")
    for label, keep in ((f">= {VISIBLE:.2f}", True), (f"< {VISIBLE:.2f}", False)):
        sel = [r for r in ok if (visible_ratio(r) >= VISIBLE) == keep]
        out.append(f"| {label} | {len(sel)} | {sum(bool(r['named_right']) for r in sel)} |")
    return out


def case_lines(rows: list[dict[str, Any]]) -> list[str]:
    """Markdown, one line per case: the overall and per-group comparison."""
    groups = list(SIGNAL_GROUPS)
    head = "| case | x threshold | named | Δgen / twin left | model / gen | cos | "
    head += " | ".join(f"{g}: gen, model, cos" for g in groups) + " |"
    out = [head, "|" + "---|" * (6 + len(groups))]
    for r in sorted(rows, key=lambda r: (r["effect"], r["case"])):
        if "error" in r:
            out.append(f"| {r['case']} | | | {r['error']} |" + " |" * (2 + len(groups)))
            continue
        a = r["all"]
        s = "" if r["strength"] is None else f"{r['strength']:.1f}"
        cells = [
            f"{r['groups'][g]['gen']:.0f}, {r['groups'][g]['model']:.0f}, {r['groups'][g]['cos']:+.2f}"
            for g in groups
        ]
        out.append(
            f"| {r['case']} | {s} | {', '.join(r['named']) or '—'}"
            f" | {visible_ratio(r):.2f} | {size_ratio(r):.2f}"
            f" | {a['cos']:+.2f} | " + " | ".join(cells) + " |"
        )
    return out


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if "error" not in r]
    fig, ax = plt.subplots(figsize=(8, 5))
    for e in sorted({r["effect"] for r in ok}):
        sel = [r for r in ok if r["effect"] == e]
        x = [size_ratio(r) for r in sel]
        y = [r["all"]["cos"] for r in sel]
        ax.scatter(x, y, label=e, s=22)
    ax.axvline(1.0, color="0.6", lw=0.8)
    ax.axhline(1.0, color="0.6", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlabel("size of the model's change at the truth / the generator's (log)")
    ax.set_ylabel("cosine between the two changes")
    ax.set_ylim(-1.05, 1.05)
    ax.legend(fontsize=7)
    ax.set_title("Each effect in the model against the same effect in the generator")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def measure_all(
    blocks: list[str], works: list[str], only: str | None, motor: dict[str, Any], workers: int
) -> list[dict[str, Any]]:
    """:func:`_one` over every non-soil single of the blocks (``only``: one effect's)."""
    jobs = [(case, work, motor) for case, work in single_cases(blocks, works, only)]
    with ProcessPoolExecutor(max(1, workers)) as pool:
        return list(pool.map(_one, jobs))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--block", action="append", required=True, help="folder with independent.json")
    ap.add_argument("--work", action="append", required=True, help="its bench work folder")
    ap.add_argument("--out", default=None, help="where to write (default: the first block)")
    ap.add_argument("--only", default=None, help="one effect's cases only")
    add_motor_argument(ap)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--from-json", default=None, help="tabulate a saved effect_twin.json again")
    a = ap.parse_args()
    if len(a.block) != len(a.work):
        ap.error("give one --work per --block")
    motor = motors(a)
    if a.from_json:
        rows = json.loads(Path(a.from_json).read_text())
    else:
        rows = measure_all(a.block, a.work, a.only, motor, a.workers)
    out = Path(a.out or a.block[0])
    out.mkdir(parents=True, exist_ok=True)
    (out / "effect_twin.json").write_text(json.dumps(rows, indent=1, default=float))
    lines = ["# Each effect in the model against the same effect in the generator", ""]
    lines += [f"Blocks: {', '.join(a.block)}."]
    if motor:
        lines.append(f"The model's motor: {', '.join(f'{k} {v}' for k, v in motor.items())}.")
    lines += ["", *summary(rows), "", *visibility(rows), "", *case_lines(rows)]
    (out / "effect_twin.md").write_text("\n".join(lines) + "\n")
    plot(rows, out / "effect_twin.png")
    print("\n".join([*summary(rows), "", *visibility(rows)]))
    return 1 if any("error" in r for r in rows) else 0


if __name__ == "__main__":
    raise SystemExit(main())
