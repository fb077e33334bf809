"""``diagnose`` on one case's logs as a real logger might have written them: the same drives
without any pose, with the pose at each drive's end only (the paper's case, SPEC §6), with
5 % of the rows dropped, with time stamps jittered by up to 3 ms, and at 25 Hz.

Why (stop 99): issue 47 asks for calibration that survives a real rover, and a real log is
seldom the generator's even 50 Hz rows with a pose fix every second. This shows, per
variant, whether ``diagnose`` runs, what it names, the fit of the case's effect with its
interval, the wheels' sensor noise it read and its seconds. The logs come from the
independent generator (:mod:`rover_env.independent`, its build drawn from ``--seed``); a
variant is made from the as-logged drives (:func:`variant`), so every variant holds the same
motion. A jittered row's angles are the logged ones interpolated at the new stamp and
quantised again to the step found in the log: a reading at that instant to within a count.

    python benchmarks/log_variants.py --effect rolling_resistance=0.04 --seed 70874 \\
        --out out/log_variants
    python benchmarks/log_variants.py --seed 70875 --variants as-logged no-pose

Writes ``OUT/log_variants.md``, ``.json`` and ``.png`` (each variant's fit and interval
against the truth). Seeds 70000-70999 are this project's exploratory seeds.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from _report import write_report
from _rules import named_fits

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnose import Options, diagnose
from rover_env.independent.effects import MAIN
from rover_env.independent.generate import make_independent_logs
from rover_env.logs import DriveLog, read_log, write_log


def _no_pose(log: DriveLog, rng: np.random.Generator) -> DriveLog:
    return replace(log, pose=np.full_like(log.pose, np.nan))


def _end_pose(log: DriveLog, rng: np.random.Generator) -> DriveLog:
    """The last fix only (and none at the start: the frame is the start's by definition)."""
    pose = np.full_like(log.pose, np.nan)
    k = np.flatnonzero(np.isfinite(log.pose[:, 0]))
    if k.size:
        pose[k[-1]] = log.pose[k[-1]]
    return replace(log, pose=pose)


def _drop(log: DriveLog, rng: np.random.Generator, share: float = 0.05) -> DriveLog:
    """``share`` of the rows lost at random, never the first or the last."""
    keep = rng.random(len(log)) >= share
    keep[0] = keep[-1] = True
    return _rows(log, keep)


def _rate25(log: DriveLog, rng: np.random.Generator) -> DriveLog:
    keep = np.zeros(len(log), dtype=bool)
    keep[::2] = True
    out = _rows(log, keep)
    return replace(out, meta=replace(out.meta, sample_rate_hz=log.meta.sample_rate_hz / 2))


def _rows(log: DriveLog, keep: np.ndarray) -> DriveLog:
    return replace(
        log,
        t=log.t[keep],
        cmd=log.cmd[keep],
        phi=log.phi[keep],
        theta=log.theta[keep],
        pose=log.pose[keep],
        effort=log.effort[keep],
    )


def _requantised(t_new: np.ndarray, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``x`` (rows at ``t``) read at ``t_new``: interpolated, then quantised to its step."""
    step = rs.resolution(x)
    out = np.column_stack([np.interp(t_new, t, x[:, j]) for j in range(x.shape[1])])
    return np.round(out / step) * step if step > 0 else out


def _jitter(log: DriveLog, rng: np.random.Generator, ms: float = 3.0) -> DriveLog:
    """Inner rows stamped up to ``ms`` early or late, their angles read at the new stamp;
    commands and pose fixes stay as logged (sent and fixed at the row's time)."""
    t = log.t.copy()
    t[1:-1] += rng.uniform(-ms, ms, len(t) - 2) * 1e-3
    return replace(
        log,
        t=t,
        phi=_requantised(t, log.t, log.phi),
        theta=_requantised(t, log.t, log.theta),
        effort=np.column_stack([np.interp(t, log.t, e) for e in log.effort.T]),
    )


VARIANTS: dict[str, Callable[[DriveLog, np.random.Generator], DriveLog]] = {
    "as-logged": lambda log, rng: log,
    "no-pose": _no_pose,
    "end-pose": _end_pose,
    "drop5": _drop,
    "jitter3": _jitter,
    "rate25": _rate25,
}


def variant(name: str, log: DriveLog, seed: int) -> DriveLog:
    """``log`` as variant ``name`` writes it (its random draws from ``seed``)."""
    return VARIANTS[name](log, np.random.default_rng([seed, 99]))


def parse_effect(text: str | None) -> dict[str, dict[str, float]]:
    """``NAME=VALUE[,PARAM=VALUE...]`` in the generator's parameters (none: clean)."""
    if not text:
        return {}
    head, *rest = text.split(",")
    name, _, value = head.partition("=")
    params = {MAIN[name]: float(value)}
    params |= {k: float(v) for k, v in (p.split("=") for p in rest)}
    return {name: params}


def run_variant(name: str, src: list[Path], work: Path, seed: int, workers: int) -> dict[str, Any]:
    """Write variant ``name`` of the drives ``src`` and diagnose it."""
    logs_dir = work / name / "logs"
    paths = []
    for i, p in enumerate(src):
        out = logs_dir / p.name
        write_log(variant(name, read_log(p), seed + i), out, overwrite=True)
        paths.append(out)
    t0 = time.perf_counter()
    try:
        res = diagnose(
            [str(p) for p in paths],
            work / name / "out",
            Options(progress=False, workers=workers),
        )
    except Exception as exc:  # a variant that fails is the finding: say which, go on
        return {"variant": name, "error": f"{type(exc).__name__}: {exc}"}
    return {
        "variant": name,
        "named": res.get("named", []),
        "named_fits": named_fits(res),
        "fits": {k: f.get("params", {}) for k, f in (res.get("fits") or {}).items()},
        "wheel_noise": [res["sensor_noise"][f"wheel_{w}"] for w in ("1L", "1R", "2L", "2R")],
        "seconds": time.perf_counter() - t0,
    }


def _fit_of(row: dict[str, Any], name: str) -> tuple[float, float, float] | None:
    """``name``'s first parameter (value, 95 % interval) in a variant's row: as named, else
    as fitted; None where it was not fitted."""
    params = row["named_fits"].get(name) or row["fits"].get(name, {}).get(name) or {}
    if not params:
        return None
    v, lo, hi = next(iter(params.values()))
    return float(v), float(lo), float(hi)


def table(rows: list[dict[str, Any]], effects: dict[str, dict[str, float]]) -> str:
    name = next(iter(effects), None)
    lines = [
        "| variant | named | fit of the effect [95 %] | driven wheels' noise (mrad) | s |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['variant']} | error: {r['error']} | | | |")
            continue
        fit = "-"
        got = _fit_of(r, name) if name else None
        if got is not None:
            v, lo, hi = got
            fit = f"{v:.4g} [{lo:.4g}, {hi:.4g}]" + ("" if name in r["named"] else " (not named)")
        noise = ", ".join(f"{1e3 * n:.2f}" for n in r["wheel_noise"])
        lines.append(
            f"| {r['variant']} | {', '.join(r['named']) or '-'} | {fit} | {noise} |"
            f" {r['seconds']:.0f} |"
        )
    return "\n".join(lines) + "\n"


def plot(rows: list[dict[str, Any]], effects: dict[str, dict[str, float]], path: Path) -> None:
    """Each variant's fit of the one effect in ``effects`` and its interval, the drawn value
    as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    (name,) = effects
    fig, ax = plt.subplots(figsize=(6.0, 3.5))
    for i, r in enumerate(rows):
        fit = _fit_of(r, name)
        if fit is None:
            continue
        v, lo, hi = fit
        named = name in r.get("named", [])
        ax.errorbar(
            i,
            v,
            yerr=[[v - lo], [hi - v]],
            fmt="o" if named else "s",
            color="C0" if named else "C3",
            capsize=4,
        )
    drawn = next(iter(effects[name].values()))
    ax.axhline(drawn, color="k", lw=0.8, ls="--", label="drawn (generator's parameter)")
    ax.legend(fontsize=8)
    ax.set_xticks(range(len(rows)), [r["variant"] for r in rows], fontsize=8)
    ax.set_ylabel(f"{name}: fit (circle: named)")
    ax.set_title("diagnose on the same drives, logged otherwise")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--effect", default=None, help="NAME=VALUE[,PARAM=VALUE] (none: clean)")
    ap.add_argument("--seed", type=int, default=70874)
    ap.add_argument("--drives", type=int, default=3)
    ap.add_argument("--duration", type=float, default=50.0)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--work", type=Path, default=Path("out/log_variants/work"))
    ap.add_argument("--out", type=Path, default=Path("out/log_variants"))
    a = ap.parse_args(argv)
    effects = parse_effect(a.effect)
    src_dir = a.work / "as-generated"
    src = sorted(src_dir.glob("drive_*.csv")) or make_independent_logs(
        src_dir, effects, drives=a.drives, seed=a.seed, duration=a.duration
    )
    rows = []
    for name in a.variants:
        print(f"{name} ...", flush=True)
        rows.append(run_variant(name, src, a.work, a.seed, a.workers))
        print(f"  {rows[-1].get('named', rows[-1].get('error'))}", flush=True)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "log_variants.json").write_text(json.dumps(rows, indent=1))
    head = (
        f"# `diagnose` on one case logged otherwise\n\n"
        f"Independent generator, seed {a.seed}, {a.drives} drives of {a.duration:g} s,"
        f" effect: {a.effect or 'none (clean)'} (`benchmarks/log_variants.py`).\n\n"
    )
    figure = "\n![fits](log_variants.png)\n" if effects else ""  # clean: nothing to draw
    write_report(a.out / "log_variants.md", head + table(rows, effects) + figure)
    if effects:
        plot(rows, effects, a.out / "log_variants.png")
    return 0 if all("error" not in r for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
