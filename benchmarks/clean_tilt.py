"""Which build tolerance a clean drive's tilt (or another effect's fit) comes from (issue 47).

On clean drives of the independent generator every effect's fit still finds something (the
clean-fit allowance, ``configs/calibration/form_allowance.yaml``): a tilt of up to 2.4°, which
a slope must clear before it is named. This script drives clean cases of that generator with
its build tolerances all drawn (``all``), none (``none``: the implementations' difference
alone), or one part at a time (:data:`rover_env.independent.nuisance.GROUPS`), and fits the
slope alone on each (``diagnose --candidates slope``): the tilt each part of the build leaves
(stop 80). ``--effect`` fits another catalogue effect alone instead and reports its first
parameter (stop 86: a clean drive's rolling resistance).

    python benchmarks/clean_tilt.py --seed0 70000 --seeds 10 --groups none,all,centres_of_mass
    python benchmarks/clean_tilt.py --effect rolling_resistance --groups none,all,motors

Seeds 70000 and up are drawn by no benchmark block. Each case is a process of its own, two at
a time; a case whose ``result.json`` exists is not run again. Prints one line a case and the
medians, and writes ``clean_tilt.json`` to ``--work``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from rover_env.effects import CATALOGUE
from rover_env.independent import make_independent_logs
from rover_env.independent.nuisance import GROUPS

CONDITIONS = ("none", "all", *GROUPS)


def case(work: Path, condition: str, seed: int, effect: str = "slope") -> dict[str, Any]:
    """One clean case: logs of the build ``condition`` names, ``effect`` fitted alone."""
    d = work / (f"{condition}_{seed}" if effect == "slope" else f"{effect}_{condition}_{seed}")
    out = d / "out"
    if not (out / "result.json").exists():
        nuisance: bool | list[str] = {"none": False, "all": True}.get(condition, [condition])
        logs = make_independent_logs(d / "logs", {}, drives=3, seed=seed, nuisance=nuisance)
        cmd = [sys.executable, "-m", "rover_env.cli", "diagnose", *map(str, logs)]
        cmd += ["--out", str(out), "--candidates", effect, "--workers", "1", "--quiet"]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    params = json.loads((out / "result.json").read_text())["fits"][effect]["params"][effect]
    if effect == "slope":
        deg, heading = params["deg"][0], params["heading_deg"][0]
        return {"condition": condition, "seed": seed, "deg": deg, "heading_deg": heading}
    name = _key(effect)
    return {"condition": condition, "seed": seed, name: params[name][0]}


def _key(effect: str) -> str:
    """The parameter a row reports: the effect's first (a slope's tilt, ``deg``)."""
    return str(CATALOGUE[effect].params[0].name)


def _line(r: dict[str, Any], effect: str) -> str:
    if effect == "slope":
        return f"tilt {r['deg']:.2f}° heading {r['heading_deg']:.0f}°"
    return f"{_key(effect)} {r[_key(effect)]:.4g}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed0", type=int, default=70000)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--groups", default="none,all,centres_of_mass", help=", ".join(CONDITIONS))
    ap.add_argument("--work", default="out/clean_tilt")
    ap.add_argument("--effect", default="slope", help="the catalogue effect fitted alone")
    a = ap.parse_args(argv)
    if a.effect not in CATALOGUE:
        ap.error(f"--effect: {a.effect} not one of {', '.join(sorted(CATALOGUE))}")
    conditions = a.groups.split(",")
    if unknown := [c for c in conditions if c not in CONDITIONS]:
        ap.error(f"--groups: {', '.join(unknown)} not one of {', '.join(CONDITIONS)}")
    work = Path(a.work)
    jobs = [(c, a.seed0 + i) for i in range(a.seeds) for c in conditions]
    rows: list[dict[str, Any]] = []
    with ThreadPoolExecutor(2) as ex:
        for k, r in enumerate(ex.map(lambda j: case(work, *j, a.effect), jobs), 1):
            rows.append(r)
            print(
                f"[{k}/{len(jobs)}] {r['condition']:16s} {r['seed']} {_line(r, a.effect)}",
                flush=True,
            )
    key = _key(a.effect)
    for c in conditions:
        v = sorted(r[key] for r in rows if r["condition"] == c)
        m = statistics.median(v)
        spread = (
            f"{m:.2f}° ({v[0]:.2f}-{v[-1]:.2f})"
            if a.effect == "slope"
            else f"{m:.4g} ({v[0]:.4g}-{v[-1]:.4g})"
        )
        print(f"{c:16s} median {spread}, {len(v)} builds")
    name = "clean_tilt.json" if a.effect == "slope" else f"clean_{a.effect}.json"
    (work / name).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
