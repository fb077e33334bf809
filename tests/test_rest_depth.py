"""A rover is put down at the depth its ground holds it at (``RoverSim.rest_depth``).

The tire's 27 mm static deflection, used as the start depth on loose soil too, is a loaded
spring in a stiff soil: at k_phi 2.5e7 it threw the rover 0.7 m up and the calibration
replay, which starts every window unsettled, diverged on stiff soils (stop 83's probe: joint
loss 52,000 at k_phi 5e7 against 63 at 1.25e7 and 128 on hard ground)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rover_env.calibration import residuals as rs
from rover_env.calibration.replay import Replayer, ReplaySettings, make_windows, prepare
from rover_env.config import load_rover
from rover_env.generators.make_logs import make_logs
from rover_env.logs import read_log
from rover_env.sim.model import static_deflection
from rover_env.sim.simulator import RoverSim
from rover_env.soil import soil_forces

CFG = load_rover()


def _on_soil(k_phi: float) -> RoverSim:
    cfg = dataclasses.replace(CFG, extensions={"loose_soil": {"k_phi": k_phi, "memory": 0.0}})
    return RoverSim(cfg, "flat", backend="plugin", contacts=False, sensors=False)


def test_rest_depth_carries_a_sixth_of_the_weight() -> None:
    assert RoverSim(CFG, "flat", backend="plugin").rest_depth(0.0, 0.0) == pytest.approx(
        static_deflection(CFG), rel=1e-12
    )
    sim = _on_soil(2.2e6)
    h = sim.rest_depth(0.0, 0.0)
    g, soil = CFG.geometry, sim.terrain.soils[0]
    fz = float(soil_forces(0.1, 0.0, 0.1, h, g.wheel_radius, g.wheel_width, soil).F_z)
    assert fz == pytest.approx(CFG.masses.total * 9.81 / 6, rel=1e-4)
    assert 1e-3 < h < static_deflection(CFG) / 2  # a soil, not the tire


@pytest.mark.parametrize("k_phi", [2.2e6, 2.5e7])
def test_a_sunk_start_stays_on_the_ground(k_phi: float) -> None:
    """Driven away unsettled, the rover's chassis rises by less than a millimetre (it sinks
    and pitches as the wheels take the pull); put down at the tire's depth, it jumps."""
    heights = {}
    for sunk in (True, False):
        sim = _on_soil(k_phi)
        sim.reset(settle=0.0, sunk=sunk)
        z0 = float(sim.data.qpos[2])
        sim.set_speed_targets([1.5] * 4)
        z = []
        for _ in range(100):
            sim.step(10)
            z.append(float(sim.data.qpos[2]) - z0)
        heights[sunk] = max(z)
    assert heights[True] < 1e-3, heights
    assert heights[False] > 0.01, heights


def test_stiff_soil_replays_without_diverging(tmp_path_factory: pytest.TempPathFactory) -> None:
    """A log of a stiff soil replays at its truth as closely as a log of hard ground does."""
    st = ReplaySettings()
    mean_square = {}
    for name, ext in (("stiff", {"loose_soil": {"k_phi": 5e7, "memory": 0.0}}), ("hard", {})):
        paths = make_logs(
            tmp_path_factory.mktemp(name), ext, drives=1, seed=3, duration=14.0, progress=False
        )
        cfg = dataclasses.replace(CFG, extensions=ext)
        prepared = [prepare(read_log(p), cfg, p.name, st) for p in paths]
        windows = make_windows(prepared, st)[:2]
        res = Replayer(cfg, st).run(prepared, windows)
        mean_square[name] = float(np.mean(rs.window_losses(res, rs.noise_floor(prepared))))
    assert mean_square["stiff"] < 3.0 * mean_square["hard"], mean_square
