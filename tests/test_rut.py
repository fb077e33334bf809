"""The rut map (rover_env/rut.py): footprint writes and reads that do not depend on the grid."""

from __future__ import annotations

import numpy as np
import pytest

from rover_env.config import ConfigError, TerrainConfig, from_dict
from rover_env.rut import (
    RUT_POOL_TILES,
    RUT_TILE,
    RutGrid,
    check_overflow,
    coverage_cdf,
    refused_writes,
)
from rover_env.soil import SoilParams
from rover_env.terrain import Terrain

B = 0.05  # the rover's wheel width


def _grid(cell: float, size: float = 2.0) -> RutGrid:
    return RutGrid.covering(
        (-size / 2, -size / 2), (size / 2, size / 2), (SoilParams(rut_cell=cell),)
    )


def _drive(g: RutGrid, state: np.ndarray, heading: float, y0: float, depth: float) -> None:
    """One wheel's pass along ``heading`` through the origin offset ``y0`` across: a write
    every 0.8 mm of travel, as a wheel at 0.2 m/s leaves every 4 substeps of 1 ms."""
    ux, uy = np.cos(heading), np.sin(heading)
    ax, ay = -uy, ux
    length = max(g.cell, 2 * 0.0008)
    for s in np.arange(-0.3, 0.3, 0.0008):
        g.write_footprint(state, s * ux + y0 * ax, s * uy + y0 * ay, ax, ay, depth, B, length)


def test_coverage_cdf_is_the_fraction_of_the_cell() -> None:
    """The closed form against counting points of the cell, for a direction across the grid."""
    rng = np.random.default_rng(0)
    c, ang = 0.005, 0.4
    a = np.array([np.cos(ang), np.sin(ang)])
    pts = rng.uniform(-c / 2, c / 2, size=(200_000, 2)) @ a
    w1, w2 = c * max(abs(a)), c * min(abs(a))
    z = np.linspace(-0.004, 0.004, 41)
    counted = np.array([(pts <= zz).mean() for zz in z])
    np.testing.assert_allclose(coverage_cdf(z, w1, w2), counted, atol=0.004)
    assert coverage_cdf(np.array([0.0]), c, 0.0)[0] == 0.5  # along the grid: a uniform


@pytest.mark.parametrize("heading", [0.0, 0.3, 0.785])
def test_a_follower_reads_the_rut_it_overlaps(heading: float) -> None:
    """A follower offset e from the leader's line reads d (1 - |e| / b) on average over its
    width, the same whichever way the track crosses the grid and wherever its lines fall."""
    g = _grid(0.005)
    depth = 0.01
    rng = np.random.default_rng(1)
    for y0 in rng.uniform(-0.005, 0.005, 2):
        state = g.new_state()
        _drive(g, state, heading, y0, depth)
        ux, uy = np.cos(heading), np.sin(heading)
        ax, ay = -uy, ux
        for e in (0.0, 0.0125, 0.025, 0.04, 0.06):
            p = np.array([[0.1 * ux + (y0 + e) * ax, 0.1 * uy + (y0 + e) * ay]])
            got = g.footprint_depth(state, p, np.array([[ax, ay, 0.0]]), B)[0]
            want = depth * max(0.0, 1.0 - e / B)
            # the edges' blur of one cell costs an aligned follower ~0.4 cell / b of the depth
            tol = 0.05 * depth if e == 0.0 else 0.015 * depth
            assert abs(got - want) <= tol, (heading, y0, e, got, want)


def test_the_map_converges_with_the_cell() -> None:
    """Halving the cell halves the aligned follower's shortfall (first order), and the
    reading no longer depends on where the grid's lines fall."""
    short = []
    for cell in (0.01, 0.005, 0.0025):
        g = _grid(cell)
        reads = []
        for y0 in (0.0, 0.3 * cell, 0.5 * cell, 0.8 * cell):
            state = g.new_state()
            _drive(g, state, 0.2, y0, 0.01)
            ax, ay = -np.sin(0.2), np.cos(0.2)
            p = np.array([[0.1 * np.cos(0.2) + y0 * ax, 0.1 * np.sin(0.2) + y0 * ay]])
            reads.append(g.footprint_depth(state, p, np.array([[ax, ay, 0.0]]), B)[0])
        # where the grid's lines fall moves it by less than a quarter of cell / b
        # (measured: 3.8 %, 1.7 %, 0.4 % of the depth at 10, 5, 2.5 mm)
        assert np.ptp(reads) < 0.25 * (cell / B) * 0.01
        short.append(0.01 - np.mean(reads))
    assert short[0] > short[1] > short[2] > 0
    assert short[1] / short[0] == pytest.approx(0.5, abs=0.12)
    assert short[2] / short[1] == pytest.approx(0.5, abs=0.12)


def test_a_full_pool_refuses_and_the_simulator_is_told() -> None:
    g = _grid(0.005, size=40.0)  # 8000 x 8000 cells: far more tiles than the pool
    state = g.new_state()
    tile = RUT_TILE * g.cell
    # one narrow write in each of separate tiles (inside a cell: a write one cell long
    # centred on a cell line may fall between the cells' centres; a pass covers them)
    for k in range(RUT_POOL_TILES + 3):
        x = -19.9 + (k % 200) * tile * 2 + 0.3 * g.cell
        y = -19.9 + (k // 200) * tile * 2 + 0.3 * g.cell
        g.write_footprint(state, x, y, 0.0, 1.0, 0.01, 0.001, g.cell)
    assert state[0] == RUT_POOL_TILES
    assert refused_writes(state) > 0
    with pytest.raises(RuntimeError, match="rut map full"):
        check_overflow(refused_writes(state))
    RutGrid.clear(state, g.index_size)
    assert refused_writes(state) == 0 and not state[: 2 + g.index_size].any()


def test_the_map_covers_the_soil_only() -> None:
    """A soil patch gets a map over the patch, not the arena; hard ground none."""
    t = Terrain(
        from_dict(
            TerrainConfig,
            {
                "name": "p",
                "size": [20.0, 10.0],
                "patches": [
                    {"name": "s", "center": [3.5, 0.0], "size": [6.0, 4.0], "soil": "mars-sand"}
                ],
            },
        )
    )
    g = t.rut_grid
    assert (g.x0, g.y0) == (0.5, -2.0)
    assert g.nx * g.cell == pytest.approx(6.0) and g.ny * g.cell == pytest.approx(4.0)
    hard = Terrain(from_dict(TerrainConfig, {"name": "h", "size": [20.0, 10.0]}))
    assert hard.rut_grid.state_size == 0


def test_a_cell_too_fine_for_the_wheel_is_refused() -> None:
    g = _grid(0.0001, size=0.5)
    with pytest.raises(ConfigError, match=r"rut_cell 0.0001 m is too fine.*1000 points"):
        g.samples(B)
    assert _grid(0.005).samples(B) == 20


def test_backends_agree_across_a_patch_and_off_its_map() -> None:
    """numpy and the plugin (to the last bits, as on soil elsewhere) on a rover that drives onto a small soil patch
    (a map of its size only), across it and off it, so the reads and writes meet every edge
    of the map and of its tiles; the followers' ruts are written and read back."""
    from rover_env.sim.simulator import RoverSim

    t = from_dict(
        TerrainConfig,
        {
            "name": "patch",
            "size": [6.0, 4.0],
            "patches": [
                {"name": "s", "center": [0.1, 0.03], "size": [0.7, 0.5], "soil": "mars-sand"}
            ],
        },
    )
    a = RoverSim(terrain=t, backend="numpy")
    b = RoverSim(terrain=t, backend="plugin")
    for sim in (a, b):
        sim.reset(-0.7, 0.0, 0.15)
        sim.set_speed_targets([4.0] * 4)
        sim.step(5000)
    np.testing.assert_allclose(a.data.qpos, b.data.qpos, rtol=0, atol=1e-12)
    pv = b._plugin
    assert pv is not None
    rut_b = pv.rut_state(b.data.plugin_state)
    t_map = a.terrain.rut_grid
    np.testing.assert_allclose(a.tires.rut, rut_b, rtol=0, atol=1e-12)
    head = 2 + t_map.index_size  # counts and tile index: the same tiles, taken in order
    np.testing.assert_array_equal(a.tires.rut[:head], rut_b[:head])
    assert rut_b[0] > 4 and rut_b[1] == 0  # tiles taken, none refused
    assert a.data.qpos[0] > 0.7  # it left the patch on the far side
