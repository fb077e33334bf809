"""The two log generators side by side: the same commands, the sensors each one reads.

    python benchmarks/compare_generators.py --k-phi 0,5.6e5,2.2e6

Both implement the same rover (the project's simulator, ``make-logs``, and the second
generator, :mod:`rover_env.generators.foreign_logs`); on hard ground they agree closely, and
where they part (loose soil: ruts, dug hole and transient slip in one, none in the other) a
fit of the one to the other's logs has to absorb the difference. Prints wheel angles (rad,
1L..3R) and joint angles theta_1..theta_5 (rad) after a 5 s straight at 2 rad/s and a 5 s
left turn (1.2 / 2.8 rad/s) and a 4 s slow pivot (-0.778 / -0.083 rad/s), from rest after
1.5 s of settling. ``--slip-floor`` and ``--sigma`` set this model's tire form (the model
form diagnose fits), e.g. ``--slip-floor 0.05 --sigma 0.0025`` (stop 30).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from rover_env.config import RoverConfig
from rover_env.generators.foreign_logs import ForeignRover
from rover_env.sim.simulator import RoverSim

LEGS = (
    ("straight", (2.0, 2.0, 2.0, 2.0), 5.0),
    ("left turn", (1.2, 2.8, 1.2, 2.8), 5.0),
    ("slow pivot", (-0.778, -0.083, -0.778, -0.083), 4.0),
)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--k-phi", default="0,5.6e5,2.2e6", help="loose_soil k_phi values (0: hard)")
    ap.add_argument(
        "--slip-floor", type=float, default=0.0, help="this model's TireParams.v_floor (m/s)"
    )
    ap.add_argument("--sigma", type=float, default=None, help="this model's relaxation length (m)")
    args = ap.parse_args()
    t = RoverConfig().tire
    sigma = t.sigma_x if args.sigma is None else args.sigma
    tire = dataclasses.replace(t, v_floor=args.slip_floor, sigma_x=sigma, sigma_y=sigma)
    print(f"this model: slip floor {args.slip_floor:g} m/s, relaxation length {sigma:g} m")
    for k in (float(x) for x in args.k_phi.split(",")):
        ext = {"loose_soil": {"k_phi": k}} if k > 0 else {}
        foreign = ForeignRover(RoverConfig(), ext)  # settles on construction
        own = RoverSim(RoverConfig(tire=tire, extensions=ext), backend="auto")
        own.step(1500)
        p_own, p_for = own.sensors().phi.copy(), foreign.sample()[0].copy()
        print(f"k_phi {k:g} ({'hard ground' if k == 0 else 'loose_soil'})")
        for name, cmd, secs in LEGS:
            own.set_speed_targets(np.array(cmd))
            own.step(round(secs * 1000))
            foreign.run(np.array(cmd), secs)
            so, sf = own.sensors(), foreign.sample()
            print(f"  after the {name}")
            print(f"    wheels own     {np.array2string(so.phi - p_own, precision=3)}")
            print(f"    wheels foreign {np.array2string(sf[0] - p_for, precision=3)}")
            print(f"    theta  own     {np.array2string(so.theta, precision=4)}")
            print(f"    theta  foreign {np.array2string(sf[1], precision=4)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
