"""Which signal group reads an effect at which size: each group's own best value, on logs of
the independent generator.

For each case the generator drives a rover (its build drawn from the seed) with the effect
at the given size, or clean; ``diagnose``'s first stages run as they do (the split, the
model's forms, the replay floor), and the effect's candidate is replayed over a grid of
values on the training windows and on every drive's straight windows. For each value the
script keeps the mean log loss ratio over the windows (what ``diagnose``'s naming test
judges by; its fits minimise the summed losses) and each
signal group's summed loss; each group's best grid value is the size that group alone would
read. Why (stop 93): a rolling resistance was read at about half its size, and the groups
disagree about it (the joints low, the free wheels and the pose near the truth); this shows
where an effect's read comes from. A diagnostic that knows the answer: ``diagnose`` reads
nothing of it.

    python benchmarks/group_reads.py --effect rolling_resistance \\
        --cases 70814=0.04 70813=0.025 --clean 70803 70804 --out out/group_reads

A case may hold the effect's other parameters: ``--effect slope.deg --cases
70833=3,heading_deg=70`` reads a slope's size along its true heading, ``--effect
slope.heading_deg --cases 70833=70,deg=3`` its heading at its true size (stop 94).
``--option FIELD=VALUE`` sets one of ``diagnose``'s options for the forms.
``--motor FIELD=FACTOR`` gives the model another motor first (``armature=2``: the rotor of the
independent generator's drive, as a datasheet would give it). Writes ``OUT/group_reads.md``,
``.jsonl`` and ``.png`` (each group's read against the truth).
Seeds 70000-70999 are this project's exploratory seeds: no registered block draws them.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from _motor import add_motor_argument, motors, with_motor
from _report import write_report

from rover_env.calibration import residuals as rs
from rover_env.calibration.candidates import Candidate, catalogue
from rover_env.calibration.diagnosis import floor, form, split
from rover_env.calibration.diagnosis.form import ZERO_PREFIX, reprepare
from rover_env.calibration.diagnosis.state import STRAIGHT, Diagnosis, Options
from rover_env.calibration.fit import SIGNAL_GROUPS, group_losses
from rover_env.effects import CATALOGUE
from rover_env.independent.generate import make_independent_logs

SETS = ("train", STRAIGHT)
"""The window sets read: the training windows (what ``diagnose`` fits on) and every drive's
windows without a turn."""


def parse_effect(text: str) -> tuple[str, str]:
    """``NAME`` (the effect's first parameter) or ``NAME.PARAM``."""
    name, _, param = text.partition(".")
    if name not in CATALOGUE:
        raise SystemExit(f"--effect: {name!r} is not in the catalogue ({', '.join(CATALOGUE)})")
    params = [p.name for p in CATALOGUE[name].params]
    param = param or params[0]
    if param not in params:
        raise SystemExit(f"--effect: {name} has no parameter {param!r} (has {', '.join(params)})")
    return name, param


def parse_case(text: str, name: str = "") -> tuple[int, float, dict[str, float]]:
    """``SEED=VALUE[,PARAM=VALUE...]``: a case's seed, the size injected, and the effect's
    other parameters, held at those values in the logs and over the grid (a slope's
    ``heading_deg``: its size is read along the true heading)."""
    head, *rest = text.split(",")
    seed, sep, value = head.partition("=")
    try:
        if not sep:
            raise ValueError
        others = {k: float(v) for k, _, v in (r.partition("=") for r in rest)}
        case = int(seed), float(value), others
    except ValueError:
        raise SystemExit(f"--cases: expected SEED=VALUE[,PARAM=VALUE...], got {text!r}") from None
    known = [p.name for p in CATALOGUE[name].params] if name in CATALOGUE else list(others)
    for k in others:
        if k not in known:
            raise SystemExit(f"--cases {text!r}: {name} has no parameter {k!r}")
    return case


def parse_option(text: str) -> tuple[str, Any]:
    """``FIELD=VALUE``: one of ``diagnose``'s :class:`Options` (``fit_com_height=true``),
    the value read as that field's default's type."""
    field, sep, value = text.partition("=")
    defaults = {f.name: getattr(Options(), f.name) for f in dataclasses.fields(Options)}
    if not sep or field not in defaults:
        raise SystemExit(f"--option {text!r}: expected FIELD=VALUE, FIELD one of Options'")
    kind = type(defaults[field])
    try:
        if kind is bool:
            if value.lower() not in ("true", "false", "1", "0"):
                raise ValueError
            return field, value.lower() in ("true", "1")
        return field, kind(value) if kind in (int, float, str) else float(value)
    except ValueError:
        raise SystemExit(f"--option {text!r}: {value!r} is not a {kind.__name__}") from None


def grid_extension(
    cand: Candidate, param: str, col: int, v: float, others: dict[str, float]
) -> dict[str, dict[str, float]]:
    """The model replayed at grid value ``v``: the candidate's own mapping at ``v`` (its
    other parameters off), or, where the case holds the effect's other parameters, the
    catalogue's parameters as they are (a slope's heading read at its true size, where
    heading 0 is a direction, not off)."""
    if others:
        return {cand.name: {param: v, **others}}
    x = np.array(cand.off, dtype=float)
    x[col] = v
    return cand.to_ext(x)


def prepared_case(job: dict[str, Any]) -> Diagnosis:
    """A case's logs (generated once into the work folder) and ``diagnose``'s first stages
    on them: the split, the model's forms, the replay floor."""
    name, param, size, seed = job["effect"], job["param"], job["size"], job["seed"]
    others: dict[str, float] = job.get("others", {})
    # The folder names everything the logs depend on: a rerun with other drives regenerates.
    held = "".join(f"_{k}{v:g}" for k, v in sorted(others.items()))
    d = Path(job["work"]) / f"{seed}_{size:g}{held}_{job['drives']}x{job['duration']:g}s"
    eff = {name: {param: size, **others}} if size or others else {}
    paths = sorted((d / "logs").glob("drive_*.csv")) or make_independent_logs(
        d / "logs", eff, drives=job["drives"], seed=seed, duration=job["duration"]
    )
    opts = Options(progress=False, **job.get("options", {}))
    dg = Diagnosis([str(p) for p in paths], d / "out", opts)
    split.split(dg)
    if job.get("motor"):  # another motor for the model (a datasheet's), before its forms
        dg.base = with_motor(dg.base, job["motor"])
        dg.prepared = reprepare(dg.prepared, dg.base, dg.st)
    form.fit_model_form(dg)
    floor.baseline(dg)
    return dg


def read_case(job: dict[str, Any]) -> dict[str, Any]:
    """One case: its logs, the forms, and every group's loss over the grid on each set."""
    name, param, size, seed = job["effect"], job["param"], job["size"], job["seed"]
    others: dict[str, float] = job.get("others", {})
    dg = prepared_case(job)
    (cand,) = catalogue([name])
    col = [p.name for p in CATALOGUE[name].params].index(param)
    row: dict[str, Any] = {
        "seed": seed,
        "truth": size,
        "others": others,
        "forms": {f.name: round(float(f.value), 4) for f in dg.forms if f.adopted},
    }
    for which in SETS:
        l0, ratios, groups = None, [], []
        for v in job["grid"]:
            res = dg.ev.run(grid_extension(cand, param, col, v, others), which)
            loss = rs.window_losses(res, dg.ev.scale)
            l0 = loss if l0 is None else l0
            ratios.append(float(np.mean(np.log(loss / l0))))
            groups.append([float(g) for g in group_losses(res, dg.ev.scale).sum(axis=0)])
        g = np.array(groups)
        row[which] = {
            "windows": len(l0) if l0 is not None else 0,
            "ratio": ratios,
            "groups": groups,
            "best": job["grid"][int(np.argmin(ratios))],
            "group_best": {
                k: job["grid"][int(np.argmin(g[:, i]))] for i, k in enumerate(SIGNAL_GROUPS)
            },
        }
    return row


def table(rows: list[dict[str, Any]], name: str, param: str) -> str:
    """The markdown report: per case, the read of all signals and of each group alone."""
    held = any(r.get("others") for r in rows)  # a slope's size where its heading is read
    head = ["seed", "truth", *(["held"] if held else [])]
    head += [*(f"{w}: {k}" for w in SETS for k in ("all", *SIGNAL_GROUPS)), "forms"]
    lines = [
        f"# Which signal group reads `{name}.{param}`",
        "",
        "Each cell: the grid value that minimises that group's loss (all: the mean log loss"
        " ratio over the windows, what `diagnose`'s naming test judges by) on the training"
        " windows and on"
        " every drive's straight windows (`benchmarks/group_reads.py`).",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for r in sorted(rows, key=lambda r: (r["truth"], r["seed"])):
        cells = [str(r["seed"]), f"{r['truth']:g}"]
        if held:
            cells.append(", ".join(f"{k} {v:g}" for k, v in r.get("others", {}).items()) or "-")
        for w in SETS:
            cells += [f"{r[w]['best']:g}", *(f"{r[w]['group_best'][k]:g}" for k in SIGNAL_GROUPS)]
        forms = ", ".join(
            f"{k} {v:g}" for k, v in r["forms"].items() if not k.startswith(ZERO_PREFIX)
        )
        lines.append("| " + " | ".join([*cells, forms or "-"]) + " |")
    return "\n".join(lines) + "\n"


def plot(rows: list[dict[str, Any]], path: Path, name: str, param: str) -> None:
    """Each group's read (training windows) against the truth, clean cases at 0."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 4.5))
    keys = ["all", *SIGNAL_GROUPS]
    for i, k in enumerate(keys):
        x = np.array([r["truth"] for r in rows])
        y = np.array(
            [r["train"]["best"] if k == "all" else r["train"]["group_best"][k] for r in rows]
        )
        jitter = (i - (len(keys) - 1) / 2) * 0.02 * max(float(np.abs(x).max()), 1e-9)
        ax.scatter(x + jitter, y, label=k, marker="os^vD"[i % 5], s=28)
    lo, hi = min(0.0, *(r["truth"] for r in rows)), max(0.0, *(r["truth"] for r in rows))
    ax.plot([lo, hi], [lo, hi], color="grey", lw=0.8, ls="--", label="read = truth")
    ax.set_xlabel(f"true {param}")
    ax.set_ylabel(f"{param} read (training windows)")
    ax.set_title(f"{name}: each signal group's own read")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--effect", required=True, help="NAME[.PARAM] (default: its first parameter)")
    ap.add_argument(
        "--cases",
        nargs="*",
        default=[],
        help="SEED=VALUE[,PARAM=VALUE...]: cases with the effect, its other parameters held"
        " (slope: 70831=3,heading_deg=70)",
    )
    ap.add_argument("--clean", type=int, nargs="*", default=[], help="clean cases")
    ap.add_argument(
        "--grid",
        type=str,
        default=None,
        help="comma-separated values; --grid=-0.3,0,0.3 where the first is negative"
        " (default: 0 to 2.5 x the largest)",
    )
    ap.add_argument("--drives", type=int, default=3)
    ap.add_argument("--duration", type=float, default=50.0)
    ap.add_argument("--work", type=Path, default=Path("out/group_reads/work"))
    ap.add_argument("--out", type=Path, default=Path("out/group_reads"))
    add_motor_argument(ap)
    ap.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="one of diagnose's options for the forms (fit_com_height=true)",
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--from-jsonl", type=Path, default=None, help="tabulate saved rows again")
    a = ap.parse_args(argv)
    name, param = parse_effect(a.effect)
    if a.from_jsonl is not None:
        saved = [json.loads(line) for line in a.from_jsonl.read_text().splitlines() if line]
        return write(saved, a.out, name, param)
    cases = [parse_case(c, name) for c in a.cases]
    if not cases and not a.clean:
        raise SystemExit("--cases or --clean: at least one case")
    top = max([abs(v) for _, v, _ in cases] or [0.0])
    if not a.grid and top == 0.0:
        raise SystemExit("--grid: give the values when no case has the effect (--cases)")
    motor = motors(a)
    try:
        grid = (
            [float(v) for v in a.grid.split(",")]
            if a.grid
            else [float(v) for v in np.linspace(0.0, 2.5 * top, 11)]
        )
    except ValueError:
        raise SystemExit(f"--grid: not comma-separated numbers: {a.grid!r}") from None
    if len(grid) < 2 or len(set(grid)) < 2 or not all(math.isfinite(v) for v in grid):
        raise SystemExit(f"--grid: at least two different finite values: {a.grid!r}")
    base = {"effect": name, "param": param, "grid": grid, "work": str(a.work)}
    base |= {"drives": a.drives, "duration": a.duration}
    base["motor"] = motor
    base["options"] = dict(parse_option(o) for o in a.option)
    rows = run_cases(read_case, base, cases, a.clean, a.workers, a.out / "group_reads.jsonl", said)
    return write(rows, a.out, name, param)


def said(row: dict[str, Any]) -> str:
    """A case's progress line."""
    return (
        f"seed {row['seed']} truth {row['truth']:g}: read {row['train']['best']:g} (train),"
        f" {row[STRAIGHT]['best']:g} (straight); groups {row['train']['group_best']}"
    )


def run_cases(
    read: Callable[[dict[str, Any]], dict[str, Any]],
    base: dict[str, Any],
    cases: list[tuple[int, float, dict[str, float]]],
    clean: list[int],
    workers: int,
    path: Path,
    line: Callable[[dict[str, Any]], str],
) -> list[dict[str, Any]]:
    """Every case (``base`` with its seed, size and held parameters; clean ones at 0) read
    by ``read`` in ``workers`` processes, a progress line each; the rows, also saved to
    ``path`` as JSON lines."""
    jobs = [{**base, "seed": s, "size": v, "others": o} for s, v, o in cases]
    jobs += [{**base, "seed": s, "size": 0.0} for s in clean]
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = []
    with ProcessPoolExecutor(max(1, workers)) as ex:
        for i, row in enumerate(ex.map(read, jobs), 1):
            rows.append(row)
            print(f"[{i}/{len(jobs)}] {line(row)}", flush=True)
    with open(path, "w", encoding="utf-8") as f:
        for r in rows:
            f.write(json.dumps(r) + "\n")
    return rows


def write(rows: list[dict[str, Any]], out: Path, name: str, param: str) -> int:
    """The table and the figure of ``rows`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    write_report(out / "group_reads.md", table(rows, name, param))
    plot(rows, out / "group_reads.png", name, param)
    print(f"wrote {out / 'group_reads.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
