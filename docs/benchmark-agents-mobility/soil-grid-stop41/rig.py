"""Followers' sinkage on level mars-sand against the rut cell and the heading (docs/soil.md 3.4b).

Straight at 3 rad/s on an 8 x 4 m field from x = -2 m, compiled plugin; mean and SD of each
wheel's sinkage over 4-7 s (the rear wheels have passed the start-up holes by then).

    PYTHONPATH=. python docs/benchmark-agents-mobility/soil-grid-stop41/rig.py 0.025,0.01,0.005
"""

from __future__ import annotations

import argparse

from rover_env.sim.rut_rig import follower_sinkage


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
    for cell in cells:
        for yaw in yaws:
            m, sd = follower_sinkage(cell, yaw)
            m, sd = m * 1000.0, sd * 1000.0
            print(
                f"cell {cell * 1000:5.1f} mm yaw {yaw:.2f}: front {m[:2].round(2)}"
                f" middle {m[2:4].round(2)} ± {sd[2:4].round(2)}"
                f" rear {m[4:].round(2)} ± {sd[4:].round(2)} mm",
                flush=True,
            )


if __name__ == "__main__":
    main()
