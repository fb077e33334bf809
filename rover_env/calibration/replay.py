"""Replay measured drives in the model by multiple shooting.

Open-loop replay of a whole drive lets an early error (a heading off by a degree) swamp
everything after it, so each drive is cut into short windows (default 3 s) and every
window is re-initialised from the log:

* joint angles from the log; joint and wheel rates from local least-squares slopes of the
  logged angles (quantised encoders are useless differenced sample to sample);
* the body's motion from the free (odometry) wheels of segment 3, which SPEC §1 takes as
  non-slipping: forward speed and yaw rate of segment 3, no sideways or vertical motion;
  the free joint's six velocities are solved so segment 3 moves that way given the joint
  rates (MuJoCo body Jacobian, so any joint layout works);
* the heading of the rover (needed only when gravity is tilted) from the logged pose where it
  exists, dead reckoning from the free wheels in between, turned by the log's
  ``start_heading_deg`` into the frame the drives share where the YAML gives one;
* the speed controllers' integrated angle setpoints by running the controller's own
  setpoint recursion (integrate the command, clip to ``max_angle_error`` of the wheel; with
  ``motor.anti_windup: conditional`` also hold the integral while the PI's raw torque,
  computed from the logged angles, rates and commands, saturates outward) on the logged
  commands and wheel angles (:func:`rover_env.sim.simulator.advance_setpoints`, one step
  per log sample), and the command effects' memory (lag, delay) from the logged commands.

A short burn-in (default 0.4 s) after each start is simulated but not scored: tire
deflection states and any mismatch of the initial velocity settle in it. Residuals are
then taken every ``stride`` samples: wheel-angle increments since the end of the burn-in
(sensitive to speed and slip errors, quantisation-level noise), joint angles, and the pose
increments between logged pose samples inside the window (in the frame of the first).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import multiprocessing as mp
import operator
import os
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, TypeVar

import mujoco
import numpy as np
from numpy.typing import NDArray

from rover_env.calibration.heading import start_yaw
from rover_env.config import JOINTS, WHEELS, MotorSpec, RoverConfig, TerrainConfig, to_dict
from rover_env.effects import CommandEffect, build_effects, command_sequence
from rover_env.estimation.dead_reckoning import fixes
from rover_env.executor import die_with_parent
from rover_env.logs import DriveLog
from rover_env.sim.build import physical_config
from rover_env.sim.model import stable_config, stable_step
from rover_env.sim.simulator import RoverSim
from rover_env.sim.speed_loop import setpoint_recursion

Array = NDArray[np.float64]
T = TypeVar("T")

WHEEL_SIGNALS = tuple(f"wheel_{w}" for w in WHEELS)
JOINT_SIGNALS = JOINTS
POSE_SIGNALS = ("pose_x", "pose_y", "pose_yaw")
SIGNALS: tuple[str, ...] = (*WHEEL_SIGNALS, *JOINT_SIGNALS, *POSE_SIGNALS)


@dataclass(frozen=True)
class ReplaySettings:
    window: float = 3.0
    """Length of one shooting window (s)."""
    burn_in: float = 1.0
    """Simulated but not scored at the start of each window (s). Until stop 23 0.4 s: too
    short for the tire states and the initial velocity mismatch to settle, so the replay of
    the model's own clean drives fitted a 4 x shorter relaxation length than the truth's;
    with 1 s it finds the truth's, and the free wheels' residual grows 6-14 x away from it."""
    stride: float = 0.1
    """Spacing of scored samples (s)."""
    every: int = 1
    """Use every ``every``-th window (subsampling for speed; 1 = all)."""
    rate_window: float = 0.2
    """Half-width (s) of the least-squares slope used for initial rates."""
    soil_lead: float = 2.0
    """On loose soil (a ``loose_soil`` extension), each window is started this much earlier
    from the log and driven by its commands, unscored, before its burn-in: a window starts
    on virgin soil with its wheels at its static sinkage (stop 84; before, at the tire's
    27 mm, which threw the rover up on stiff soil), while the logged rover's wheels had
    sunk under way and its middle and rear wheels ran in the front ones' ruts (0.5 m of
    wheelbase, ~3 s at 0.15 m/s). The scored samples are the same as on hard ground.
    Measured on logs made with a soil looser than the fit's form (k_phi 4e5, phi 28, n0
    1.1), the truth's replay cost 1.51 x the best k_phi's without a lead, 1.16 x with 2 s
    and 1.55 x with 5 s (docs/calibration, stop 28: on soil that loose the replay stays
    noisy)."""
    timestep: float | None = 0.002
    """Physics step of the replay (s), when coarser than the rover's own (None: the rover's).
    Why 2 ms: the timestep study (docs/timestep.md) passes every physical check at 2 ms
    against 1 ms (end points within 0.015 %), and the replay's cost is its physics steps:
    a candidate's fit costs half. The model's twins (the replay floor) are driven at the
    rover's own step, so the floor includes what the coarser replay leaves."""
    terrain: TerrainConfig | None = None
    """The ground every window is replayed on; None: flat hard ground. ``diagnose`` sets it
    from the logs' declared terrain (:func:`rover_env.calibration.ground.common_ground`),
    which refuses a ground the replay cannot honour."""


@dataclass
class PreparedLog:
    """A log with what the replay needs precomputed from it."""

    log: DriveLog
    name: str
    phi_rate: Array
    theta_rate: Array
    setpoint_err: Array
    """(N, 4) controller setpoint minus wheel angle of 1L 1R 2L 2R (rad)."""
    yaw3: Array
    """(N,) heading of segment 3 in the log frame."""
    regimes: dict[str, NDArray[np.bool_]] = field(default_factory=dict)
    loop: tuple[object, ...] = ()
    """What ``setpoint_err`` was computed for (:func:`loop_key` of the configuration)."""


def loop_motor(cfg: RoverConfig) -> MotorSpec:
    """The motor as the simulator builds it from ``cfg``: after the model extensions (a
    torque limit effect changes ``torque_limit``), as :class:`RoverSim`'s ``phys_cfg``."""
    return physical_config(cfg).motor


def _command_effects(cfg: RoverConfig) -> list[CommandEffect]:
    """The command effects (lag, delay) that are on in ``cfg``, in the simulator's order."""
    return [
        e for e in build_effects(cfg.extensions) if not e.is_off and isinstance(e, CommandEffect)
    ]


def loop_key(cfg: RoverConfig) -> tuple[object, ...]:
    """The numbers the setpoint recursion reads from ``cfg``: the bound alone for the clamp,
    the loop's gains and the motor's torque bounds too for conditional integration, and the
    command effects that change what the loop integrates (a delay or a lag)."""
    mo = loop_motor(cfg)
    cmd = tuple((e.name, tuple(sorted(e.values.items()))) for e in _command_effects(cfg))
    if mo.anti_windup == "clamp":
        return ("clamp", mo.max_angle_error, cmd)
    return (
        mo.anti_windup,
        mo.max_angle_error,
        mo.integral_gain,
        mo.speed_gain,
        mo.torque_limit,
        mo.stall_torque,
        mo.no_load_speed,
        cmd,
    )


def loop_commands(log: DriveLog, cfg: RoverConfig) -> Array:
    """(N, 4) the speed targets the loop integrates over each log interval: ``log.cmd``
    after the command effects of ``cfg``, averaged over the interval's substeps (row k is the
    interval from sample k to k + 1; the last row repeats its command).

    The simulator integrates its setpoints from the targets *after* a delay or a lag, so the
    recursion must too: fed the logged commands, a 0.22 s delay left every window's setpoint
    ``cmd x delay`` ahead (0.44 rad at 2 rad/s, 17 N m of integral), a surge at each window's
    start that a fitted torque limit then made up for (issue 16, stop 37).
    """
    effects = _command_effects(cfg)
    cmd = np.asarray(log.cmd, dtype=np.float64)
    if not effects:
        return cmd
    dt = cfg.sim.timestep
    step_of = np.round(np.asarray(log.t) / dt).astype(np.int64)
    for e in effects:
        e.reset(np.zeros(4))
    out = cmd.copy()
    n = np.diff(step_of)
    held = np.flatnonzero(n > 0)  # the intervals with substeps, in order
    if not held.size:
        return out
    # Every substep's output at once (the same numbers as interval by interval), then each
    # interval's mean, the intervals of one length together: a (k, n, 4) mean over its
    # middle axis sums each interval's rows as ``rows.mean(axis=0)`` does, to the bit
    # (numpy's pairwise sum; a running sum, ``np.add.reduceat``, moves the last bits).
    rows = command_sequence(effects, np.repeat(cmd[held], n[held], axis=0), dt)
    starts = np.concatenate([[0], np.cumsum(n[held])[:-1]])
    for m in np.unique(n[held]):
        pick = n[held] == m
        out[held[pick]] = rows[starts[pick][:, None] + np.arange(m)].mean(axis=1)
    return out


def setpoint_errors(log: DriveLog, cfg: RoverConfig) -> Array:
    """(N, 4) the speed controllers' setpoint minus wheel angle at every log sample.

    The simulator's recursion (:func:`advance_setpoints`) with one step per sample: the
    command held since the last sample, the logged angle as the wheel's, the logged
    increment as its motion and that increment over the interval as its rate. (The rate
    decides saturation, for conditional integration only. The local least-squares slope
    used to start the windows is wrong there: it leads a wheel that accelerates and is
    one-sided at a log's start. On the simulator's own drive under a torque limit the
    recursion then left 12 mrad median, 30 mrad at most, against the simulator's setpoints;
    with the interval's rate 2.6 mrad median, 8 mrad at most, 13 mrad with 2048-count
    encoders; the clamp's recursion 1.6 and 6 mrad.) Run on Python floats
    (:func:`~rover_env.sim.speed_loop.setpoint_recursion`): the same numbers, 0.25 s less per
    log and loop.
    """
    return setpoint_recursion(log.t, log.phi, loop_commands(log, cfg), loop_motor(cfg))


def _slopes(t: Array, y: Array, half: float) -> Array:
    """Centred least-squares slope of each column of y over +-half seconds."""
    out = np.zeros_like(y)
    n = len(t)
    lo = np.searchsorted(t, t - half, side="left")
    hi = np.searchsorted(t, t + half, side="right")
    c = np.concatenate([np.zeros((1, y.shape[1])), np.cumsum(y, axis=0)])
    ct = np.concatenate([[0.0], np.cumsum(t)])
    ctt = np.concatenate([[0.0], np.cumsum(t * t)])
    cty = np.concatenate([np.zeros((1, y.shape[1])), np.cumsum(t[:, None] * y, axis=0)])
    m = (hi - lo).astype(float)
    st, stt = ct[hi] - ct[lo], ctt[hi] - ctt[lo]
    sy, sty = c[hi] - c[lo], cty[hi] - cty[lo]
    den = m * stt - st * st
    ok = den > 1e-12
    out[ok] = (m[ok, None] * sty[ok] - st[ok, None] * sy[ok]) / den[ok, None]
    del n
    return out


def _free_radius(cfg: RoverConfig) -> float:
    """Rolling radius of segment 3's free wheels at their static load (the model's r_e)."""
    load = (cfg.masses.segment_mass(3) + 2 * cfg.masses.wheel) * 9.81 / 2
    return cfg.geometry.wheel_radius - cfg.tire.k_re * load / cfg.tire.C_z


def regimes(log: DriveLog, phi_rate: Array) -> dict[str, NDArray[np.bool_]]:
    """Per-sample regime masks from commands and measured wheel rates (may overlap)."""
    cmd = log.cmd
    v_cmd = cmd.mean(axis=1)
    turn = ((cmd[:, 1] - cmd[:, 0]) + (cmd[:, 3] - cmd[:, 2])) / 4
    v_drv = phi_rate[:, :4].mean(axis=1)
    v_free = phi_rate[:, 4:].mean(axis=1)
    moving = (np.abs(v_cmd) > 0.1) | (np.abs(v_drv) > 0.1)
    acc = (np.abs(v_cmd) - np.abs(v_drv) > 0.25) & (np.abs(v_cmd) > 0.1)
    brk = np.abs(v_drv) - np.abs(v_cmd) > 0.25
    left = turn > 0.15
    right = turn < -0.15
    rev = v_cmd < -0.1
    slip = np.abs(v_drv - v_free) / np.maximum(np.maximum(np.abs(v_drv), np.abs(v_free)), 0.3)
    high = moving & (slip > 0.15)
    straight = moving & ~left & ~right & ~acc & ~brk
    return {
        "straight": straight,
        "left_turn": left,
        "right_turn": right,
        "accelerating": acc,
        "braking": brk,
        "reversing": rev,
        "high_slip": high,
        "all": np.ones(len(log), dtype=bool),
    }


def prepare(log: DriveLog, cfg: RoverConfig, name: str, settings: ReplaySettings) -> PreparedLog:
    """``log`` made ready for replays under ``cfg``. A pose reference faster than 1 Hz is
    read as fixes at least :data:`~rover_env.estimation.dead_reckoning.FIX_SPACING` apart
    (:func:`~rover_env.estimation.dead_reckoning.fixes`): every weight and threshold that
    reads the pose (its share of a window's loss, the gap tolerance, the odometry band) was
    measured on 1 Hz fixes, and a 50 Hz pose would be most of each window's loss."""
    pose = fixes(log.t, log.pose)
    if pose is not log.pose:  # a faster pose; 1 Hz logs pass as they are
        log = dataclasses.replace(log, pose=pose)
    t = log.t
    phi_rate = _slopes(t, log.phi, settings.rate_window)
    theta_rate = _slopes(t, log.theta, settings.rate_window)
    # The speed controller's setpoint recursion (RoverSim.step) on the logged data.
    errs = setpoint_errors(log, cfg)
    # Heading: dead reckoning from the free wheels, pinned to logged yaw where present.
    g = cfg.geometry
    r3 = _free_radius(cfg)
    w3 = r3 * (phi_rate[:, 5] - phi_rate[:, 4]) / (2 * g.half_track)
    dr = np.concatenate([[0.0], np.cumsum(0.5 * (w3[1:] + w3[:-1]) * np.diff(t))])
    have = np.flatnonzero(np.isfinite(log.pose[:, 2]))
    yaw = dr.copy()
    if have.size:
        corr = log.pose[have, 2] - dr[have]
        yaw = dr + np.interp(t, t[have], corr)
    yaw = yaw + start_yaw(log)  # in the frame the drives share (their YAML's start heading)
    return PreparedLog(
        log=log,
        name=name,
        phi_rate=phi_rate,
        theta_rate=theta_rate,
        setpoint_err=errs,
        yaw3=yaw,
        regimes=regimes(log, phi_rate),
        loop=loop_key(cfg),
    )


def for_config(p: PreparedLog, cfg: RoverConfig) -> PreparedLog:
    """``p`` with its setpoints recomputed if ``cfg``'s speed loop differs from the one it
    was prepared for (a fitted torque limit under conditional integration: the recursion
    decides saturation by the limit; a clamp's recursion reads only the bound)."""
    key = loop_key(cfg)
    if not p.loop or p.loop == key:
        return p
    return dataclasses.replace(p, setpoint_err=_setpoints_for(p.log, cfg, key), loop=key)


class Kept(Generic[T]):
    """The last ``size`` answers of a pure function of objects (logs), least recent dropped.
    An entry holds the objects it was keyed on, so their ids are never reused while it
    stands, and it is answered only for those very objects (not equal ones)."""

    def __init__(self, size: int = 16) -> None:
        self.size = size
        self._kept: OrderedDict[Hashable, tuple[tuple[object, ...], T]] = OrderedDict()

    def get(self, key: Hashable, holders: Sequence[object]) -> T | None:
        hit = self._kept.get(key)
        if hit is None or len(hit[0]) != len(holders):
            return None
        if not all(map(operator.is_, hit[0], holders)):
            return None
        self._kept.move_to_end(key)
        return hit[1]

    def put(self, key: Hashable, holders: Sequence[object], value: T) -> None:
        self._kept[key] = (tuple(holders), value)
        if len(self._kept) > self.size:
            self._kept.popitem(last=False)


_SETPOINTS: Kept[Array] = Kept(64)
"""Recent :func:`setpoint_errors` by log and loop (:func:`loop_key`)."""


def _setpoints_for(log: DriveLog, cfg: RoverConfig, key: tuple[object, ...]) -> Array:
    """:func:`setpoint_errors` of ``log`` under ``cfg``'s loop ``key``, computed once per
    log and loop. Why: every candidate that moves the loop's key (each delay, lag or torque
    limit replayed) asked for it again, per log and replay: 663 recursions, 3 % of a lag
    case's time (stop 107's profile). The entry holds the log, so an id is never reused
    while it stands; the arrays are the same numbers (a pure function of log and key)."""
    k = (id(log), key)
    hit = _SETPOINTS.get(k, [log])
    if hit is not None:
        return hit
    errs = setpoint_errors(log, cfg)
    errs.setflags(write=False)
    _SETPOINTS.put(k, [log], errs)
    return errs


@dataclass
class Window:
    log_index: int
    k0: int
    k1: int
    """Samples k0 .. k1 (inclusive) of the log."""


def make_windows(logs: list[PreparedLog], settings: ReplaySettings) -> list[Window]:
    out: list[Window] = []
    for i, p in enumerate(logs):
        t = p.log.t
        starts: list[int] = []
        k = 0
        while True:
            k1 = int(np.searchsorted(t, t[k] + settings.window - 1e-9))
            if k1 >= len(t):
                break
            starts.append(k)
            k = k1
        for j, k0 in enumerate(starts):
            if j % settings.every == 0:
                k1 = int(np.searchsorted(t, t[k0] + settings.window - 1e-9))
                out.append(Window(i, k0, k1))
    return out


def straight_windows(logs: list[PreparedLog], windows: list[Window]) -> list[Window]:
    """The windows of ``windows`` in which no sample is commanded to turn (the regimes
    ``left_turn`` and ``right_turn``): there the yaw springs and the wheels' side forces,
    which a turn loads, carry nothing."""
    out = []
    for w in windows:
        reg = logs[w.log_index].regimes
        turning = reg["left_turn"][w.k0 : w.k1 + 1] | reg["right_turn"][w.k0 : w.k1 + 1]
        if not np.any(turning):
            out.append(w)
    return out


@dataclass
class WindowResult:
    """Residuals (sim - log) of one window at its scored samples."""

    window: Window
    idx: NDArray[np.intp]
    """Log sample index of each scored row."""
    resid: Array
    """(n, 11) wheel increments (6) and joint angles (5)."""
    sim: Array
    """(n, 11) the simulated values themselves."""
    pose_idx: NDArray[np.intp]
    pose_resid: Array
    """(m, 3) x, y (m), yaw (rad) increments since the window's first scored pose sample."""
    pose_sim: Array


def replay_step(cfg: RoverConfig, timestep: float | None) -> RoverConfig:
    """``cfg`` stepped at ``timestep`` when that is coarser than its own step and within the
    tire's stable step (:func:`rover_env.sim.model.stable_step`); else at its own step, or
    finer where that rings (:func:`rover_env.sim.model.stable_config`, as the twins are made).

    Why the bound: a model form with a short relaxation length (a steady-state tire, 0.32 mm)
    rang the free wheels at 2 ms, and the replay floor of their encoders came out 20 x what
    the same model leaves at the rover's 1 ms (stop 104): a floor that silenced the free
    wheels for every candidate fitted under that form."""
    cfg = stable_config(cfg)
    if timestep is None or timestep <= cfg.sim.timestep or timestep >= stable_step(cfg):
        return cfg
    return dataclasses.replace(cfg, sim=dataclasses.replace(cfg.sim, timestep=timestep))


class Replayer:
    """Replays windows of prepared logs in one simulator built from a configuration."""

    def __init__(
        self,
        cfg: RoverConfig,
        settings: ReplaySettings,
        backend: str = "auto",
        contacts: bool = False,
        sensors: bool = False,
    ) -> None:
        cfg = replay_step(cfg, settings.timestep)
        self.cfg = cfg
        self.settings = settings
        self.contacts = contacts
        self.sensors = sensors
        # Flat ground (or the uniform ground a log declares): the chassis never touches it and the tire layer is the wheels' contact,
        # so MuJoCo's collision pass is skipped (the same replay to the bit, ~15 % faster;
        # benchmarks/bench_replay.py).
        # The replay reads the state only (qpos, the segments' poses), so MuJoCo's sensor
        # stage is off by default: the same replay to the bit, faster (bench_replay.py).
        ground = "flat" if settings.terrain is None else settings.terrain
        # Nothing renders a replay: built without the visual geoms (the same to the bit).
        self.sim = RoverSim(
            cfg, ground, backend=backend, contacts=contacts, sensors=sensors, visuals=False
        )
        self.backend = self.sim.backend
        s = self.sim
        m = s.model
        self.lead = settings.soil_lead if s.terrain.has_soil else 0.0
        """Unscored lead of every window (s): :attr:`ReplaySettings.soil_lead` on soil."""
        self._seg3 = int(s.index.seg_body[2])
        self._root_dofs = np.arange(6)
        self._nv = m.nv
        self._zero = s.joint_zero
        """The joint sensors' zeros: windows start from the logged angles less them, and the
        replay's angles are compared as the sensors would read them."""

    def _init_window(self, p: PreparedLog, k0: int) -> None:
        s, m, d = self.sim, self.sim.model, self.sim.data
        log = p.log
        th = log.theta[k0] - self._zero  # the joints' true angles, as the sensors' zeros say
        # Heading of segment 1 = segment 3's minus the yaw joints between them (small angles):
        # R_3 = R_1 Rx(theta_1) Rz(theta_2) Rx(theta_3) Ry(theta_4) Rz(theta_5) (SPEC §1).
        # Until stop 31 the sign was +: every window started 2 (theta_2 + theta_5) off in
        # heading, harmless under vertical gravity, but on a slope the tilt then acted in the
        # wrong direction (a 6.3 deg cross-slope: 25 deg off in a pivot, the free wheels
        # replayed at 0.71 rad RMS under the truth, and slopes were fitted low).
        yaw1 = float(p.yaw3[k0] - th[1] - th[4])
        s.reset(0.0, 0.0, yaw1, settle=0.0, theta=th, sunk=True)
        d.time = float(log.t[k0])
        qv = np.zeros(self._nv)
        qv[s.index.wheel_dof] = p.phi_rate[k0]
        qv[s.index.joint_dof] = p.theta_rate[k0]
        # Segment 3's twist from its free wheels (no sideways, vertical, roll or pitch motion).
        g = s.phys_cfg.geometry
        r3 = _free_radius(s.phys_cfg)
        v3 = r3 * p.phi_rate[k0, 4:].mean()
        w3 = r3 * (p.phi_rate[k0, 5] - p.phi_rate[k0, 4]) / (2 * g.half_track)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        jacp = np.zeros((3, self._nv))
        jacr = np.zeros((3, self._nv))
        mujoco.mj_jacBody(m, d, jacp, jacr, self._seg3)
        rot = d.xmat[self._seg3].reshape(3, 3)
        target = np.concatenate([rot @ np.array([v3, 0.0, 0.0]), rot @ np.array([0.0, 0.0, w3])])
        jac = np.vstack([jacp, jacr])
        rhs = target - jac @ qv
        qv[self._root_dofs] = np.linalg.solve(jac[:, self._root_dofs], rhs)
        d.qvel[:] = qv
        s.set_setpoints(d.qpos[s.index.driven_qpos] + p.setpoint_err[k0])
        s.prime_commands(log.t[: k0 + 1], log.cmd[: k0 + 1])
        mujoco.mj_forward(m, d)

    def run_window(self, p: PreparedLog, w: Window) -> WindowResult:
        s = self.sim
        log = p.log
        st = self.settings
        t = log.t
        step_of = np.round(t / s.dt).astype(np.int64)
        k_lead = int(np.searchsorted(t, t[w.k0] - self.lead - 1e-9)) if self.lead > 0 else w.k0
        self._init_window(p, k_lead)
        # On soil: sink and rut before the window (unscored).
        s.drive(log.cmd[k_lead : w.k0], np.diff(step_of[k_lead : w.k0 + 1]))
        kb = int(np.searchsorted(t, t[w.k0] + st.burn_in - 1e-9))
        stride = max(1, round(st.stride * log.meta.sample_rate_hz))
        scored = np.arange(kb, w.k1 + 1, stride)
        pose_k = (kb + np.flatnonzero(np.isfinite(log.pose[kb : w.k1 + 1, 0]))).tolist()
        want = sorted(set(scored.tolist()) | set(pose_k))  # all at or after k0
        last = want[-1] if want else w.k0
        q, xp, xr = s.drive_read(
            log.cmd[w.k0 : last],
            np.diff(step_of[w.k0 : last + 1]),
            np.array(want, dtype=np.int64) - w.k0,
            np.concatenate([s.index.wheel_qpos, s.index.joint_qpos]),
            self._seg3,
        )
        q[:, 6:] += self._zero
        at = {r: i for i, r in enumerate(want)}
        rows = {r: q[i] for r, i in at.items()}
        poses = {r: np.concatenate([xp[at[r]], xr[at[r]]]) for r in pose_k}
        simv = np.array([rows[int(k)] for k in scored])
        logv = np.hstack([log.phi[scored], log.theta[scored]])
        # Wheel angles as increments since the end of the burn-in.
        base_sim = rows[kb][:6]
        base_log = log.phi[kb]
        simv[:, :6] -= base_sim
        logv[:, :6] -= base_log
        resid = simv - logv
        pose_idx = np.array(pose_k[1:], dtype=np.intp)
        pose_sim = np.zeros((len(pose_idx), 3))
        pose_res = np.zeros((len(pose_idx), 3))
        if len(pose_k) >= 2:
            a = pose_k[0]
            pa = poses[a]
            ra = pa[3:].reshape(3, 3)
            yaw_a = math.atan2(ra[1, 0], ra[0, 0])
            la = log.pose[a]
            ca, sa = math.cos(la[2]), math.sin(la[2])
            for j, k in enumerate(pose_k[1:]):
                pk = poses[k]
                dp = ra.T @ (pk[:3] - pa[:3])
                rk = pk[3:].reshape(3, 3)
                dyaw = math.atan2(rk[1, 0], rk[0, 0]) - yaw_a
                dyaw = (dyaw + math.pi) % (2 * math.pi) - math.pi
                pose_sim[j] = [dp[0], dp[1], dyaw]
                lk = log.pose[k]
                dx, dy = lk[0] - la[0], lk[1] - la[1]
                lrel = [ca * dx + sa * dy, -sa * dx + ca * dy, lk[2] - la[2]]
                pose_res[j] = pose_sim[j] - np.array(lrel)
        return WindowResult(w, scored, resid, simv, pose_idx, pose_res, pose_sim)

    def run(self, logs: list[PreparedLog], windows: list[Window]) -> list[WindowResult]:
        """Replay ``windows`` in order; inside :func:`parallel_replays` split over processes.

        Every window starts from a full reset (:meth:`RoverSim.reset`), so where it runs
        does not change its numbers (tested). Logs prepared for another speed loop get
        their setpoints again for this one (:func:`for_config`).

        A run repeated with the same configuration, settings, log objects and windows is
        answered from :data:`_RUNS` (read-only arrays): the same numbers, since a replay is a
        pure function of them. Why: the model-form stage replayed its nominal model again
        before each form it fitted, 3 % of a slope case's replays (stop 108's count)."""
        key = json.dumps(
            [
                to_dict(self.cfg),
                repr(self.settings),
                self.backend,
                self.contacts,
                self.sensors,
                [id(p) for p in logs],
                [(w.log_index, w.k0, w.k1) for w in windows],
            ],
            sort_keys=True,
            default=str,
        )
        hit = _RUNS.get(key, logs)
        if hit is not None:
            return list(hit)
        out = self._run(logs, windows)
        for r in out:
            for a in (r.idx, r.resid, r.sim, r.pose_idx, r.pose_resid, r.pose_sim):
                a.setflags(write=False)
        _RUNS.put(key, logs, out)
        return list(out)

    def _run(self, logs: list[PreparedLog], windows: list[Window]) -> list[WindowResult]:
        """:meth:`run` without the memo."""
        used = {w.log_index for w in windows}
        logs = [for_config(p, self.cfg) if i in used else p for i, p in enumerate(logs)]
        pool, n = _PARALLEL
        if pool is None or len(windows) < 2 * n:
            return [self.run_window(logs[w.log_index], w) for w in windows]
        bounds = np.linspace(0, len(windows), n + 1).round().astype(int)
        chunks = [windows[a:b] for a, b in itertools.pairwise(bounds)]
        # A worker keeps one simulator per key: everything the simulator is built from.
        key = json.dumps(
            [to_dict(self.cfg), self.backend, self.contacts, self.sensors],
            sort_keys=True,
            default=str,
        )
        futures = [
            pool.submit(
                _replay_chunk,
                key,
                self.cfg,
                self.settings,
                self.backend,
                self.contacts,
                self.sensors,
                {i: logs[i] for i in {w.log_index for w in c}},
                c,
            )
            for c in chunks[1:]
        ]
        out = [self.run_window(logs[w.log_index], w) for w in chunks[0]]
        for f in futures:
            out.extend(f.result())
        return out


_RUNS: Kept[list[WindowResult]] = Kept(16)
"""Recent :meth:`Replayer.run` answers, by configuration, settings, logs and windows."""

_PARALLEL: tuple[Executor | None, int] = (None, 1)
_WORKER_REPLAYERS: dict[str, Replayer] = {}


def _replay_chunk(
    key: str,
    cfg: RoverConfig,
    settings: ReplaySettings,
    backend: str,
    contacts: bool,
    sensors: bool,
    logs: dict[int, PreparedLog],
    windows: list[Window],
) -> list[WindowResult]:
    """A worker's share of :meth:`Replayer.run` (its simulator kept per configuration)."""
    rp = _WORKER_REPLAYERS.get(key)
    if rp is None or rp.settings != settings:
        if len(_WORKER_REPLAYERS) >= 4:
            _WORKER_REPLAYERS.clear()
        rp = _WORKER_REPLAYERS[key] = Replayer(cfg, settings, backend, contacts, sensors)
    return [rp.run_window(logs[w.log_index], w) for w in windows]


@contextmanager
def parallel_replays(workers: int) -> Iterator[None]:
    """Within: every :meth:`Replayer.run` of this process splits its windows over
    ``workers`` processes (this one and ``workers - 1`` forked ones). For the serial stages
    of ``diagnose`` (model form, replay floors, bias, evidence); no-op for ``workers <= 1``
    or where fork is unavailable."""
    global _PARALLEL
    if workers <= 1 or "fork" not in mp.get_all_start_methods() or _PARALLEL[0] is not None:
        yield
        return
    pool = ProcessPoolExecutor(
        workers - 1,
        mp_context=mp.get_context("fork"),
        initializer=die_with_parent,
        initargs=(os.getpid(),),
    )
    _PARALLEL = (pool, workers)
    try:
        yield
    finally:
        _PARALLEL = (None, 1)
        pool.shutdown(wait=True, cancel_futures=True)


def pool_map(fn: Callable[..., T], args: list[tuple[Any, ...]]) -> list[T]:
    """``fn(*a)`` for each ``a`` of ``args``, in order; inside :func:`parallel_replays` all
    but the first in the pool's processes while this one runs the first. For whole-drive
    simulations (a model's twin of each drive), which cannot be split into windows."""
    pool, _ = _PARALLEL
    if pool is None or len(args) < 2:
        return [fn(*a) for a in args]
    futures = [pool.submit(fn, *a) for a in args[1:]]
    first = fn(*args[0])
    return [first, *(f.result() for f in futures)]


def serial_replays() -> None:
    """In a forked child (a candidate-fit worker): replay here, never through the parent's
    pool (its processes belong to the parent)."""
    global _PARALLEL
    _PARALLEL = (None, 1)


def replay_arrays(results: list[WindowResult]) -> dict[str, Array]:
    """The replay as plain arrays (for saving and exact comparison)."""
    return {
        "sim": np.concatenate([r.sim for r in results]) if results else np.zeros((0, 11)),
        "resid": np.concatenate([r.resid for r in results]) if results else np.zeros((0, 11)),
        "pose_sim": np.concatenate([r.pose_sim for r in results]) if results else np.zeros((0, 3)),
    }


def replay_config(
    cfg_path: str | Path | RoverConfig,
    logs: list[DriveLog],
    settings: ReplaySettings | None = None,
    backend: str = "auto",
) -> dict[str, Array]:
    """Replay ``logs`` (all windows) with a rover configuration; see :func:`replay_arrays`."""
    from rover_env.config import load_rover

    cfg = cfg_path if isinstance(cfg_path, RoverConfig) else load_rover(cfg_path)
    st = settings or ReplaySettings()
    prepared = [prepare(lg, cfg, f"log{i}", st) for i, lg in enumerate(logs)]
    wins = make_windows(prepared, st)
    return replay_arrays(Replayer(cfg, st, backend).run(prepared, wins))
