"""MJCF for the tire plugin, its terrain block, and typed views of its ``plugin_state``.

The rover-side constants (wheel, joint and motor names, radius, tire parameters, anti-windup
bound) are plugin config attributes, fixed at compile time. The ground lives in a
``<numeric>`` element that the plugin reads on every substep instead: a compiled model's
config strings cannot change, but ``model.numeric_data`` can, so ``RoverSim.set_terrain``
keeps working without recompiling and ``mujoco.batch`` can give each simulation its own
ground (``batch.expand("numeric_data")``). Numbers are written with ``repr`` and parsed
back exactly, so the plugin sees the very floats :class:`~rover_env.terrain.Terrain` uses.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import NamedTuple
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np
from numpy.typing import NDArray

from rover_env.config import DRIVEN_WHEELS, WHEELS, RoverConfig
from rover_env.rut import RUT_POOL_TILES, RUT_TILE, RutGrid
from rover_env.sim.fast.build import PLUGIN_NAME, load_plugin
from rover_env.terrain import Terrain
from rover_env.tire import TireParams

__all__ = [
    "INSTANCE",
    "TERRAIN_NUMERIC",
    "PluginView",
    "StateLayout",
    "TruthArrays",
    "inject_plugin",
    "terrain_block",
]

INSTANCE = "rover_env_tires"
TERRAIN_NUMERIC = "rover_env_terrain"
CONTACT_ITERATIONS = 3
"""Fixed-point passes of the contact search off flat ground (Terrain.wheel_contact's default)."""
MIN_PATCH_CAPACITY = 16
"""Friction patches a compiled model can take later (set_terrain), at the least."""

MIN_SOIL_CAPACITY = 4
"""Soil presets a compiled model can take later (set_terrain), at the least."""

SCHEDULE_ROWS = 64
"""Substeps of speed targets the plugin can queue at once (tire_plugin.c's SCHED_ROWS)."""

_TERRAIN_VERSION = 3
_HEADER = 19
_WAVE = 5
_PATCH = 7
_SOIL = 16
_TRUTH = 17

Array = NDArray[np.float64]


def _num(x: float) -> str:
    return repr(float(x))


def terrain_block(
    terrain: Terrain, wave_capacity: int, patch_capacity: int, soil_capacity: int
) -> Array:
    """The plugin's ground description (layout documented in tire_plugin.c)."""
    t = terrain
    a = t.arrays()
    amp, k, phase, start = a.amp, a.k, a.phase, a.start
    lo, hi, mu = a.patch_lo, a.patch_hi, a.patch_mu
    nwave, npatch, nsoil = len(amp), len(mu), len(t.soils)
    if nwave > wave_capacity or npatch > patch_capacity or nsoil > soil_capacity:
        raise ValueError(
            f"terrain has {nwave} wave components, {npatch} patches and {nsoil} soils, more than"
            f" the compiled plugin's capacity ({wave_capacity}, {patch_capacity},"
            f" {soil_capacity}); build the simulator with the largest terrain first"
        )
    g = t.rut_grid
    out = np.zeros(
        _HEADER + _WAVE * wave_capacity + _PATCH * patch_capacity + _SOIL * soil_capacity
    )
    out[:_HEADER] = [
        _TERRAIN_VERSION,
        1.0 if t.flat else 0.0,
        CONTACT_ITERATIONS,
        a.gx,
        a.gy,
        t.mu_x_default,
        t.mu_y_default,
        nwave,
        npatch,
        wave_capacity,
        patch_capacity,
        t.ground_soil,
        nsoil,
        soil_capacity,
        g.x0,
        g.y0,
        g.cell,
        g.nx,
        g.ny,
    ]
    waves = out[_HEADER : _HEADER + _WAVE * wave_capacity].reshape(wave_capacity, _WAVE)
    waves[:nwave] = np.column_stack([amp, k[:, 0], k[:, 1], phase, start])
    p0 = _HEADER + _WAVE * wave_capacity
    patches = out[p0 : p0 + _PATCH * patch_capacity].reshape(patch_capacity, _PATCH)
    patches[:npatch] = np.column_stack([lo, hi, mu, a.patch_soil])
    soils = out[p0 + _PATCH * patch_capacity :].reshape(soil_capacity, _SOIL)
    for i, sp in enumerate(t.soils):
        soils[i] = sp.numbers()
    return out


EFFECT_SLOTS = ("combined_on", "load_fall", "load_fz0", "load_span")
"""The plugin's ``effects`` numbers, in order (tire_plugin.c), and their off values below."""
_EFFECT_OFF = {"combined_on": 0.0, "load_fall": 0.0, "load_fz0": 1.0, "load_span": 1.0}


def inject_plugin(
    xml: str, cfg: RoverConfig, terrain: Terrain, effects: dict[str, float] | None = None
) -> str:
    """Scene XML from ``scene_xml`` with the tire plugin declared and configured.

    ``effects``: values of :data:`EFFECT_SLOTS` set by the tire-layer model extensions
    (``rover_env.effects.TireEffect.plugin_values``); missing slots are off. Loads
    (building it first if needed) the plugin library, so the result compiles.
    """
    eff = {**_EFFECT_OFF, **(effects or {})}
    unknown = set(eff) - set(EFFECT_SLOTS)
    if unknown:
        raise ValueError(f"inject_plugin: unknown effect slot(s) {sorted(unknown)}")
    load_plugin()
    if terrain.has_soil:  # the footprint read's points must fit the plugin's buffer
        terrain.rut_grid.samples(cfg.geometry.wheel_width)
    tire = cfg.tire
    shape = terrain.arrays()
    block = terrain_block(
        terrain,
        len(shape.amp),
        max(MIN_PATCH_CAPACITY, len(shape.patch_mu)),
        max(MIN_SOIL_CAPACITY, len(terrain.soils)),
    )
    config = {
        "wheels": " ".join(f"wheel_{w}" for w in WHEELS),
        "joints": " ".join(f"wheel_{w}" for w in WHEELS),
        "motors": " ".join(f"motor_{w}" for w in DRIVEN_WHEELS),
        "radius": _num(cfg.geometry.wheel_radius),
        "tire": " ".join(_num(getattr(tire, f.name)) for f in fields(TireParams)),
        "max_angle_error": _num(cfg.motor.max_angle_error),
        "terrain": TERRAIN_NUMERIC,
        "effects": " ".join(_num(eff[k]) for k in EFFECT_SLOTS),
        "rut_state": str(terrain.rut_grid.state_size),
        "width": _num(cfg.geometry.wheel_width),
    }
    mo = cfg.motor
    if mo.anti_windup != "clamp":  # the clamp needs no more (and a clamp model stays as it was)
        config["anti_windup"] = mo.anti_windup
        config["speed_loop"] = " ".join(
            _num(v)
            for v in (
                mo.integral_gain,
                mo.speed_gain,
                mo.torque_limit,
                mo.stall_torque,
                mo.no_load_speed,
                mo.tracking_ratio,
            )
        )
    lines = [
        "  <extension>",
        f'    <plugin plugin="{PLUGIN_NAME}">',
        f'      <instance name="{INSTANCE}">',
    ]
    lines += [f'        <config key="{k}" value={quoteattr(v)}/>' for k, v in config.items()]
    lines += ["      </instance>", "    </plugin>", "  </extension>", "  <custom>"]
    lines.append(
        f'    <numeric name="{TERRAIN_NUMERIC}" size="{block.size}"'
        f' data="{" ".join(_num(v) for v in block)}"/>'
    )
    lines.append("  </custom>")
    head, sep, rest = xml.partition("\n")
    if not head.startswith("<mujoco") or not sep:
        raise ValueError("inject_plugin: expected scene XML starting with a <mujoco> line")
    return head + "\n" + "\n".join(lines) + "\n" + rest


@dataclass(frozen=True)
class StateLayout:
    """Offsets into one plugin instance's ``plugin_state`` (mirrors tire_plugin.c)."""

    nw: int
    nd: int
    rut_state: int = 0

    @property
    def u_x(self) -> slice:
        return slice(0, self.nw)

    @property
    def u_y(self) -> slice:
        return slice(self.nw, 2 * self.nw)

    @property
    def setpoint(self) -> slice:
        return slice(2 * self.nw, 2 * self.nw + self.nd)

    @property
    def nstep(self) -> int:
        return 2 * self.nw + self.nd

    @property
    def truth(self) -> int:
        return self.nstep + 1

    @property
    def pending(self) -> int:
        """Start of the pending block (u_x, u_y, setpoints, then a truth block)."""
        return self.truth + _TRUTH * self.nw

    @property
    def pending_truth(self) -> int:
        return self.pending + 2 * self.nw + self.nd

    @property
    def dig(self) -> slice:
        start = self.pending_truth + _TRUTH * self.nw
        return slice(start, start + self.nw)

    @property
    def schedule(self) -> int:
        """The command schedule: rows queued, rows used, then ``SCHEDULE_ROWS`` x nd targets."""
        return self.dig.stop + 7 * self.nw  # after pending dig and the pending rut writes

    @property
    def rut(self) -> slice:
        start = self.schedule + 2 + SCHEDULE_ROWS * self.nd
        return slice(start, start + self.rut_state)

    @property
    def rut_index(self) -> int:
        """Capacity of the rut map's tile index (rover_env.rut's state layout)."""
        return max(self.rut_state - 2 - RUT_POOL_TILES * RUT_TILE * RUT_TILE, 0)

    @property
    def size(self) -> int:
        return self.rut.stop


class TruthArrays(NamedTuple):
    """Per-wheel outputs of a truth block; leading dimensions are those of the state rows."""

    v_x: Array
    v_y: Array
    v_w: Array
    F_x: Array
    F_y: Array
    F_z: Array
    delta: Array
    point: Array
    normal: Array
    patch: NDArray[np.int64]
    sinkage: Array
    torque: Array
    soil: NDArray[np.int64]


class PluginView:
    """Reads and writes the tire plugin's part of ``plugin_state`` of one model."""

    def __init__(self, model: mujoco.MjModel) -> None:
        inst = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_PLUGIN, INSTANCE)
        if inst < 0:
            raise ValueError(f"model has no {PLUGIN_NAME} plugin instance named {INSTANCE!r}")
        adr = int(model.plugin_stateadr[inst])
        num = int(model.plugin_statenum[inst])
        bare = StateLayout(len(WHEELS), len(DRIVEN_WHEELS))
        self.layout = StateLayout(bare.nw, bare.nd, max(num - bare.size, 0))
        if self.layout.rut_state and not self.layout.rut_index:
            raise ValueError(f"plugin state's rut block ({self.layout.rut_state}) has no index")
        if num != self.layout.size:
            raise ValueError(f"plugin state has {num} numbers, layout expects {self.layout.size}")
        self.slice = slice(adr, adr + num)
        self.terrain_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, TERRAIN_NUMERIC)
        size = int(model.numeric_size[self.terrain_id])
        adr_t = int(model.numeric_adr[self.terrain_id])
        self.terrain_slice = slice(adr_t, adr_t + size)

    def state(self, plugin_state: Array) -> Array:
        """This instance's state: a view of ``data.plugin_state`` or of batch rows (..., n)."""
        return plugin_state[..., self.slice]

    def set_setpoints(self, plugin_state: Array, values: Array) -> None:
        """Position setpoints of the driven wheels: the plugin owns them (not ctrl[pos])."""
        self.state(plugin_state)[..., self.layout.setpoint] = values

    def reset_tires(self, plugin_state: Array) -> None:
        st = self.state(plugin_state)
        st[..., self.layout.u_x] = 0.0
        st[..., self.layout.u_y] = 0.0
        st[..., self.layout.dig] = 0.0
        RutGrid.clear(st[..., self.layout.rut], self.layout.rut_index)

    def clear_ground_memory(self, plugin_state: Array) -> None:
        """Forget the ruts and dug holes (TireLayer.clear_ground_memory); tire states stay."""
        st = self.state(plugin_state)
        st[..., self.layout.dig] = 0.0
        RutGrid.clear(st[..., self.layout.rut], self.layout.rut_index)

    def queue_commands(self, plugin_state: Array, rows: Array) -> None:
        """Queue (n, nd) speed targets, one row per coming substep (n <= ``SCHEDULE_ROWS``):
        the plugin uses them as ``ctrl[vel]`` in order, then ``ctrl[vel]`` again."""
        r = np.asarray(rows, dtype=np.float64)
        n = len(r)
        if r.ndim != 2 or r.shape[1] != self.layout.nd or not 0 < n <= SCHEDULE_ROWS:
            raise ValueError(
                f"queue_commands: rows must be (n, {self.layout.nd}) with 0 < n <="
                f" {SCHEDULE_ROWS}, got {r.shape}"
            )
        st = self.state(plugin_state)
        q = self.layout.schedule
        st[q + 2 : q + 2 + n * self.layout.nd] = r.reshape(-1)
        st[q + 1] = 0.0
        st[q] = float(n)

    def queued_left(self, plugin_state: Array) -> int:
        """Queued command rows not used yet."""
        st = self.state(plugin_state)
        q = self.layout.schedule
        return int(st[q] - st[q + 1])

    def rut_state(self, plugin_state: Array) -> Array:
        """The rut map's block (rover_env.rut's layout): a view."""
        return self.state(plugin_state)[..., self.layout.rut]

    def nstep(self, plugin_state: Array) -> Array:
        return self.state(plugin_state)[..., self.layout.nstep]

    def truth(self, plugin_state: Array, pending: bool = False) -> TruthArrays:
        """Outputs of the last committed substep (or of the last compute, ``pending``): copies."""
        st = self.state(plugin_state)
        nw = self.layout.nw
        start = self.layout.pending_truth if pending else self.layout.truth
        b = st[..., start : start + _TRUTH * nw]
        lead = b.shape[:-1]

        def part(i: int, width: int = 1) -> Array:
            seg = b[..., i * nw : (i + width) * nw].copy()
            return seg.reshape(*lead, nw, 3) if width == 3 else seg

        return TruthArrays(
            v_x=part(0),
            v_y=part(1),
            v_w=part(2),
            F_x=part(3),
            F_y=part(4),
            F_z=part(5),
            delta=part(6),
            point=part(7, 3),
            normal=part(10, 3),
            patch=part(13).astype(np.int64),
            sinkage=part(14),
            torque=part(15),
            soil=part(16).astype(np.int64),
        )

    def pending_u(self, plugin_state: Array) -> tuple[Array, Array]:
        st = self.state(plugin_state)
        p, nw = self.layout.pending, self.layout.nw
        return st[..., p : p + nw].copy(), st[..., p + nw : p + 2 * nw].copy()

    def check_terrain(self, model: mujoco.MjModel, terrain: Terrain) -> Array:
        """The block :meth:`write_terrain` would write; raises if the model cannot take it."""
        cur = model.numeric_data[self.terrain_slice]
        if bool(cur[1]) != terrain.flat:
            raise ValueError("tire plugin: the terrain's flatness must not change")
        if terrain.rut_grid.index_size > self.layout.rut_index:
            raise ValueError(
                f"tire plugin: the terrain's rut map needs {terrain.rut_grid.index_size} tiles"
                f" in its index, the compiled model holds {self.layout.rut_index}; build it"
                " with that terrain"
            )
        return terrain_block(terrain, int(cur[9]), int(cur[10]), int(cur[13]))

    def write_terrain(self, model: mujoco.MjModel, terrain: Terrain) -> None:
        """Replace the plugin's ground (same flatness; within the compiled capacities)."""
        model.numeric_data[self.terrain_slice] = self.check_terrain(model, terrain)
