"""Followers' sinkage on level mars-sand against the rut cell and the heading (docs/soil.md 3.4b).

Straight at 3 rad/s on an 8 x 4 m field from x = -2 m, compiled plugin; mean and SD of each
wheel's sinkage over 4-7 s (the rear wheels have passed the start-up holes by then).

    PYTHONPATH=. python docs/benchmark-agents-mobility/soil-grid-stop41/rig.py 0.025,0.01,0.005
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import yaml

from rover_env.config import TerrainConfig, from_dict, to_dict
from rover_env.sim.simulator import RoverSim
from rover_env.soil import load_soil


def rig(tmp: Path, cell: float, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    soil = tmp / f"mars-sand-{cell:g}.yaml"
    soil.write_text(yaml.safe_dump({**to_dict(load_soil("mars-sand")), "rut_cell": cell}))
    t = from_dict(TerrainConfig, {"name": "level", "size": [8.0, 4.0], "soil": str(soil)})
    sim = RoverSim(terrain=t, backend="plugin")
    sim.reset(-2.0, 0.0, yaw)
    sim.set_speed_targets([3.0] * 4)
    sim.step(4000)
    sinks = []
    for _ in range(300):
        sim.step(10)
        sinks.append(sim.wheel_truth().sinkage)
    s = np.array(sinks) * 1000.0
    return s.mean(axis=0), s.std(axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cells", help="rut cells in m, comma-separated, e.g. 0.01,0.005")
    ap.add_argument("--yaws", default="0,0.1", help="start headings in rad, comma-separated")
    args = ap.parse_args()
    try:
        cells = [float(c) for c in args.cells.split(",")]
        yaws = [float(y) for y in args.yaws.split(",")]
    except ValueError as e:
        ap.error(f"cells and --yaws must be comma-separated numbers: {e}")
    with tempfile.TemporaryDirectory() as d:
        for cell in cells:
            for yaw in yaws:
                m, sd = rig(Path(d), cell, yaw)
                print(
                    f"cell {cell * 1000:5.1f} mm yaw {yaw:.2f}: front {m[:2].round(2)}"
                    f" middle {m[2:4].round(2)} ± {sd[2:4].round(2)}"
                    f" rear {m[4:].round(2)} ± {sd[4:].round(2)} mm",
                    flush=True,
                )


if __name__ == "__main__":
    main()
