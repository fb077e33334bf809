"""A rover rig for the rut map: how deep the followers run in the leaders' ruts.

Straight at 3 rad/s on a level 8 x 4 m field of one soil from x = -2 m (compiled plugin);
each wheel's sinkage is averaged over 4-7 s, after the rear wheels have passed the holes the
others dug while starting. That the middle and rear wheels' figures do not depend on the rut
map's cell or the heading is docs/soil.md 3.4b's convergence check.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from rover_env.config import RoverConfig, TerrainConfig, from_dict
from rover_env.sim.simulator import RoverSim
from rover_env.soil import soil_variant


def follower_sinkage(
    rut_cell: float,
    yaw: float,
    soil: str = "mars-sand",
    backend: str = "plugin",
    rover: RoverConfig | str = "proto_explorer",
) -> tuple[np.ndarray, np.ndarray]:
    """Mean and SD (m) of each wheel's sinkage (1L..3R) over 4-7 s of the drive, with the
    soil's rut map at ``rut_cell`` (m), starting at heading ``yaw`` (rad) to the grid;
    sampled every 10 ms at any ``rover`` timestep."""
    with tempfile.TemporaryDirectory() as d:
        path = soil_variant(soil, {"rut_cell": rut_cell}, Path(d))
        t = from_dict(TerrainConfig, {"name": "level", "size": [8.0, 4.0], "soil": str(path)})
        sim = RoverSim(rover, terrain=t, backend=backend)
    sim.reset(-2.0, 0.0, yaw)
    sim.set_speed_targets([3.0] * 4)
    sim.step(round(4.0 / sim.dt))
    sinks = []
    for _ in range(300):
        sim.step(round(0.01 / sim.dt))
        sinks.append(sim.wheel_truth().sinkage)
    s = np.array(sinks)
    return s.mean(axis=0), s.std(axis=0)
