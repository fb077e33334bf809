"""The rut map: how deep wheels have compacted loose soil, kept as simulation state.

A wheel leaves a rut as wide as itself, as deep as it stood (docs/soil.md 3.4). The map
stores that on square cells of ``rut_cell`` (5 mm by default, a tenth of the wheel's width)
so that the physics does not depend on the cell:

* **write** the wheel's footprint: every cell a strip of the wheel's width covers, at the
  fraction of the cell it covers (exact for a straight edge), a little behind the contact
  patch, every :data:`RUT_WRITE_EVERY` substeps over a strip stretched to the distance
  travelled; a cell keeps the deepest pass;
* **read** the mean over the follower's width, bilinearly at points spaced at half a cell.

A follower offset by e from its leader then reads d (1 - |e| / b), smooth in e and the same
whichever way the track crosses the grid (within 1.5 % of d at offsets beyond a cell, at any
angle; an aligned follower reads about 0.4 cell / b short, 4 % at 5 mm, from the edges' blur,
and halving the cell halves that: tests/test_rut.py).

Cells are grouped in tiles of ``RUT_TILE`` squared, allocated from a pool the first time a
wheel writes into them, so the map costs memory only where wheels have driven: a 20 x 20 m
field at 5 mm is 16 M cells, a drive of tens of metres touches a few hundred thousand. The
state is one flat array (the same layout in the numpy layer and the compiled plugin):
``[tiles used, writes refused, tile index (ntx * nty; 0: none, k: pool tile k - 1),
pool (RUT_POOL_TILES x RUT_TILE^2)]``. A full pool refuses further new tiles and counts the
refused writes; the simulator raises on the first (:func:`check_overflow`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from rover_env.config import ConfigError
from rover_env.soil import SoilParams

Array = NDArray[np.float64]

RUT_TILE = 16
"""Cells per tile side (a tile of 8 cm at 5 mm cells)."""
RUT_POOL_TILES = 2048
"""Tiles one simulation may touch: 512 k cells, 4 MB of state (about 50 m of straight drive)."""
RUT_WRITE_EVERY = 4
"""A wheel writes its rut every this many substeps, over a strip stretched to twice the
distance it travels meanwhile (at least one cell): every cell it passes is written."""
MAX_RUT_SAMPLES = 512
"""Most footprint read points across a wheel (2 width / cell; the plugin's buffer)."""
MAX_RUT_INDEX = 1_000_000
"""Largest tile index a terrain may ask for (its soil's bounding box in tiles)."""
_HEAD = 2  # tiles used, writes refused


def coverage_cdf(z: Array, w1: float, w2: float) -> Array:
    """Fraction of a square cell whose points lie at most ``z`` from its centre along a unit
    direction whose projections of the cell's sides are ``w1 >= w2 >= 0`` (cell |a_x|,
    cell |a_y|): the distribution of a sum of two uniforms, a trapezoid."""
    zp = z + 0.5 * (w1 + w2)
    tail = w1 + w2 - zp
    with np.errstate(divide="ignore", invalid="ignore"):  # w2 = 0: those branches unused
        upper = 1.0 - tail * tail / (2.0 * w1 * w2)
        lower = zp * zp / (2.0 * w1 * w2)
    out = np.where(zp <= w1, (zp - 0.5 * w2) / w1, upper)
    out = np.where(zp <= w2, lower, out)
    out = np.where(zp >= w1 + w2, 1.0, out)
    return np.where(zp <= 0.0, 0.0, out)


class RutGrid(NamedTuple):
    """Geometry of the rut map: cell (ix, iy) covers x0 + ix*cell, y0 + iy*cell.

    The map itself is simulation state (the numpy tire layer's or the plugin's), in the
    layout of the module docstring; these methods read and write it.
    """

    x0: float
    y0: float
    cell: float
    nx: int
    ny: int

    @classmethod
    def covering(
        cls, lo: tuple[float, float], hi: tuple[float, float], soils: tuple[SoilParams, ...]
    ) -> RutGrid:
        """The map over the box [lo, hi] (the soil's extent) at the finest soil's cell."""
        if not soils:
            return cls(0.0, 0.0, 1.0, 0, 0)
        cell = min(sp.rut_cell for sp in soils)
        nx = max(1, int(np.ceil((hi[0] - lo[0]) / cell)))
        ny = max(1, int(np.ceil((hi[1] - lo[1]) / cell)))
        grid = cls(float(lo[0]), float(lo[1]), cell, nx, ny)
        if grid.index_size > MAX_RUT_INDEX:
            raise ConfigError(
                f"soil box {lo}..{hi} with rut_cell {cell} m needs {grid.index_size} rut tiles"
                f" of {RUT_TILE}x{RUT_TILE} cells, more than {MAX_RUT_INDEX}; use a smaller soil"
                " area or a coarser rut_cell"
            )
        return grid

    @property
    def ntx(self) -> int:
        return -(-self.nx // RUT_TILE)

    @property
    def nty(self) -> int:
        return -(-self.ny // RUT_TILE)

    @property
    def index_size(self) -> int:
        return self.ntx * self.nty if self.nx * self.ny else 0

    @property
    def state_size(self) -> int:
        """Numbers of state this map needs (0 without soil)."""
        if not self.index_size:
            return 0
        return _HEAD + self.index_size + RUT_POOL_TILES * RUT_TILE * RUT_TILE

    def new_state(self) -> Array:
        return np.zeros(self.state_size)

    @staticmethod
    def clear(state: Array, index_size: int) -> None:
        """Forget every rut (tiles are zeroed when they are next taken from the pool)."""
        state[..., : _HEAD + index_size] = 0.0

    def _index_at(self, ix: NDArray[np.int64], iy: NDArray[np.int64]) -> NDArray[np.int64]:
        """Where in the state the tile index entry of cells (ix, iy) (inside the map) lies."""
        return _HEAD + (iy // RUT_TILE) * self.ntx + ix // RUT_TILE

    def _cell_at(
        self, tile: NDArray[np.int64], ix: NDArray[np.int64], iy: NDArray[np.int64]
    ) -> NDArray[np.int64]:
        """Where in the state cells (ix, iy) of pool tiles ``tile`` (1-based) lie."""
        size = RUT_TILE * RUT_TILE
        return (
            _HEAD + self.index_size + (tile - 1) * size + (iy % RUT_TILE) * RUT_TILE + ix % RUT_TILE
        )

    def cells(self, state: Array, ix: NDArray[np.int64], iy: NDArray[np.int64]) -> Array:
        """Depth stored at cells (ix, iy); 0 outside the map and in tiles never written."""
        ok = (ix >= 0) & (ix < self.nx) & (iy >= 0) & (iy < self.ny)
        cx = np.where(ok, ix, 0)
        cy = np.where(ok, iy, 0)
        tile = state[self._index_at(cx, cy)].astype(np.int64)
        return np.where(ok & (tile > 0), state[self._cell_at(np.maximum(tile, 1), cx, cy)], 0.0)

    def lookup(self, state: Array, x: Array, y: Array) -> Array:
        """Bilinear rut depth at points (0 outside the map)."""
        out = np.zeros(np.shape(x))
        if self.index_size == 0:
            return out
        inv = 1.0 / self.cell  # a product per point, as the plugin (no division per read)
        gx = (np.asarray(x) - self.x0) * inv - 0.5
        gy = (np.asarray(y) - self.y0) * inv - 0.5
        ix = np.floor(gx)
        iy = np.floor(gy)
        fx = gx - ix
        fy = gy - iy
        for dx, dy, wgt in (
            (0, 0, (1 - fx) * (1 - fy)),
            (1, 0, fx * (1 - fy)),
            (0, 1, (1 - fx) * fy),
            (1, 1, fx * fy),
        ):
            val = self.cells(state, (ix + dx).astype(np.int64), (iy + dy).astype(np.int64))
            out = out + wgt * val
        return out

    def samples(self, width: float) -> int:
        """Points across a wheel for its footprint read: at most half a cell apart."""
        k = max(2, math.ceil(2.0 * width / self.cell))
        if k > MAX_RUT_SAMPLES:
            raise ConfigError(
                f"rut_cell {self.cell} m is too fine for a wheel {width} m wide: its footprint"
                f" read needs {k} points, more than {MAX_RUT_SAMPLES}; use rut_cell >="
                f" {2.0 * width / MAX_RUT_SAMPLES:.2g} m"
            )
        return k

    def footprint_depth(self, state: Array, point: Array, axis: Array, width: float) -> Array:
        """Mean rut depth across each wheel's width at its contact point (n,): ``point``
        (n, >=2) contact points, ``axis`` (n, >=2) spin axes (their horizontal part)."""
        n = len(point)
        if self.index_size == 0 or n == 0:
            return np.zeros(n)
        k = self.samples(width)
        ax, ay = across_unit(axis)
        t = (np.arange(k) + 0.5) * (width / k) - 0.5 * width
        x = point[:, 0][:, None] + t[None, :] * ax[:, None]
        y = point[:, 1][:, None] + t[None, :] * ay[:, None]
        return np.mean(self.lookup(state, x, y), axis=1)

    def write_footprint(
        self,
        state: Array,
        qx: float,
        qy: float,
        ax: float,
        ay: float,
        depth: float,
        width: float,
        length: float,
    ) -> None:
        """Compact a strip ``width`` across (unit (ax, ay), horizontal) and ``length`` along,
        centred at (qx, qy), to ``depth``: each cell whose centre lies within the length keeps
        max(its depth, depth x the fraction of it inside the strip's width). Cells and new
        tiles in row order (iy, then ix)."""
        c = self.cell
        ux, uy = -ay, ax
        reach = 0.5 * width + c
        hx = abs(ux) * 0.5 * length + abs(ax) * reach
        hy = abs(uy) * 0.5 * length + abs(ay) * reach
        ix0 = max(math.floor((qx - hx - self.x0) / c), 0)
        ix1 = min(math.floor((qx + hx - self.x0) / c), self.nx - 1)
        iy0 = max(math.floor((qy - hy - self.y0) / c), 0)
        iy1 = min(math.floor((qy + hy - self.y0) / c), self.ny - 1)
        if ix0 > ix1 or iy0 > iy1:
            return
        iy, ix = np.mgrid[iy0 : iy1 + 1, ix0 : ix1 + 1]
        ix = ix.ravel()
        iy = iy.ravel()
        px = self.x0 + (ix + 0.5) * c - qx
        py = self.y0 + (iy + 0.5) * c - qy
        s = px * ux + py * uy
        t = px * ax + py * ay
        w1 = c * max(abs(ax), abs(ay))
        w2 = c * min(abs(ax), abs(ay))
        f = coverage_cdf(0.5 * width - t, w1, w2) - coverage_cdf(-0.5 * width - t, w1, w2)
        val = depth * f
        cur = self.cells(state, ix, iy)
        keep = (np.abs(s) <= 0.5 * length) & (val > cur)
        if not keep.any():
            return
        ix, iy, val = ix[keep], iy[keep], val[keep]
        idx = self._index_at(ix, iy)
        size = RUT_TILE * RUT_TILE
        base = _HEAD + self.index_size
        ok = np.ones(len(idx), dtype=bool)
        for j in np.flatnonzero(state[idx] == 0.0):  # new tiles in row order, as the plugin
            if state[idx[j]] != 0.0:  # taken by an earlier cell of this write
                continue
            used = int(state[0])
            if used >= RUT_POOL_TILES:
                state[1] += 1.0
                ok[j] = False
                continue
            state[0] = used + 1
            state[idx[j]] = used + 1
            state[base + used * size : base + (used + 1) * size] = 0.0
        at = self._cell_at(state[idx].astype(np.int64), ix, iy)
        state[at[ok]] = val[ok]


def across_unit(axis: Array) -> tuple[Array, Array]:
    """Unit horizontal direction of each spin axis (a wheel lying on its side: x)."""
    h = np.hypot(axis[:, 0], axis[:, 1])
    safe = h > 1e-9
    hh = np.where(safe, h, 1.0)
    return np.where(safe, axis[:, 0] / hh, 1.0), np.where(safe, axis[:, 1] / hh, 0.0)


def refused_writes(state: Array) -> float:
    """How many rut writes a full pool refused (0 without soil)."""
    return float(state[..., 1].max()) if state.shape[-1] else 0.0


def check_overflow(refused: float) -> None:
    """Raise if the rut map's pool has refused writes (:func:`refused_writes`): the map
    would be silently wrong."""
    if refused > 0:
        raise RuntimeError(
            f"rut map full: the wheels drove over more than {RUT_POOL_TILES} tiles of"
            f" {RUT_TILE}x{RUT_TILE} rut cells since the last reset; reset the episode sooner"
            " or use a coarser rut_cell (rover_env.rut.RUT_POOL_TILES)"
        )
