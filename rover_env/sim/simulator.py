"""The rover simulation: MuJoCo multibody dynamics plus the tire-slip force layer.

MuJoCo integrates the rigid bodies, joints, leaf springs, motors and obstacle contacts; the
wheels never touch the ground through MuJoCo. On every physics substep the tire layer finds
each wheel's contact with the analytic terrain, evaluates the Gim–Nikravesh forces in their
transient-slip form and applies them at the contact point through ``qfrc_applied`` between
``mj_step1`` and ``mj_step2`` (no global ``mjcb_*`` callbacks, so several simulations can live
in one process).
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from rover_env import tire
from rover_env.config import (
    DRIVEN_WHEELS,
    JOINTS,
    WHEELS,
    RoverConfig,
    TerrainConfig,
    load_rover,
    load_terrain,
)
from rover_env.effects import (
    CommandEffect,
    HingeEffect,
    TireEffect,
    build_effects,
    command_rows,
    command_sequence,
    plugin_refusals,
)
from rover_env.rut import check_overflow, refused_writes
from rover_env.sim.build import effect_soil, physical_config, resolve_auto_backend
from rover_env.sim.fast import PluginView, inject_plugin
from rover_env.sim.fast.plugin import SCHEDULE_ROWS
from rover_env.sim.index import (
    SegmentTruth,
    SensorReadings,
    SimIndex,
    SimulationError,
    WheelTruth,
    as_slice,
)
from rover_env.sim.model import (
    fill_hfield,
    hfield_data,
    physics_only,
    scene_xml,
    stable_step,
    static_deflection,
    wheel_load,
)
from rover_env.sim.speed_loop import advance_setpoints
from rover_env.sim.tire_layer import TireLayer, TireState
from rover_env.soil import SoilParams
from rover_env.soil import static_sinkage as soil_static_sinkage
from rover_env.terrain import Terrain

Array = NDArray[np.float64]


HINGE_EVERY = 10
"""Substeps between updates of the hinge effects' friction from the tire loads (10 ms at the
default step: far faster than the loads change, ~3 Hz tire bounce; per substep it cost ~3x)."""
FRICTION_DOF = int(mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF)
"""Constraint type of a dof's dry friction (``frictionloss``) rows in ``efc_*``."""


@functools.lru_cache(maxsize=64)
def _static_sinkage(load: float, radius: float, width: float, params: SoilParams) -> float:
    """:func:`rover_env.soil.static_sinkage`, once per soil (replays reset every window)."""
    return soil_static_sinkage(load, radius, width, params, tol=1e-7)


class RoverSim:
    """One rover on one terrain.

    Args:
        rover: rover configuration, a shipped name or a YAML path.
        terrain: terrain configuration, a shipped name or a YAML path.
        backend: ``"numpy"`` (the reference tire layer, run from Python on every substep),
            ``"plugin"`` (the same layer as a compiled MuJoCo engine plugin, see
            :mod:`rover_env.sim.fast`; needs a C compiler on first use), or ``"auto"``: the
            plugin when it builds and the configuration has no model extension that only the
            numpy layer implements, otherwise numpy (with a warning if the plugin failed).
        contacts: ``False`` skips MuJoCo's own collisions (the chassis boxes on the ground,
            wheel on wheel; the tire layer is the wheels' ground contact either way): for
            flat-ground replays, where they never fire and cost ~1/5 of a substep.
        sensors: ``False`` skips MuJoCo's sensor stage (the accelerometers need a second
            pass over the bodies' accelerations every substep) and makes :meth:`sensors`
            refuse; the state is the same to the bit. For replays that read only the state
            (a tenth of a replay's time, ``benchmarks/bench_replay.py``).
        visuals: ``False`` builds the model without what only a renderer reads (the visual
            geoms, camera, light and texture: :func:`~rover_env.sim.model.physics_only`);
            the same motion to the bit, each substep a few per cent cheaper. For replays.

    Model extensions (``cfg.extensions``, catalogue in :mod:`rover_env.effects`) are applied
    here: through the configuration the physics is built from (``self.phys_cfg``), the
    compiled model's arrays, the speed targets (per substep) and the numpy tire layer.
    ``self.cfg`` stays the configuration as given.
    """

    def __init__(
        self,
        rover: RoverConfig | str | Path = "proto_explorer",
        terrain: TerrainConfig | str | Path = "flat",
        backend: str = "numpy",
        contacts: bool = True,
        sensors: bool = True,
        visuals: bool = True,
    ) -> None:
        self.cfg = rover if isinstance(rover, RoverConfig) else load_rover(rover)
        self.terrain_cfg = terrain if isinstance(terrain, TerrainConfig) else load_terrain(terrain)
        # --- fast-backend integration point (rover_env.sim.fast) ---
        if backend not in ("numpy", "plugin", "auto"):
            raise ValueError(f"backend must be 'numpy', 'plugin' or 'auto', got {backend!r}")
        if backend == "auto":
            backend = resolve_auto_backend(self.cfg)
        refused = plugin_refusals(self.cfg.extensions)
        if backend == "plugin" and refused:
            raise NotImplementedError(
                f"backend='plugin' does not implement model extension(s) "
                f"{', '.join(refused)} (numpy tire layer only); use backend='numpy' or 'auto'"
            )
        self.backend = backend
        # --- model extensions (rover_env.effects) ---
        self.effects = [e for e in build_effects(self.cfg.extensions) if not e.is_off]
        self.phys_cfg = physical_config(self.cfg, self.effects)
        bound = stable_step(self.phys_cfg)
        if self.phys_cfg.sim.timestep >= bound:
            warnings.warn(
                f"sim.timestep {self.phys_cfg.sim.timestep:g} s is not below the tire's stable"
                f" step {bound:.3g} s (tire.sigma_x {self.phys_cfg.tire.sigma_x:g} m): the"
                " unpowered wheels ring on the tire's contact patch (docs/timestep.md)",
                RuntimeWarning,
                stacklevel=2,
            )
        self._cmd_effects = [e for e in self.effects if isinstance(e, CommandEffect)]
        self._hinge_effects = [e for e in self.effects if isinstance(e, HingeEffect)]
        # --- end of model extensions ---
        self.terrain = self._terrain_of(self.terrain_cfg)
        xml = scene_xml(self.phys_cfg, self.terrain_cfg)
        if not visuals:  # nothing renders this model: the same motion to the bit, cheaper
            xml = physics_only(xml)
        if backend == "plugin":
            slots: dict[str, float] = {}
            for e in self.effects:
                if isinstance(e, TireEffect):
                    slots.update(e.plugin_values(self.phys_cfg))
            xml = inject_plugin(xml, self.phys_cfg, self.terrain, slots)
        self.model = mujoco.MjModel.from_xml_string(xml)
        if not contacts:
            # MuJoCo's own contacts are the chassis boxes on the ground and wheel on wheel:
            # on flat ground they never fire while the rover drives (the tire layer carries it),
            # yet their collision pass is ~1/5 of a substep. The calibration replay skips it.
            self.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        self.has_sensors = sensors
        if not sensors:  # nothing reads sensordata; the dynamics do not depend on it
            self.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
        frictionloss0 = self.model.dof_frictionloss.copy()  # before any effect
        for e in self.effects:
            e.apply_model(self.model, self.phys_cfg)
        self._plugin = PluginView(self.model) if backend == "plugin" else None
        # --- end of integration point ---
        fill_hfield(self.model, self.terrain_cfg)
        self.data = mujoco.MjData(self.model)
        self._load_view: tuple[Array, Array] | None = None
        if self._plugin is not None:  # views of the committed F_z and delta (hinge effects)
            nw = len(WHEELS)
            t0 = self._plugin.slice.start + self._plugin.layout.truth
            ps = self.data.plugin_state
            self._load_view = (ps[t0 + 5 * nw : t0 + 6 * nw], ps[t0 + 6 * nw : t0 + 7 * nw])
        m = self.model
        self.dt = float(m.opt.timestep)
        ix = self._index = SimIndex.of_model(m)
        self._wheel_body, self._wheel_jnt = ix.wheel_body, ix.wheel_jnt
        self._wheel_dof, self._wheel_qpos = ix.wheel_dof, ix.wheel_qpos
        self._carrier = m.body_parentid[self._wheel_body]
        self._carriers = np.unique(self._carrier)
        self._carrier_of_wheel = (self._carriers[:, None] == self._carrier[None, :]).astype(float)
        """(carriers, wheels) incidence: sums the wheels' torques onto their carrier bodies."""
        self._seg_body = ix.seg_body
        self._root = int(m.body_rootid[self._seg_body[0]])
        self._joint_qpos, self._joint_dof = ix.joint_qpos, ix.joint_dof
        self._ctrl_pos, self._ctrl_vel = ix.ctrl_pos, ix.ctrl_vel
        self._vel_at = as_slice(ix.ctrl_vel)
        """``ctrl``'s speed targets as a slice where evenly spaced: a row written through it
        costs a sixth of the index array's write (0.4 against 2.6 us), the same numbers."""
        self._driven_qpos = ix.driven_qpos
        self._driven_dof = ix.driven_dof
        self._hinge_friction0 = frictionloss0[self._wheel_dof]
        self._hinge_ground = np.zeros(len(WHEELS))
        """The hinge effects' (the ground's) part of each wheel hinge's dry friction (N m)."""
        self._share = np.zeros(len(WHEELS))
        """:meth:`_ground_share`: the ground's share of each wheel hinge's dry friction."""
        self._sensor = ix.sensor
        self.joint_zero = np.array([self.cfg.joints[j].zero for j in JOINTS])
        """Each joint sensor's reading at the joint's true zero (:attr:`JointSpec.zero`)."""
        self.radius = self.cfg.geometry.wheel_radius
        self._obstacle_names = {ob.name for ob in self.terrain_cfg.obstacles}
        self.tires = TireLayer(
            m,
            self._wheel_body,
            self._wheel_jnt,
            self.radius,
            self.terrain,
            self.phys_cfg.tire,
            effects=[e for e in self.effects if isinstance(e, TireEffect)],
            width=self.cfg.geometry.wheel_width,
        )
        self.speed_targets = np.zeros(4)
        self._substep = 0
        self.reset()

    # ------------------------------------------------------------------ state
    @property
    def time(self) -> float:
        return float(self.data.time)

    def reset(
        self,
        x: float = 0.0,
        y: float = 0.0,
        yaw: float = 0.0,
        settle: float = 0.5,
        theta: Array | None = None,
        sunk: bool = False,
    ) -> None:
        """Place the rover at rest on the ground at (x, y) heading ``yaw``, then let it settle.

        The chassis is oriented to the local ground plane and lifted by the static tire
        deflection so the settling transient is small; ``settle`` seconds with zero speed
        targets then bring it to equilibrium and set time back to 0. ``theta`` sets initial
        joint angles theta_1..theta_5. ``sunk``: where axle 1 stands on loose soil, its
        wheels start at the soil's static sinkage instead (:meth:`rest_depth`): the tire's
        27 mm in a stiff soil is a loaded spring that throws the rover up, beyond what the
        settling absorbs from k_phi ~5e6 (replays, make-logs and proposed drives use it; the
        registered envs keep the tire's depth, so their episodes stay as they were).
        """
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        self._substep = 0
        h, hx, hy = self.terrain.height_and_gradient(np.array([x]), np.array([y]))
        n = np.array([-hx[0], -hy[0], 1.0])
        n /= np.linalg.norm(n)
        heading = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        fwd = heading - n * (heading @ n)
        fwd /= np.linalg.norm(fwd)
        left = np.cross(n, fwd)
        rot = np.column_stack([fwd, left, n])
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rot.ravel())
        hub = self.radius - (self.rest_depth(x, y) if sunk else static_deflection(self.phys_cfg))
        # Put axle 1 above the ground point (x, y) along the normal.
        pos = np.array([x, y, h[0]]) + n * hub
        d.qpos[0:3] = pos
        d.qpos[3:7] = quat
        if theta is not None:
            d.qpos[self._joint_qpos] = np.asarray(theta, dtype=float).reshape(5)
        mujoco.mj_forward(m, d)
        self.speed_targets[:] = 0.0
        d.ctrl[self._ctrl_vel] = 0.0
        d.ctrl[self._ctrl_pos] = d.qpos[self._driven_qpos]
        self.tires.reset()
        for ce in self._cmd_effects:
            ce.reset(np.zeros(4))
        if self._hinge_effects:  # static load until the first substep sets each wheel's own
            d0 = static_deflection(self.phys_cfg)
            self._set_hinges(
                np.full(len(WHEELS), self.phys_cfg.tire.C_z * d0), np.full(len(WHEELS), d0)
            )
        if self._plugin is not None:  # fast backend: the plugin owns setpoints and tire states
            self._plugin.set_setpoints(d.plugin_state, d.ctrl[self._ctrl_pos])
            self._plugin.reset_tires(d.plugin_state)
        if settle > 0:
            self.step(round(settle / self.dt))
            # Start the clock and the wheel angles (encoders) from zero, as a log does.
            d.time = 0.0
            d.qpos[self._wheel_qpos] = 0.0
            d.ctrl[self._ctrl_pos] = 0.0
            if self._plugin is not None:  # fast backend
                self._plugin.set_setpoints(d.plugin_state, d.ctrl[self._ctrl_pos])
            # Settling is not part of the drive: the soil keeps no rut or hole from it (the
            # wheels were placed at the hard-ground deflection and popped up in the soil).
            self.tires.clear_ground_memory()
            if self._plugin is not None:
                self._plugin.clear_ground_memory(d.plugin_state)
            mujoco.mj_forward(m, d)

    def rest_depth(self, x: float, y: float) -> float:
        """Depth (m) a wheel at rest at (x, y) sits below the surface under a sixth of the
        weight: the tire's static deflection on hard ground, the soil's static sinkage on
        loose soil (the wheel is rigid there, docs/soil.md).

        Why not the tire's everywhere: a wheel put 27 mm deep in a soil whose static sinkage
        is 2.5 mm (k_phi 6e6) starts under ~35 times its load and throws the rover 13 cm up;
        at k_phi 2.5e7 it was still bouncing 2 s later (stop 84's probe).
        """
        k = int(self.terrain.soil_index(np.array([x]), np.array([y]))[0])
        if k == 0:
            return static_deflection(self.phys_cfg)
        g = self.phys_cfg.geometry
        load = wheel_load(self.phys_cfg)
        return _static_sinkage(load, g.wheel_radius, g.wheel_width, self.terrain.soils[k - 1])

    def _terrain_of(self, terrain: TerrainConfig) -> Terrain:
        """The ground as simulated: ``terrain`` with the model extensions' loose soil (one
        place, so a swapped terrain keeps a ``loose_soil`` effect)."""
        return Terrain(
            terrain, self.phys_cfg.tire, soil_over_ground=effect_soil(terrain, self.effects)
        )

    def set_terrain(self, terrain: TerrainConfig) -> None:
        """Swap the ground without recompiling: new relief, friction map and obstacle poses.

        The arena size, grid resolution and number of obstacles must match the compiled
        model (per-episode terrain randomisation changes values, not structure). Call
        :meth:`reset` afterwards.
        """
        if self._plugin is not None:  # fast backend: refuse before anything changes
            self._plugin.check_terrain(self.model, self._terrain_of(terrain))
        old = self.terrain_cfg
        if terrain.is_flat != old.is_flat or (
            not old.is_flat and (terrain.size != old.size or terrain.resolution != old.resolution)
        ):
            raise ValueError("set_terrain: arena size, resolution and flatness must not change")
        if len(terrain.obstacles) != len(old.obstacles):
            raise ValueError("set_terrain: the number of obstacles must not change")
        m = self.model
        if not terrain.is_flat:
            # The compiled elevation range (and so the ground's bounding box) stays fixed.
            data, lo, span = hfield_data(terrain)
            cap = float(m.hfield_size[0, 2])
            if span > cap * (1 + 1e-9):
                raise ValueError(
                    f"set_terrain: relief spans {span:.3f} m, more than the compiled {cap:.3f} m;"
                    " build the simulator with the largest terrain first"
                )
            m.hfield_data[:] = (data * (span / cap)).ravel()
            m.geom_pos[m.geom("ground").id, 2] = lo
        for ob in terrain.obstacles:
            gid = m.geom(ob.name).id if ob.name in self._obstacle_names else None
            if gid is None:
                raise ValueError(f"set_terrain: obstacle {ob.name!r} is not in the model")
            m.geom_pos[gid] = ob.pos
            m.geom_size[gid] = ob.size
            quat = np.zeros(4)
            mujoco.mju_axisAngle2Quat(quat, np.array([0.0, 0.0, 1.0]), np.radians(ob.yaw_deg))
            m.geom_quat[gid] = quat
        self.terrain_cfg = terrain
        self.terrain = self._terrain_of(terrain)
        self.tires.terrain = self.terrain
        if self._plugin is not None:  # fast backend: the plugin reads the ground from the model
            self._plugin.write_terrain(m, self.terrain)

    def set_speed_targets(self, targets: ArrayLike) -> None:
        """Speed targets (rad/s) of the driven wheels 1L 1R 2L 2R, clipped to the motor's range."""
        t = np.asarray(targets, dtype=float).reshape(4)
        if not np.all(np.isfinite(t)):
            bad = [DRIVEN_WHEELS[i] for i in np.flatnonzero(~np.isfinite(t))]
            raise ValueError(f"speed targets not finite for wheel(s) {', '.join(bad)}")
        lim = self.cfg.motor.max_wheel_speed
        self.speed_targets[:] = np.clip(t, -lim, lim)

    # ------------------------------------------------------------------ stepping
    def step(self, n: int = 1) -> None:
        """Advance ``n`` physics substeps, applying the tire layer on each."""
        m, d = self.model, self.data
        if self._cmd_effects or self._hinge_effects:
            self._step_commanded(n)
            return
        if self._plugin is not None:
            # Fast backend: the plugin integrates the setpoints and applies the tire forces
            # inside mj_step (rover_env.sim.fast), so no Python runs per substep.
            d.ctrl[self._vel_at] = self.speed_targets
            mujoco.mj_step(m, d, n)
            self.check()
            return
        for _ in range(n):
            # Speed loop: integrate the angle setpoint (the controller's I-term), with anti-windup.
            self._advance_setpoints(self.speed_targets)
            d.ctrl[self._ctrl_vel] = self.speed_targets
            mujoco.mj_step1(m, d)
            self.tires.apply(d)
            mujoco.mj_step2(m, d)
        self.check()

    def drive(self, targets: ArrayLike, steps: ArrayLike) -> None:
        """``targets[i]`` (1L 1R 2L 2R) held for ``steps[i]`` substeps, row after row: to the
        bit :meth:`set_speed_targets` then :meth:`step` per row, checked once at the end (a
        replay window's rows: a fifth of its time went to per-row checks, bench_replay.py)."""
        tt = np.asarray(targets, dtype=float).reshape(-1, 4)
        nn = np.asarray(steps, dtype=np.int64).reshape(-1)
        if not np.all(np.isfinite(tt)):
            i, j = np.argwhere(~np.isfinite(tt))[0]
            raise ValueError(f"speed targets not finite in row {i} for wheel {DRIVEN_WHEELS[j]}")
        lim = self.cfg.motor.max_wheel_speed
        tt = np.clip(tt, -lim, lim)
        if self._plugin is None:
            for u, n in zip(tt, nn, strict=True):
                self.speed_targets[:] = u
                self.step(int(n))
            return
        if self._hinge_effects:
            for u, n in zip(tt, nn, strict=True):
                self.speed_targets[:] = u
                self._step_commanded(int(n), check=False)
            self.check()
            return
        self.drive_read(tt, nn, (), (), 0)  # the plugin's batched paths, nothing read

    def drive_read(
        self,
        targets: ArrayLike,
        steps: ArrayLike,
        after: ArrayLike,
        qpos: ArrayLike,
        body: int,
        quat: bool = False,
    ) -> tuple[Array, Array, Array]:
        """:meth:`drive` over all rows, reading the state after ``after[j]`` rows (sorted,
        0 = before any): ``d.qpos[qpos]``, ``d.xpos[body]`` and ``d.xmat[body]`` (flat; with
        ``quat``, ``d.xquat[body]``) at each read, as arrays (reads, ...). The same numbers to the bit as one :meth:`drive`
        per stretch between reads (tested), checked once at the end: a replay reads after
        every log row, and one call per row cost it about a seventh of its time
        (benchmarks/bench_replay.py). Hinge effects and the numpy backend drive stretch by
        stretch."""
        tt = np.asarray(targets, dtype=float).reshape(-1, 4)
        nn = np.asarray(steps, dtype=np.int64).reshape(-1)
        at = np.asarray(after, dtype=np.int64).reshape(-1)
        qi = np.asarray(qpos, dtype=np.intp)
        if at.size and (np.any(np.diff(at) < 0) or at[0] < 0 or at[-1] > len(tt)):
            raise ValueError(f"reads must be sorted row counts in [0, {len(tt)}]")
        d = self.data
        frame = d.xquat if quat else d.xmat
        out = (
            np.empty((len(at), len(qi))),
            np.empty((len(at), 3)),
            np.empty((len(at), frame.shape[1])),
        )
        if not np.all(np.isfinite(tt)):
            i, j = np.argwhere(~np.isfinite(tt))[0]
            raise ValueError(f"speed targets not finite in row {i} for wheel {DRIVEN_WHEELS[j]}")
        batched = self._plugin is not None and not self._hinge_effects
        if batched:
            lim = self.cfg.motor.max_wheel_speed
            tt = np.clip(tt, -lim, lim)
            run = (
                self._stretch_commanded(tt, nn)
                if self._cmd_effects
                else self._stretch_plain(tt, nn)
            )
        else:  # hinge effects, the numpy backend: drive() stretch by stretch

            def run(idx: NDArray[np.int64]) -> None:
                self.drive(tt[idx], nn[idx])

        for j, rows in enumerate(np.split(np.arange(len(tt)), at)):
            run(rows)
            if j < len(at):
                out[0][j], out[1][j], out[2][j] = d.qpos[qi], d.xpos[body], frame[body]
        if batched:
            if len(tt):
                self.speed_targets[:] = tt[-1]
            self.check()
        return out

    def _stretch_plain(
        self, tt: Array, nn: NDArray[np.int64]
    ) -> Callable[[NDArray[np.int64]], None]:
        """:meth:`drive_read`'s stepper without command effects: each row's targets to the
        plugin's motors, its substeps in one ``mj_step`` call (as :meth:`drive`)."""
        m, d, vel = self.model, self.data, self._vel_at
        rows, ns = tt.tolist(), nn.tolist()

        def run(idx: NDArray[np.int64]) -> None:
            ctrl = d.ctrl
            for i in idx.tolist():
                ctrl[vel] = rows[i]
                mujoco.mj_step(m, d, ns[i])

        return run

    def _stretch_commanded(
        self, tt: Array, nn: NDArray[np.int64]
    ) -> Callable[[NDArray[np.int64]], None]:
        """:meth:`drive_read`'s stepper with command effects: every substep's motor targets
        at once (:func:`command_sequence`, one recursion over all rows), queued stretch by
        stretch ``SCHEDULE_ROWS`` at a time."""
        m, d = self.model, self.data
        assert self._plugin is not None
        plugin = self._plugin
        sub = command_sequence(self._cmd_effects, np.repeat(tt, nn, axis=0), self.dt)
        start = np.concatenate([[0], np.cumsum(nn)])

        def run(idx: NDArray[np.int64]) -> None:
            if not idx.size:
                return
            rows = sub[start[idx[0]] : start[idx[-1] + 1]]
            for j in range(0, len(rows), SCHEDULE_ROWS):
                chunk = rows[j : j + SCHEDULE_ROWS]
                plugin.queue_commands(d.plugin_state, chunk)
                mujoco.mj_step(m, d, len(chunk))
            self._substep += len(rows)

        return run

    def _advance_setpoints(self, u: Array) -> None:
        """One substep of the speed loop's setpoints (:func:`advance_setpoints`)."""
        d = self.data
        w = d.qvel[self._driven_dof]
        d.ctrl[self._ctrl_pos] = advance_setpoints(
            d.ctrl[self._ctrl_pos],
            d.qpos[self._driven_qpos],
            w * self.dt,
            w,
            u,
            self.dt,
            self.phys_cfg.motor,
        )

    def _command(self) -> Array:
        """Speed targets after the command effects (lag, delay), advanced one substep."""
        u = self.speed_targets.copy()
        for ce in self._cmd_effects:
            u = ce.step(u, self.dt)
        return u

    def _set_hinges(self, F_z: Array, delta: Array) -> None:
        """Wheel hinges' dry friction from this substep's loads (hinge effects)."""
        ground = np.zeros(len(WHEELS))
        for he in self._hinge_effects:
            ground = ground + he.hinge_friction(F_z, delta, self.radius)
        self._hinge_ground = ground
        fl = self._hinge_friction0 + ground
        self.model.dof_frictionloss[self._wheel_dof] = fl
        self._share = np.divide(ground, fl, out=np.zeros(len(WHEELS)), where=fl > 0)

    def _ground_share(self) -> Array:
        """Share of each wheel hinge's present dry friction that is the ground's moment (kept
        when the friction is set: the model's array holds the same numbers)."""
        return self._share

    def _react_on_ground(self, share: Array) -> None:
        """Take the ground's share of each hinge's friction torque off the wheel's carrier:
        rolling resistance is the ground's moment (Wong 1.2), not a bearing's, so the carrier
        gets that share back through ``xfrc_applied`` (issue 16: else theta_4 moved 1.3 x)."""
        d = self.data
        if d.ncon == 0 and d.ne == 0:
            # No contact or equality rows, and the wheel hinges have no limits: a wheel's
            # only constraint row is its dry friction's, a unit row of its dof, so the dof's
            # constraint force is that row's force to the bit (tests/test_sim.py), read at
            # half the cost of picking the rows out.
            friction = d.qfrc_constraint[self._wheel_dof]
        else:
            n = d.nefc
            rows = d.efc_type[:n] == FRICTION_DOF  # the dry-friction rows, one per dof
            per_dof = np.zeros(self.model.nv)
            per_dof[d.efc_id[:n][rows]] = d.efc_force[:n][rows]
            friction = per_dof[self._wheel_dof]
        torque = (friction * share)[:, None] * d.xaxis[self._wheel_jnt]
        d.xfrc_applied[self._carriers, 3:] = self._carrier_of_wheel @ torque

    def _step_commanded(self, n: int, check: bool = True) -> None:
        """``step`` substep by substep where needed: command effects change the motors'
        targets on every substep; hinge effects set the wheel hinges' friction from the
        tire loads every ``HINGE_EVERY`` substeps (identically on both backends; the plugin
        runs the substeps in between in one call, any command effects' targets for them
        queued in its state)."""
        m, d = self.model, self.data
        if self._plugin is not None and not self._hinge_effects:
            # Command effects on the plugin: their n outputs at once (the targets are held
            # over the call), queued in the plugin state, which feeds them to the motors
            # substep by substep inside one mj_step call per SCHEDULE_ROWS.
            rows = command_rows(self._cmd_effects, self.speed_targets.copy(), self.dt, n)
            for j in range(0, n, SCHEDULE_ROWS):
                chunk = rows[j : j + SCHEDULE_ROWS]
                self._plugin.queue_commands(d.plugin_state, chunk)
                mujoco.mj_step(m, d, len(chunk))
            self._substep += n
            if check:
                self.check()
            return
        k = HINGE_EVERY
        left = n
        while left > 0:
            if self._plugin is not None:  # here with hinge effects
                # Up to the next hinge update in one call; command effects' targets for
                # those substeps queued in the plugin state at once, as without hinges
                # (one mj_step and a Python recursion per substep cost a command effect
                # beside a hinge effect about twice its plain replay).
                run = min(left, k - self._substep % k)
                if self._cmd_effects:
                    rows = command_rows(self._cmd_effects, self.speed_targets.copy(), self.dt, run)
                    self._plugin.queue_commands(d.plugin_state, rows)
                    d.ctrl[self._vel_at] = rows[-1]  # what a substep's feed leaves there
                else:
                    d.ctrl[self._vel_at] = self.speed_targets
                mujoco.mj_step(m, d, run)
                self._substep += run
                left -= run
                if self._substep % k == 0 and self._load_view is not None:
                    self._react_on_ground(self._ground_share())
                    self._set_hinges(*self._load_view)
                continue
            left -= 1
            self._substep += 1
            update = bool(self._hinge_effects) and self._substep % k == 0
            u = self._command()
            self._advance_setpoints(u)
            d.ctrl[self._ctrl_vel] = u
            mujoco.mj_step1(m, d)
            self.tires.apply(d)
            # The ground's share of the rows this substep's step2 solves (built in step1).
            share = self._ground_share() if update else None
            if update and self.tires.last is not None:
                self._set_hinges(self.tires.last.F_z, self.tires.last.delta)
            mujoco.mj_step2(m, d)
            if share is not None and self.tires.last is not None:
                self._react_on_ground(share)
        if check:
            self.check()

    def prime_commands(self, t: ArrayLike, cmd: ArrayLike) -> None:
        """Fill the command effects' memory as if ``cmd[k]`` had been sent from ``t[k]``.

        For starting a simulation mid-drive (replay windows): times are those of the log
        the rover's clock now continues (``self.time`` is the log's time of now).
        """
        tt = np.asarray(t, dtype=float)
        cc = np.asarray(cmd, dtype=float).reshape(-1, 4)
        for ce in self._cmd_effects:
            ce.prime(tt, cc, self.time, self.dt)

    def set_setpoints(self, setpoints: ArrayLike) -> None:
        """Set the speed controllers' integrated angle setpoints of 1L 1R 2L 2R (rad)."""
        sp = np.asarray(setpoints, dtype=float).reshape(4)
        self.data.ctrl[self._ctrl_pos] = sp
        if self._plugin is not None:
            self._plugin.set_setpoints(self.data.plugin_state, sp)

    @property
    def index(self) -> SimIndex:
        """Where the model keeps wheels, joints, segments, motors and sensors."""
        return self._index

    @property
    def has_command_effects(self) -> bool:
        """Whether a model extension shapes the speed targets per substep (lag, delay)."""
        return bool(self._cmd_effects)

    def check(self) -> None:
        """Raise :class:`SimulationError` on a MuJoCo warning or a non-finite state (and
        on a full rut pool): what :meth:`step` checks after its substeps."""
        d = self.data
        if d.warning.number.any():  # one vectorised read; names only when something is wrong
            warned = [
                mujoco.mjtWarning(i).name for i in range(len(d.warning)) if d.warning[i].number > 0
            ]
            raise SimulationError(f"MuJoCo warning(s) at t={d.time:.3f}s: {', '.join(warned)}")
        if not np.all(np.isfinite(d.qpos)) or not np.all(np.isfinite(d.qvel)):
            raise SimulationError(f"non-finite state at t={d.time:.3f}s")
        if self.terrain.has_soil:  # a full rut pool would leave ruts out silently
            rut = self.tires.rut if self._plugin is None else self._plugin.rut_state(d.plugin_state)
            check_overflow(refused_writes(rut))

    # ------------------------------------------------------------------ outputs
    def wheel_truth(self) -> WheelTruth:
        """Privileged tire state from the last substep."""
        ts = self.tires.last
        if self._plugin is not None:  # fast backend: the last committed substep's outputs
            pv = self._plugin
            tr = pv.truth(self.data.plugin_state)
            ts = TireState(*tr) if pv.nstep(self.data.plugin_state) > 0 else None
        if ts is None:
            raise RuntimeError("wheel_truth() needs at least one physics substep")
        eps = self.cfg.tire.v_eps
        S = tire.slip_ratio(ts.v_x, ts.v_w, eps)
        return WheelTruth(
            S=S,
            S_alpha=tire.lateral_slip(ts.v_x, ts.v_y, ts.v_w, S, eps),
            F_x=ts.F_x,
            F_y=ts.F_y,
            F_z=ts.F_z,
            delta=ts.delta,
            v_x=ts.v_x,
            v_y=ts.v_y,
            v_w=ts.v_w,
            contact_point=ts.point.copy(),
            patch=ts.patch,
            sinkage=ts.sinkage,
            soil=ts.soil,
        )

    def segment_truth(self) -> SegmentTruth:
        d = self.data
        b = self._seg_body
        vel = np.zeros((3, 6))
        for i, bid in enumerate(b):
            # Local frame: angular then linear velocity of the body origin in body axes.
            mujoco.mj_objectVelocity(self.model, d, mujoco.mjtObj.mjOBJ_BODY, int(bid), vel[i], 1)
        lin_w = np.einsum("bij,bj->bi", d.xmat[b].reshape(3, 3, 3), vel[:, 3:])
        ang_w = np.einsum("bij,bj->bi", d.xmat[b].reshape(3, 3, 3), vel[:, :3])
        return SegmentTruth(
            pos=d.xpos[b].copy(),
            quat=d.xquat[b].copy(),
            lin_vel=lin_w,
            ang_vel=ang_w,
            forward_speed=vel[:, 3].copy(),
            yaw_rate=vel[:, 2].copy(),
        )

    def sensors(self) -> SensorReadings:
        if not self.has_sensors:
            raise RuntimeError(
                "RoverSim.sensors(): this simulator was built with sensors=False (its sensor"
                " stage is off, sensordata is not updated); build it with sensors=True"
            )
        s, sd = self._sensor, self.data.sensordata
        return SensorReadings(
            t=self.time,
            phi=np.array([sd[s[f"phi_{w}"]][0] for w in WHEELS]),
            phi_dot=np.array([sd[s[f"phidot_{w}"]][0] for w in WHEELS]),
            theta=np.array([sd[s[j]][0] for j in JOINTS]) + self.joint_zero,
            theta_dot=np.array([sd[s[f"{j}_dot"]][0] for j in JOINTS]),
            imu_quat=np.stack([sd[s[f"imu_seg{i}_quat"]] for i in (1, 2, 3)]),
            imu_gyro=np.stack([sd[s[f"imu_seg{i}_gyro"]] for i in (1, 2, 3)]),
            imu_accel=np.stack([sd[s[f"imu_seg{i}_accel"]] for i in (1, 2, 3)]),
        )

    def motor_torque(self) -> Array:
        """Torque each driven wheel's motor applies (N m)."""
        return self.data.actuator_force[: len(DRIVEN_WHEELS)].copy()

    def joint_angles(self) -> Array:
        return self.data.qpos[self._joint_qpos].copy()

    def flipped(self, max_tilt_deg: float = 75.0) -> bool:
        """True once any segment tilts more than ``max_tilt_deg`` from upright.

        A segment tips over near 58 deg (half-track 0.225 m, centre of mass ~0.14 m above the
        ground), so beyond 75 deg it is lying on its side or back and cannot drive on.
        """
        up_z = self.data.xmat[self._seg_body, 8]
        return bool(np.any(up_z < np.cos(np.radians(max_tilt_deg))))
