"""N rovers on MuJoCo Warp with the tire layer as Warp kernels (the GPU twin of RoverSim).

``WarpRoverSim(n, terrain=...)`` builds the rover's scene without the C plugin (MuJoCo
Warp runs no engine plugins), puts it on a Warp device (``"cuda"`` or ``"cpu"``) as
``n`` worlds, and on every substep runs ``mujoco_warp.step1``, the layer's kernels
(:mod:`rover_env.warp.layer`: speed loop, wheel forces, force application and rut writes)
and ``mujoco_warp.step2`` — where the plugin's ``compute`` and ``advance`` run inside
``mj_step``. On CUDA the substeps are captured once in a CUDA graph and replayed.

Differences from ``RoverSim(backend="plugin")`` (docs/gpu.md):

* float32 throughout (MuJoCo Warp's precision), against float64;
* MuJoCo's sensor stage is off (observations come from the state and the wheel truth);
* no model extensions (``cfg.extensions`` must be empty) and no obstacle-free terrain
  swaps at run time; each world may have its own flat ground (``terrain`` a list);
* each world's rut map has ``rut_pool_tiles`` tiles (the plugin: 2048, about 50 m of
  drive; 2048 tiles are 2 MB per world in float32).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any

import mujoco
import mujoco_warp as mjw
import numpy as np
import warp as wp
from numpy.typing import NDArray

from rover_env.config import (
    DRIVEN_WHEELS,
    WHEELS,
    RoverConfig,
    TerrainConfig,
    load_rover,
    load_terrain,
)
from rover_env.rut import RUT_POOL_TILES, RUT_TILE
from rover_env.sim.fast.plugin import MIN_PATCH_CAPACITY, MIN_SOIL_CAPACITY, terrain_block
from rover_env.sim.model import fill_hfield, scene_xml, static_deflection
from rover_env.terrain import Terrain
from rover_env.tire import TireParams
from rover_env.warp import layer

Array = NDArray[np.float64]

GRAPH_SUBSTEPS = 50
"""Most substeps per captured graph (WarpRoverEnv replays graphs of one estimator sample, 20)."""
TRUTH_FIELDS = ("v_x", "v_y", "v_w", "F_x", "F_y", "F_z", "delta", "sinkage", "torque")


def warp_model(cfg: RoverConfig, terrain: TerrainConfig, contacts: bool = True) -> mujoco.MjModel:
    """The rover scene as MuJoCo Warp runs it: ``scene_xml`` without the tire plugin, with
    the sensor stage off (and MuJoCo's own contacts off if ``contacts`` is False)."""
    m = mujoco.MjModel.from_xml_string(scene_xml(cfg, terrain))
    fill_hfield(m, terrain)
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
    if not contacts:
        m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    return m


def _params(cfg: RoverConfig, dt: float) -> NDArray[np.float32]:
    """The layer's parameter row (layer.P_*): tire numbers, geometry, speed loop, dt."""
    mo = cfg.motor
    tire = [float(getattr(cfg.tire, f.name)) for f in fields(TireParams)]
    if mo.anti_windup == "back_calculation":
        raise ValueError(
            "motor.anti_windup 'back_calculation' is not on the GPU backend (clamp and"
            " conditional are); use RoverSim"
        )
    cond = mo.anti_windup == "conditional"
    row = [
        *tire,
        cfg.geometry.wheel_radius,
        cfg.geometry.wheel_width,
        mo.max_angle_error,
        1.0 if cond else 0.0,
        mo.integral_gain,
        mo.speed_gain,
        mo.torque_limit,
        mo.stall_torque,
        mo.no_load_speed,
        dt,
    ]
    assert len(row) == layer.NPAR
    return np.asarray(row, dtype=np.float32)


def _terrain_rows(terrains: Sequence[Terrain]) -> tuple[NDArray[np.float32], int]:
    """One terrain block per world at common capacities, and the largest rut index."""
    arrs = [t.arrays() for t in terrains]
    capw = max(len(a.amp) for a in arrs)
    capp = max(MIN_PATCH_CAPACITY, *(len(a.patch_mu) for a in arrs))
    caps = max(MIN_SOIL_CAPACITY, *(len(t.soils) for t in terrains))
    rows = np.stack([terrain_block(t, capw, capp, caps) for t in terrains])
    return rows.astype(np.float32), max(t.rut_grid.index_size for t in terrains)


class WarpRoverSim:
    """``n_worlds`` rovers stepping together on one Warp device.

    Args:
        n_worlds: number of worlds.
        rover: rover configuration (no model extensions).
        terrain: one terrain for all worlds, or one per world (then all flat: the MJCF
            ground is the first's).
        device: Warp device, e.g. ``"cuda:0"`` or ``"cpu"`` (default: Warp's default).
        contacts: ``False`` turns MuJoCo's own collisions off (as ``RoverSim(contacts=False)``).
        rut_pool_tiles: rut-map tiles per world (16 x 16 cells each).
    """

    def __init__(
        self,
        n_worlds: int,
        rover: RoverConfig | str | Path = "proto_explorer",
        terrain: TerrainConfig | str | Path | Sequence[TerrainConfig | str | Path] = "flat",
        device: str | None = None,
        contacts: bool = True,
        rut_pool_tiles: int = RUT_POOL_TILES,
    ) -> None:
        self.cfg = rover if isinstance(rover, RoverConfig) else load_rover(rover)
        if self.cfg.extensions:
            raise NotImplementedError(
                f"WarpRoverSim runs no model extensions; got {sorted(self.cfg.extensions)}"
            )
        items = list(terrain) if isinstance(terrain, (list, tuple)) else [terrain] * n_worlds
        if len(items) != n_worlds:
            raise ValueError(f"terrain: {len(items)} terrains for {n_worlds} worlds")
        tcfgs = [t if isinstance(t, TerrainConfig) else load_terrain(t) for t in items]  # type: ignore[arg-type]
        if len({id(t) for t in tcfgs}) > 1 and not all(t.is_flat for t in tcfgs):
            raise ValueError("terrain: one terrain per world needs flat terrains")
        self.terrain_cfg = tcfgs[0]
        self.terrains = [Terrain(t, self.cfg.tire) for t in tcfgs]
        self.n = n_worlds
        self.device = wp.get_device(device)
        self.mjm = warp_model(self.cfg, self.terrain_cfg, contacts)
        self.dt = float(self.mjm.opt.timestep)
        mj = self.mjm
        body = np.array([mj.body(f"wheel_{w}").id for w in WHEELS])
        jnt = np.array([mj.joint(f"wheel_{w}").id for w in WHEELS])
        act = [mj.actuator(f"motor_{w}").id for w in DRIVEN_WHEELS]
        self.wheel_qpos = mj.jnt_qposadr[jnt]
        self.wheel_dof = mj.jnt_dofadr[jnt]
        self.driven_qpos = self.wheel_qpos[: len(DRIVEN_WHEELS)]
        self.seg_body = np.array([mj.body(f"seg{i}").id for i in (1, 2, 3)])
        rows, index_size = _terrain_rows(self.terrains)
        nw, nd = len(WHEELS), len(DRIVEN_WHEELS)
        has_soil = any(t.has_soil for t in self.terrains)
        with wp.ScopedDevice(self.device):
            self.m = mjw.put_model(mj)
            self.d = mjw.put_data(mj, self._initial_data(), nworld=n_worlds)

            def ints(a: NDArray[np.int64] | list[int]) -> wp.array:
                return wp.array(np.asarray(a, dtype=np.int32), dtype=int)

            def zeros(*shape: int, dtype: Any = float) -> Any:
                return wp.zeros(shape, dtype=dtype)

            self._ix = {
                "wheel_body": ints(body),
                "wheel_jnt": ints(jnt),
                "wheel_dof": ints(self.wheel_dof),
                "carrier": ints(mj.body_parentid[body]),
                "root": ints(mj.body_rootid[mj.body_parentid[body]]),
                "driven_qpos": ints(self.driven_qpos),
                "driven_dof": ints(self.wheel_dof[:nd]),
                "ctrl_pos": ints(mj.actuator_ctrladr[act]),
                "ctrl_vel": ints(mj.actuator_ctrladr[act] + 1),
                "body_rootid": ints(mj.body_rootid),
                "body_dofnum": ints(mj.body_dofnum),
                "body_dofadr": ints(mj.body_dofadr),
                "body_parentid": ints(mj.body_parentid),
                "dof_parentid": ints(mj.dof_parentid),
            }
            self.par: Any = wp.array(_params(self.cfg, self.dt), dtype=float)
            self.ter: Any = wp.array(rows, dtype=float)
            self.targets = zeros(n_worlds, nd)
            self.setpoints = zeros(n_worlds, nd)
            self.u_x = zeros(n_worlds, nw)
            self.u_y = zeros(n_worlds, nw)
            self.dig = zeros(n_worlds, nw)
            self.nstep = zeros(n_worlds, dtype=int)
            self.force = zeros(n_worlds, nw, dtype=wp.vec3)
            self.moment = zeros(n_worlds, nw, dtype=wp.vec3)
            self.at = zeros(n_worlds, nw, dtype=wp.vec3)
            truth: Any = layer.Truth()
            self.truth = truth
            for name in TRUTH_FIELDS:
                setattr(self.truth, name, zeros(n_worlds, nw))
            self.truth.patch = zeros(n_worlds, nw, dtype=int)
            self.truth.soil = zeros(n_worlds, nw, dtype=int)
            self.truth.point = zeros(n_worlds, nw, dtype=wp.vec3)
            self.truth.normal = zeros(n_worlds, nw, dtype=wp.vec3)
            rut: Any = layer.Rut()
            self.rut = rut
            tiles = rut_pool_tiles if has_soil else 0
            self.rut.index = zeros(n_worlds, index_size if has_soil else 0, dtype=wp.int32)
            self.rut.pool = zeros(n_worlds, max(tiles, 1) * RUT_TILE * RUT_TILE)
            self.rut.count = zeros(n_worlds, 2, dtype=wp.int32)
            self.rut.pending = zeros(n_worlds, nw, dtype=wp.spatial_vector)
        self._graphs: dict[int, Any] = {}
        self._warm = False
        self.reset()

    # ------------------------------------------------------------------ setup
    def _initial_data(self) -> mujoco.MjData:
        """RoverSim.reset's pose at the origin (heading x), before settling."""
        m = self.mjm
        d = mujoco.MjData(m)
        t = self.terrains[0]
        h, hx, hy = t.height_and_gradient(np.array([0.0]), np.array([0.0]))
        n = np.array([-hx[0], -hy[0], 1.0])
        n /= np.linalg.norm(n)
        fwd = np.array([1.0, 0.0, 0.0]) - n * n[0]
        fwd /= np.linalg.norm(fwd)
        rot = np.column_stack([fwd, np.cross(n, fwd), n])
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rot.ravel())
        hub = self.cfg.geometry.wheel_radius - static_deflection(self.cfg)
        d.qpos[0:3] = np.array([0.0, 0.0, h[0]]) + n * hub
        d.qpos[3:7] = quat
        mujoco.mj_forward(m, d)
        ix = [m.actuator(f"motor_{w}").id for w in DRIVEN_WHEELS]
        d.ctrl[m.actuator_ctrladr[ix]] = d.qpos[self.driven_qpos]
        return d

    def _snapshot(self) -> dict[str, wp.array]:
        d = self.d
        src = {
            "qpos": d.qpos,
            "qvel": d.qvel,
            "ctrl": d.ctrl,
            "qacc_warmstart": d.qacc_warmstart,
            "setpoints": self.setpoints,
            "u_x": self.u_x,
            "u_y": self.u_y,
        }
        return {k: wp.clone(v) for k, v in src.items()}

    def reset(self, settle: float = 0.5) -> None:
        """RoverSim.reset at the origin for every world: settle ``settle`` s with zero
        targets, then restart the clock, encoders and setpoints and forget the ruts dug
        meanwhile; the result becomes the template :meth:`reset_worlds` copies."""
        d0 = self._initial_data()
        with wp.ScopedDevice(self.device):
            n = self.n
            for name in ("qpos", "qvel", "ctrl", "qacc_warmstart"):
                getattr(self.d, name).assign(np.tile(getattr(d0, name), (n, 1)))
            self.d.time.zero_()
            sp = np.tile(d0.qpos[self.driven_qpos], (n, 1))
            self.setpoints.assign(sp.astype(np.float32))
            for a in (self.u_x, self.u_y, self.dig, self.nstep, self.targets):
                a.zero_()
            self._clear_ruts()
            mjw.forward(self.m, self.d)
            self.step(round(settle / self.dt))
            qpos = self.d.qpos.numpy()
            qpos[:, self.wheel_qpos] = 0.0
            self.d.qpos.assign(qpos)
            ctrl = self.d.ctrl.numpy()
            ctrl[:, self._ix["ctrl_pos"].numpy()] = 0.0
            self.d.ctrl.assign(ctrl)
            self.d.time.zero_()
            self.setpoints.zero_()
            self.dig.zero_()
            self._clear_ruts()
            mjw.forward(self.m, self.d)
            self._template = self._snapshot()

    def _clear_ruts(self) -> None:
        self.rut.index.zero_()
        self.rut.count.zero_()

    # ------------------------------------------------------------------ stepping
    def set_speed_targets(self, targets: wp.array | NDArray[np.float64]) -> None:
        """Speed targets (n, 4) rad/s of 1L 1R 2L 2R, clipped to the motor's range."""
        lim = self.cfg.motor.max_wheel_speed
        if isinstance(targets, wp.array):
            wp.launch(layer.clip_copy, dim=self.targets.shape, inputs=[targets, lim, self.targets])
        else:
            t = np.clip(np.asarray(targets, dtype=np.float64).reshape(self.n, -1), -lim, lim)
            self.targets.assign(t.astype(np.float32))

    def _substep(self) -> None:
        m, d, ix = self.m, self.d, self._ix
        mjw.step1(m, d)
        wp.launch(
            layer.speed_loop,
            dim=self.targets.shape,
            inputs=[
                self.par,
                ix["driven_qpos"],
                ix["driven_dof"],
                ix["ctrl_pos"],
                ix["ctrl_vel"],
                d.qpos,
                d.qvel,
                self.targets,
                self.setpoints,
                d.ctrl,
            ],
        )
        wp.launch(
            layer.wheel_forces,
            dim=self.u_x.shape,
            inputs=[
                self.par,
                self.ter,
                ix["wheel_body"],
                ix["wheel_jnt"],
                ix["wheel_dof"],
                ix["carrier"],
                ix["root"],
                d.xpos,
                d.xaxis,
                d.cvel,
                d.subtree_com,
                d.qvel,
                self.nstep,
                self.u_x,
                self.u_y,
                self.dig,
                self.rut,
                self.truth,
                self.force,
                self.moment,
                self.at,
            ],
        )
        wp.launch(
            layer.apply_wheels,
            dim=self.n,
            inputs=[
                self.par,
                self.ter,
                ix["wheel_body"],
                ix["body_rootid"],
                ix["body_dofnum"],
                ix["body_dofadr"],
                ix["body_parentid"],
                ix["dof_parentid"],
                d.subtree_com,
                d.cdof,
                self.force,
                self.moment,
                self.at,
                self.rut,
                self.nstep,
                d.qfrc_applied,
            ],
        )
        mjw.step2(m, d)

    def step(self, n: int = 1) -> None:
        """Advance every world ``n`` substeps: graphs of up to ``GRAPH_SUBSTEPS`` substeps,
        captured on first use (a CUDA graph on a GPU; Warp's recorded launch stream on CPU,
        which replays without Python per kernel: ~40x faster there) and replayed."""
        with wp.ScopedDevice(self.device):
            while n > 0:
                k = min(n, GRAPH_SUBSTEPS)
                graph = self._graphs.get(k)
                if graph is None:
                    if not self._warm:
                        self._substep()  # compile outside the capture (one real substep)
                        self._warm = True
                        n -= 1
                        continue
                    with wp.ScopedCapture() as cap:
                        for _ in range(k):
                            self._substep()
                    graph = self._graphs[k] = cap.graph
                wp.capture_launch(graph)
                n -= k

    def reset_worlds(self, mask: Any) -> None:
        """Put the worlds where ``mask`` (int32, (n,)) is nonzero back to the settled template."""
        with wp.ScopedDevice(self.device):
            for name, tmpl in self._template.items():
                live = getattr(self.d, name) if hasattr(self.d, name) else getattr(self, name)
                wp.launch(layer.copy_rows, dim=live.shape, inputs=[mask, tmpl, live])
            for a in (self.dig, self.rut.index, self.rut.count):
                wp.launch(
                    layer.zero_rows_f if a.dtype == wp.float32 else layer.zero_rows_i,
                    dim=a.shape,
                    inputs=[mask, a],
                )
            wp.launch(layer.zero_time, dim=self.n, inputs=[mask, self.d.time, self.nstep])

    # ------------------------------------------------------------------ outputs
    def wheel_truth(self) -> dict[str, Array]:
        """The last substep's per-wheel outputs as numpy arrays (n, 6) (point, normal:
        (n, 6, 3)), in ``WHEELS`` order."""
        out = {name: getattr(self.truth, name).numpy().astype(np.float64) for name in TRUTH_FIELDS}
        out["point"] = self.truth.point.numpy().astype(np.float64)
        out["normal"] = self.truth.normal.numpy().astype(np.float64)
        out["patch"] = self.truth.patch.numpy()
        out["soil"] = self.truth.soil.numpy()
        return out

    def rut_state(self, world: int) -> Array:
        """World ``world``'s rut map in rover_env.rut's state layout (float64, the pool at
        ``RUT_POOL_TILES`` tiles), so that ``RutGrid.lookup`` and its kin read it."""
        g = self.terrains[world].rut_grid
        out = g.new_state()
        if not g.index_size:
            return out
        count = self.rut.count.numpy()[world]
        index = self.rut.index.numpy()[world, : g.index_size]
        pool = self.rut.pool.numpy()[world].astype(np.float64)
        out[0], out[1] = float(count[0]), float(count[1])
        out[2 : 2 + g.index_size] = index
        size = min(pool.size, out.size - 2 - g.index_size)
        out[2 + g.index_size : 2 + g.index_size + size] = pool[:size]
        return out
