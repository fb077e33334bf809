"""Analytic ground surface and friction map that the tire layer reads (numpy only).

The ground is a smooth function h(x, y) (slope + sinusoidal bumps + seeded Fourier
roughness) with an analytic gradient, so each wheel's contact point and normal are exact
and continuous. MuJoCo gets a heightfield sampled from the same function for rendering and
for chassis/obstacle contacts only: wheels never touch it through MuJoCo.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from rover_env.config import ConfigError, TerrainConfig
from rover_env.rut import RutGrid
from rover_env.soil import SoilParams, load_soil
from rover_env.tire import TireParams

Array = NDArray[np.float64]


class WheelContact(NamedTuple):
    """Per-wheel contact geometry, world frame; arrays of shape (n,) or (n, 3)."""

    point: Array
    """Contact point on the ground surface."""
    normal: Array
    """Unit ground normal at the contact point."""
    delta: Array
    """Tire compression along the normal (m); negative when the wheel is off the ground."""


class TerrainArrays(NamedTuple):
    """The numbers that define a :class:`Terrain`'s surface and patches (what the compiled
    tire plugin's terrain block carries; read-only by convention)."""

    gx: float
    """Slope gradient dh/dx."""
    gy: float
    amp: Array
    """Relief wave components: amplitude, wave vector (k, 2), phase, start of each wave."""
    k: Array
    phase: Array
    start: Array
    patch_lo: Array
    """Friction/soil patches: lower and upper corners (p, 2), (mu_x, mu_y) (p, 2), soil
    index (p,) (0: no soil, i: ``soils[i - 1]``)."""
    patch_hi: Array
    patch_mu: Array
    patch_soil: NDArray[np.int64]


class Terrain:
    """Ground surface h(x, y), its normal, and per-point friction."""

    def __init__(
        self,
        cfg: TerrainConfig,
        tire: TireParams | None = None,
        soil_over_ground: SoilParams | None = None,
    ) -> None:
        tire = tire or TireParams()
        self.cfg = cfg
        self.flat = cfg.is_flat
        self._gx = float(np.tan(np.radians(cfg.slope_deg[0])))
        self._gy = float(np.tan(np.radians(cfg.slope_deg[1])))
        # Each wave component: amplitude A, wave vector k (2,), phase p, start along k.
        amps: list[float] = []
        ks: list[tuple[float, float]] = []
        phases: list[float] = []
        starts: list[float] = []
        for b in cfg.bumps:
            th = np.radians(b.direction_deg)
            kk = 2 * np.pi / b.wavelength
            amps.append(b.amplitude)
            ks.append((kk * np.cos(th), kk * np.sin(th)))
            phases.append(b.phase)
            starts.append(b.start * kk)
        r = cfg.roughness
        if r.rms > 0:
            rng = np.random.default_rng(r.seed)
            # Isotropic modes with wavelengths spread around 2*pi*correlation_length.
            lam = r.correlation_length * 2 * np.pi * rng.uniform(0.5, 2.0, r.modes)
            ang = rng.uniform(0, 2 * np.pi, r.modes)
            kmag = 2 * np.pi / lam
            a = r.rms * np.sqrt(2.0 / r.modes) * np.ones(r.modes)
            for i in range(r.modes):
                amps.append(float(a[i]))
                ks.append((float(kmag[i] * np.cos(ang[i])), float(kmag[i] * np.sin(ang[i]))))
                phases.append(float(rng.uniform(0, 2 * np.pi)))
                starts.append(-np.inf)
        self._amp = np.asarray(amps, dtype=float)
        self._k = np.asarray(ks, dtype=float).reshape(-1, 2)
        self._phase = np.asarray(phases, dtype=float)
        self._start = np.asarray(starts, dtype=float)
        self.mu_x_default = cfg.mu_x if cfg.mu_x is not None else tire.mu_x
        self.mu_y_default = cfg.mu_y if cfg.mu_y is not None else tire.mu_y
        p = cfg.patches
        self._patch_lo = np.array(
            [[c[0] - s[0] / 2, c[1] - s[1] / 2] for c, s in ((q.center, q.size) for q in p)]
        ).reshape(-1, 2)
        self._patch_hi = np.array(
            [[c[0] + s[0] / 2, c[1] + s[1] / 2] for c, s in ((q.center, q.size) for q in p)]
        ).reshape(-1, 2)
        # Soil patches keep the ground's friction in the table: the soil model ignores it.
        self._patch_mu = np.array(
            [[self.mu_x_default, self.mu_y_default] if q.soil else [q.mu_x, q.mu_y] for q in p]
        ).reshape(-1, 2)
        self.patch_names: tuple[str, ...] = ("ground", *(q.name for q in p))
        # Loose soil: distinct presets numbered from 1 (0 = hard ground, the Gim layer).
        names = [n for n in (cfg.soil, *(q.soil for q in p)) if n]
        unique = list(dict.fromkeys(names))
        soils = [_changed(load_soil(n), cfg.soil_changes.get(n)) for n in unique]
        self.ground_soil = unique.index(cfg.soil) + 1 if cfg.soil else 0
        if soil_over_ground is not None:  # a model extension's soil (loose_soil) replaces cfg.soil
            soils.append(soil_over_ground)
            self.ground_soil = len(soils)
        self.soils: tuple[SoilParams, ...] = tuple(soils)
        self._patch_soil = np.array(
            [unique.index(q.soil) + 1 if q.soil else 0 for q in p], dtype=np.int64
        )
        self.rut_grid = RutGrid.covering(*self._soil_box(), self.soils)

    def _soil_box(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """Where the ground is loose soil: the arena, or the box around the soil patches."""
        sx, sy = self.cfg.size
        if self.ground_soil or not self._patch_soil.any():
            return (-sx / 2, -sy / 2), (sx / 2, sy / 2)
        on = self._patch_soil > 0
        lo = self._patch_lo[on].min(axis=0)
        hi = self._patch_hi[on].max(axis=0)
        return (float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1]))

    @property
    def has_soil(self) -> bool:
        return bool(self.soils)

    def arrays(self) -> TerrainArrays:
        """The surface's defining numbers (the compiled plugin's copy of this terrain)."""
        return TerrainArrays(
            self._gx,
            self._gy,
            self._amp,
            self._k,
            self._phase,
            self._start,
            self._patch_lo,
            self._patch_hi,
            self._patch_mu,
            self._patch_soil,
        )

    # ------------------------------------------------------------------ surface
    def height_and_gradient(self, x: Array, y: Array) -> tuple[Array, Array, Array]:
        """h, dh/dx, dh/dy at points (any matching shapes)."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        h = self._gx * x + self._gy * y
        hx = np.full_like(h, self._gx)
        hy = np.full_like(h, self._gy)
        if self._amp.size:
            s = x[..., None] * self._k[:, 0] + y[..., None] * self._k[:, 1]
            on = s >= self._start
            arg = s + self._phase
            h = h + np.sum(np.where(on, self._amp * np.sin(arg), 0.0), axis=-1)
            c = np.where(on, self._amp * np.cos(arg), 0.0)
            hx = hx + np.sum(c * self._k[:, 0], axis=-1)
            hy = hy + np.sum(c * self._k[:, 1], axis=-1)
        return h, hx, hy

    def height(self, x: Array, y: Array) -> Array:
        return self.height_and_gradient(x, y)[0]

    def friction(self, x: Array, y: Array) -> tuple[Array, Array, NDArray[np.int64]]:
        """mu_x, mu_y and patch index (0 = default ground, i = patches[i-1]); last patch wins."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        mux = np.full(x.shape, self.mu_x_default)
        muy = np.full(x.shape, self.mu_y_default)
        idx = np.zeros(x.shape, dtype=np.int64)
        for i in range(self._patch_mu.shape[0]):
            inside = (
                (x >= self._patch_lo[i, 0])
                & (x <= self._patch_hi[i, 0])
                & (y >= self._patch_lo[i, 1])
                & (y <= self._patch_hi[i, 1])
            )
            mux = np.where(inside, self._patch_mu[i, 0], mux)
            muy = np.where(inside, self._patch_mu[i, 1], muy)
            idx = np.where(inside, i + 1, idx)
        return mux, muy, idx

    def soil_index(self, x: Array, y: Array) -> NDArray[np.int64]:
        """Soil at points: 0 = hard ground (Gim layer), k = ``soils[k-1]``; last patch wins."""
        x = np.asarray(x, dtype=float)
        idx = np.full(x.shape, self.ground_soil, dtype=np.int64)
        if not self.soils:
            return idx
        y = np.asarray(y, dtype=float)
        for i in range(self._patch_mu.shape[0]):
            inside = (
                (x >= self._patch_lo[i, 0])
                & (x <= self._patch_hi[i, 0])
                & (y >= self._patch_lo[i, 1])
                & (y <= self._patch_hi[i, 1])
            )
            idx = np.where(inside, self._patch_soil[i], idx)
        return idx

    # ------------------------------------------------------------------ wheel contact
    def wheel_contact(
        self, centre: Array, axis: Array, radius: float, iterations: int = 3
    ) -> WheelContact:
        """Contact of thin discs (centre (n,3), unit spin axis (n,3)) with the surface.

        The deepest rim point lies where the rim direction opposes the surface normal
        projected into the wheel plane; for a plane one pass is exact, for smooth ground a
        few fixed-point passes converge (curvature radius of the ground >> wheel radius).
        Compression is measured along the normal: for a plane at distance D from the hub
        and camber gamma it is radius*cos(gamma) - D, the thin-disc answer.
        """
        n = np.tile(np.array([0.0, 0.0, 1.0]), (centre.shape[0], 1))
        if not self.flat:
            _, hx, hy = self.height_and_gradient(centre[:, 0], centre[:, 1])
            n = _normal(hx, hy)
        for it in range(1 if self.flat else iterations):
            # Rim direction: minus the normal projected into the wheel plane.
            u = -(n - np.sum(n * axis, axis=1, keepdims=True) * axis)
            u /= np.linalg.norm(u, axis=1, keepdims=True)
            q = centre + radius * u
            if self.flat:
                h = np.zeros(q.shape[0])
                break
            h, hx, hy = self.height_and_gradient(q[:, 0], q[:, 1])
            if it < iterations - 1:
                n = _normal(hx, hy)
        # Vertical gap to the surface, converted to the normal direction.
        delta = (h - q[:, 2]) * n[:, 2]
        point = q + delta[:, None] * n
        return WheelContact(point=point, normal=n, delta=delta)

    def sample_grid(self, nx: int, ny: int) -> tuple[Array, Array, Array]:
        """Heights on a regular grid covering the arena (rows along y), for MuJoCo's hfield."""
        sx, sy = self.cfg.size
        xs = np.linspace(-sx / 2, sx / 2, nx)
        ys = np.linspace(-sy / 2, sy / 2, ny)
        gx, gy = np.meshgrid(xs, ys)
        return xs, ys, self.height(gx, gy)


def _changed(soil: SoilParams, changes: dict[str, float] | None) -> SoilParams:
    """``soil`` with the terrain's ``soil_changes`` for it (a family's drawn soil)."""
    if not changes:
        return soil
    unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(soil)} - {"name"})
    if unknown or "name" in changes:
        raise ConfigError(
            f"terrain.soil_changes.{soil.name}: unknown soil field(s) {', '.join(unknown or ['name'])}"
        )
    values: dict[str, Any] = dict(changes)  # every changed field is a number (checked above)
    return dataclasses.replace(soil, **values)


def _normal(hx: Array, hy: Array) -> Array:
    n = np.stack([-hx, -hy, np.ones_like(hx)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)
