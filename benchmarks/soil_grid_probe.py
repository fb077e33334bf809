"""Is a loose-soil scenario's stall rate physics or the rut map's grid? Goals against the rut
cell and the approach heading.

    python benchmarks/soil_grid_probe.py --rut-cells 0.025,0.0125,0.008 --yaws seed,0,0.05,0.1

Runs one controller (default ``open-loop@gain=2.3@ramp=2``) on a scenario's seeds (default
soft-patch, tuning seeds 1000-1039) once per setting: the soil of every loose patch with
``rut_cell`` (and any ``--set`` field) replaced, and the start heading either the seed's own
(``seed``: the scenario's jitter) or forced to +-YAW rad (sign alternating with the seed).
A stall rate that depends on the rut cell is a property of the discretisation, not of the
soil. One that depends on the heading of a straight drive across a ripple running across the
drive is suspect (a real rover's middle wheels run in its front wheels' ruts at any heading,
stop 40), but not proven numerical: stop 42 found a heading window on soft-patch that neither
the rut cell nor the heightfield's grid moved, and stop 43 traced it to a 7.8 cm ledge where
the ripples began (``docs/benchmark-agents-mobility/README.md``, Stop 43).
Prints goals with a Wilson 95 % interval, the failed seeds, energy per metre and mean
sinkage per setting; writes ``--out`` (CSV and a plot; ``episodes.csv`` holds every drive
with its start heading). ``--resolution`` replaces the terrain heightfield's grid, to tell
that discretisation apart too. Tuning and validation seeds only (a test seed is refused:
this is looking).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from rover_env.benchmark.run import ScenarioWrapper, run_episode
from rover_env.config import ConfigError, TerrainConfig
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.policies.specs import make_controller
from rover_env.seeds import split_of
from rover_env.soil import soil_variant
from rover_env.tasks.scenarios import load_scenario


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of a proportion k / n."""
    if n == 0:
        return float("nan"), float("nan")
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, mid - half), min(1.0, mid + half)  # rounding: no -0.0 at k = 0


def terrain_with(t: TerrainConfig, changes: dict[str, float], folder: Path) -> TerrainConfig:
    """``t`` with every loose patch's soil (and the ground's, if loose) changed."""
    patches = tuple(
        dataclasses.replace(p, soil=str(soil_variant(p.soil, changes, folder))) if p.soil else p
        for p in t.patches
    )
    soil = str(soil_variant(t.soil, changes, folder)) if t.soil else None
    return dataclasses.replace(t, patches=patches, soil=soil)


def main() -> int:
    try:
        return _main()
    except ConfigError as exc:  # a soil field or a rut cell the soil or the arena refuses
        print(f"error: {exc}", file=sys.stderr)
        return 2


def _main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--controller", default="open-loop@gain=2.3@ramp=2")
    ap.add_argument("--scenario", default="soft-patch")
    ap.add_argument("--seeds", default="1000-1039", help="first-last (tuning or validation)")
    ap.add_argument("--rut-cells", default="0.025,0.0125", help="rut cells to try (m)")
    ap.add_argument("--yaws", default="seed,0,0.05,0.1", help="'seed' or a heading (rad)")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="another soil field for every setting, e.g. k_dig=0")  # fmt: skip
    ap.add_argument(
        "--resolution",
        type=float,
        default=None,
        help="the terrain heightfield's grid (m) instead of the scenario's",
    )
    ap.add_argument("--out", default=None, help="folder for probe.csv and probe.png")
    args = ap.parse_args()
    try:
        first, _, last = args.seeds.partition("-")
        seeds = list(range(int(first), int(last or first) + 1))
        extra = {k: float(v) for k, v in (kv.split("=", 1) for kv in args.set)}
        cells = [float(c) for c in args.rut_cells.split(",")]
        yaws = [None if y == "seed" else float(y) for y in args.yaws.split(",")]
    except ValueError as exc:
        print(f"error: {exc} (--seeds FIRST-LAST, --rut-cells and --yaws comma-separated "
              "numbers, --set FIELD=NUMBER)", file=sys.stderr)  # fmt: skip
        return 2
    if not seeds:
        print(f"error: --seeds {args.seeds!r} holds no seed", file=sys.stderr)
        return 2
    bad = [s for s in seeds if split_of(s) in ("test", "spent")]
    if bad:
        print(
            f"error: seeds {bad[0]}..: test or spent seeds; probe tuning or validation seeds",
            file=sys.stderr,
        )
        return 2
    scen = load_scenario(args.scenario)
    ground = scen.episode(seeds[0]).terrain
    varies = [s for s in seeds if scen.episode(s).terrain != ground]
    if varies:  # one env per rut cell is built on one ground
        print(f"error: {args.scenario}'s ground differs with the seed (seed {varies[0]} "
              f"against {seeds[0]}); this probe needs one ground", file=sys.stderr)  # fmt: skip
        return 2
    ctrl = make_controller(args.controller)
    rows: list[dict[str, Any]] = []
    episodes: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for cell in cells:
            terrain = terrain_with(ground, {**extra, "rut_cell": cell}, Path(tmp))
            if args.resolution is not None:  # the heightfield's own grid, not the rut map's
                terrain = dataclasses.replace(terrain, resolution=args.resolution)
            env = ScenarioWrapper(
                ProtoExplorerEnv(terrain=terrain, action_layout=ctrl.action_layout)  # type: ignore[arg-type]
            )
            for yaw in yaws:
                res = []
                for s in seeds:
                    ep = dataclasses.replace(scen.episode(s), terrain=terrain)
                    if yaw is not None:
                        x, y, _ = ep.start
                        ep = dataclasses.replace(ep, start=(x, y, yaw if s % 2 == 0 else -yaw))
                    m = run_episode(env, ctrl, ep)
                    res.append((s, m))
                    episodes.append(
                        {
                            "rut_cell": cell,
                            "yaw": "seed" if yaw is None else yaw,
                            "seed": s,
                            "start_yaw": ep.start[2],
                            "success": bool(m["success"]),
                            "energy_per_metre": float(m["energy_per_metre"]),
                            "mean_sinkage_mm": 1000 * float(m["mean_sinkage"]),
                        }
                    )
                ok = [s for s, m in res if m["success"]]
                lo, hi = wilson(len(ok), len(res))
                row = {
                    "rut_cell": cell,
                    "yaw": "seed" if yaw is None else yaw,
                    "goals": len(ok),
                    "n": len(res),
                    "goal_lo": lo,
                    "goal_hi": hi,
                    "energy_per_metre": float(np.mean([m["energy_per_metre"] for _, m in res])),
                    "mean_sinkage_mm": 1000 * float(np.mean([m["mean_sinkage"] for _, m in res])),
                    "failed": " ".join(str(s) for s, m in res if not m["success"]),
                }
                rows.append(row)
                print(
                    f"rut_cell {cell:<7g} yaw {row['yaw']!s:<5} goals {len(ok)}/{len(res)} "
                    f"[{lo:.2f}, {hi:.2f}]  {row['energy_per_metre']:.1f} J/m  "
                    f"{row['mean_sinkage_mm']:.2f} mm  failed: {row['failed'] or '-'}",
                    flush=True,
                )
            env.close()
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        with (out / "probe.csv").open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        with (out / "episodes.csv").open("w", newline="") as fh:  # one row per drive
            w = csv.DictWriter(fh, fieldnames=list(episodes[0]))
            w.writeheader()
            w.writerows(episodes)
        _plot(rows, out / "probe.png", args)
        print(f"wrote {out / 'probe.csv'}, {out / 'episodes.csv'} and {out / 'probe.png'}")
    return 0


def _plot(rows: list[dict[str, Any]], path: Path, args: argparse.Namespace) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    labels = sorted({str(r["yaw"]) for r in rows}, key=lambda v: (v != "seed", v))
    for i, cell in enumerate(sorted({r["rut_cell"] for r in rows}, reverse=True)):
        sel = {str(r["yaw"]): r for r in rows if r["rut_cell"] == cell}
        xs = [j + 0.12 * i for j, lab in enumerate(labels) if lab in sel]
        rs = [sel[lab] for lab in labels if lab in sel]
        p = [r["goals"] / r["n"] for r in rs]
        err = [
            [a - r["goal_lo"] for a, r in zip(p, rs, strict=True)],
            [r["goal_hi"] - a for a, r in zip(p, rs, strict=True)],
        ]
        ax.errorbar(xs, p, yerr=err, fmt="o", capsize=3, label=f"rut cell {cell * 1000:g} mm")
    ax.set_xticks(range(len(labels)), [f"start heading {lab}" for lab in labels], fontsize=8)
    ax.set_ylabel("goals reached (Wilson 95 %)")
    ax.set_title(f"{args.controller} on {args.scenario}, seeds {args.seeds}", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    raise SystemExit(main())
