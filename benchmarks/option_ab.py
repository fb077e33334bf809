"""One of ``diagnose``'s on/off options against the default, on the same fresh logs (issue 47).

Each case is a single effect on the independent generator (its build tolerances drawn from
the seed): torque-limit cuts the drives reach (``--torque N``: the generator's fraction
uniform in [-0.8, -0.5]), then the other catalogue effects in turn at magnitudes drawn
log-uniform as ``bench_independent.py`` draws them, then clean builds (``--clean N``,
nothing injected). Each case's logs are diagnosed twice, side by side, one worker each: as
``diagnose`` runs by default and with ``--OPTION`` (both with ``--candidates`` where given).
With ``--untested`` the logs first get every drive a default diagnosis of them proposes, the
drives for a limit they never tested too, driven by the same build as ``bench_independent.py
--untested`` drives them (the procedure the report advises for an unreached torque limit).
A row per case (what each named, the fits, seconds) goes to ``--json`` after each case.

    python benchmarks/option_ab.py --option forms-beside-rival --seed0 71600 --torque 8 \\
        --others 8 --work out/option_ab --json out/option_ab/rows.json
    # loose soils alone, then clean builds
    python benchmarks/option_ab.py --option no-screen-middle --seed0 74100 --torque 0 \\
        --others 16 --others-from loose_soil --dry-sand --clean 8 --work out/soil_ab
    # strong rolling resistances alone (c_rr 0.065-0.12)
    python benchmarks/option_ab.py --option no-presence-on-windows --seed0 74130 --torque 0 \\
        --others 12 --others-from rolling_resistance --strong --work out/rr_ab
    # what one candidate fits on clean builds, with the option and without
    # (--untested: after the drives a first diagnosis proposes)
    python benchmarks/option_ab.py --option torque-forms --seed0 74044 --torque 0 \\
        --others 0 --clean 20 --candidates torque_limit --work out/clean_torque \\
        --json out/clean_torque/rows.json

A study's hypotheses and its look script are registered before it runs
(docs/calibration/studyNNNNN/).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from _independent_plan import DRIVES, STRONG, catalogue_truth, generator_params, strong_params
from bench_independent import drive_proposals, proposals

from rover_env.independent import make_independent_logs

OTHERS = (
    "command_delay",
    "command_lag",
    "slope",
    "rolling_resistance",
    "loose_soil",
    "friction",
    "rolling_radius",
    "load_dependent_friction",
)
"""The other effects, in the order their cases are drawn."""


CLEAN = "clean"
"""A clean build's "effect": nothing injected."""


def plan(
    seed0: int,
    torque: int,
    others: int,
    clean: int = 0,
    pool: tuple[str, ...] = OTHERS,
    dry_sand: bool = False,
    strong: bool = False,
) -> list[tuple[int, str, dict[str, float]]]:
    """(seed, effect, the generator's parameters) of every case, from the seeds alone: a
    torque cut and another effect (of ``pool``, in its order) in turn (a run stopped early
    keeps both kinds), then the clean builds, whose seeds follow theirs. ``dry_sand``: every
    second loose soil is the generator's dry sand (else each is its regolith; with ``strong``
    each soil draws its own, as :func:`~_independent_plan.strong_params` does). ``strong``:
    the other effects drawn over :data:`~_independent_plan.STRONG`'s ranges (about twice
    their usual "named from" to their ranges' top), each of ``pool`` one of STRONG's."""
    if strong and not set(pool) <= set(STRONG):
        raise ValueError(
            f"strong: {sorted(set(pool) - set(STRONG))} not in STRONG ({', '.join(STRONG)})"
        )
    soils = 0
    kinds = ["torque"] * torque + ["other"] * others
    order = sorted(range(len(kinds)), key=lambda k: (k if k < torque else k - torque, k))
    out = []
    for k in [*order, *range(len(kinds), len(kinds) + clean)]:
        seed = seed0 + k
        if k >= len(kinds):
            out.append((seed, CLEAN, {}))
        elif kinds[k] == "torque":
            rng = np.random.default_rng([seed, 97])
            out.append((seed, "torque_limit", {"fraction": float(rng.uniform(-0.8, -0.5))}))
        else:
            eff = pool[(k - torque) % len(pool)]
            sand = dry_sand and eff == "loose_soil" and soils % 2 == 1
            soils += eff == "loose_soil"
            params = strong_params(eff, seed) if strong else generator_params(eff, seed, sand=sand)
            out.append((seed, eff, params))
    return out


def diagnose(logs: list[Path], out: Path, extra: list[str]) -> dict[str, Any]:
    """One ``rover-env diagnose`` (one worker): what it named, the fits, its seconds."""
    if not (out / "result.json").exists():
        cmd = [sys.executable, "-m", "rover_env.cli", "diagnose", *map(str, logs)]
        cmd += ["--out", str(out), "--workers", "1", "--quiet", *extra]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        (out / "wall_seconds.txt").write_text(f"{time.perf_counter() - t0:.1f}\n")
    r = json.loads((out / "result.json").read_text())
    final = {k: v["params"] for k, v in (r.get("final") or {}).items()}
    return {
        "named": r["named"],
        "final": final,
        "fits": {k: v.get("params") for k, v in (r.get("fits") or {}).items()},
        "forms_beside": r.get("model_form_beside"),
        "seconds": float((out / "wall_seconds.txt").read_text()),
    }


def followed(
    d: Path, injected: dict[str, dict[str, float]], seed: int, logs: list[Path], common: list[str]
) -> tuple[list[Path], list[str]]:
    """``logs`` and every drive a default diagnosis of them (``d/first``, with ``common``)
    proposes, the untested limit's too, driven as ``bench_independent.py`` drives them
    (:func:`bench_independent.drive_proposals`); and the proposed plans' names."""
    diagnose(logs, d / "first", common)
    props = proposals(d / "first", untested=True)
    return [*logs, *drive_proposals(d, injected, seed, props)], [p.plan for p in props]


def run_case(
    work: Path,
    option: str,
    seed: int,
    effect: str,
    params: dict[str, float],
    common: list[str] | None = None,
    untested: bool = False,
) -> dict[str, Any]:
    """One case's logs (made once) diagnosed in both arms, side by side; ``common``: the
    arguments both arms get; ``untested``: after the drives a first diagnosis proposes
    (:func:`followed`)."""
    d = work / f"case_{seed}"
    logs = sorted((d / "logs").glob("drive_*.csv"))
    injected = {} if effect == CLEAN else {effect: params}
    if len(logs) < DRIVES:
        logs = make_independent_logs(d / "logs", injected, drives=DRIVES, seed=seed)
    both = common or []
    plans: list[str] = []
    if untested:
        logs, plans = followed(d, injected, seed, logs, both)
    with ThreadPoolExecutor(2) as ex:
        off = ex.submit(diagnose, logs, d / "off", both)
        on = ex.submit(diagnose, logs, d / "on", [*both, f"--{option}"])
        arms = {"off": off.result(), "on": on.result()}
    truth = {} if effect == CLEAN else catalogue_truth(effect, params)
    return {
        "seed": seed,
        "effect": effect,
        "params": params,
        "truth": truth,
        "followup": plans,
        **arms,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--option", required=True, help="a diagnose switch, without its dashes")
    ap.add_argument("--seed0", type=int, required=True)
    ap.add_argument("--torque", type=int, default=8)
    ap.add_argument("--others", type=int, default=8)
    ap.add_argument("--clean", type=int, default=0, help="clean builds after the others")
    ap.add_argument(
        "--others-from",
        default=",".join(OTHERS),
        help="the other effects, comma-separated, drawn in this order (default: all)",
    )
    ap.add_argument(
        "--dry-sand",
        action="store_true",
        help="every second loose soil the generator's dry sand (with --strong each soil draws its own)",
    )
    ap.add_argument(
        "--strong",
        action="store_true",
        help="the other effects over STRONG's ranges (bench_independent --strong-pairs')",
    )
    ap.add_argument("--candidates", default=None, help="diagnose's --candidates, both arms")
    ap.add_argument(
        "--untested", action="store_true", help="first add the drives a diagnosis proposes"
    )
    ap.add_argument("--work", type=Path, default=Path("out/option_ab"))
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args(argv)
    rows = []
    pool = tuple(e.strip() for e in a.others_from.split(",") if e.strip())
    unknown = [e for e in pool if e not in OTHERS]
    if unknown or not pool:
        ap.error(f"--others-from: unknown {unknown or 'nothing'}; known: {', '.join(OTHERS)}")
    try:
        cases = plan(a.seed0, a.torque, a.others, a.clean, pool, a.dry_sand, a.strong)
    except ValueError as exc:
        ap.error(f"--strong with --others-from: {exc}")
    common = [] if a.candidates is None else ["--candidates", a.candidates]
    for k, (seed, effect, params) in enumerate(cases, 1):
        row = run_case(a.work, a.option, seed, effect, params, common, a.untested)
        rows.append(row)
        print(
            f"[{k}/{len(cases)}] {seed} {effect} {params}: off {row['off']['named']}"
            f" ({row['off']['seconds']:.0f} s), on {row['on']['named']}"
            f" ({row['on']['seconds']:.0f} s)",
            flush=True,
        )
        if a.json is not None:
            a.json.parent.mkdir(parents=True, exist_ok=True)
            a.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
