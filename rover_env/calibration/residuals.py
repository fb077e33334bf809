"""Residual bookkeeping: noise floors, per-signal and per-regime tables, the noise test.

Sensor noise is estimated from the logs themselves, not assumed: the encoder and
potentiometer resolution from the smallest step in the data, white noise from the robust
spread (MAD) of high-order differences (smooth motion cancels there). The test against
noise is deliberately conservative about the strong autocorrelation inside a window: each
window contributes one degree of freedom, its mean square divided by the noise variance
(a chi-square with as many degrees of freedom as windows under "noise only").
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from rover_env.calibration.replay import SIGNALS, Kept, PreparedLog, WindowResult, pool_map
from rover_env.config import JOINTS, RoverConfig, to_dict
from rover_env.logs import DriveLog

Array = NDArray[np.float64]

REGIMES = (
    "all",
    "straight",
    "left_turn",
    "right_turn",
    "accelerating",
    "braking",
    "reversing",
    "high_slip",
)


def resolution(x: Array) -> float:
    """The quantisation step of ``x`` (samples in rows), 0 if it is not quantised.

    Quantised data moves by whole counts, so the step is the smallest move that every
    move is (nearly) a multiple of. The smallest move is tried first: a wheel that turns 5-7
    counts per sample makes one-count moves rarer than 1 % (stop 54: the independent
    generator's 1024-count encoders were read as unquantised, the 1st percentile being two
    counts, and its wheels' replay floor came out without their 6.1 mrad quantisation); a
    whole fraction of it next, for a wheel that never moves by one count."""
    d = np.abs(np.diff(x, axis=0)).ravel()
    d = d[d > 1e-12]
    if d.size == 0:
        return 0.0
    for small in (float(d.min()), *(float(q) for q in np.percentile(d, [0.1, 1.0]))):
        for k in range(1, 9):  # the smallest move may itself be several counts
            step = small / k
            if np.mean(np.isclose(d / step, np.round(d / step), atol=0.02)) > 0.9:
                return step
    return 0.0


def _spread(e: Array) -> Array:
    """Robust standard deviation (MAD) of each column of ``e``."""
    return np.asarray(
        1.4826 * np.median(np.abs(e - np.median(e, axis=0)), axis=0), dtype=np.float64
    )


def interpolation_residuals(t: Array, x: Array) -> Array:
    """Each inner sample of ``x`` (rows at times ``t``) less the straight line through its
    two neighbours, in units of the white noise's standard deviation: with ``a`` the later
    neighbour's share, (x_i - a x_(i-1) - (1 - a) x_(i+1)) / sqrt(1 + a^2 + (1 - a)^2).
    Smooth motion cancels to first order however the samples are spaced.

    Why (stop 99): a logger's rows are not evenly spaced (a dropped row leaves a gap of two
    intervals; time stamps jitter by milliseconds), and a plain second difference then holds
    the motion, not the noise. On an independent-generator drive with 5 % of its rows
    dropped, three wheels' noise was read twice as large. On even rows it is the second
    difference over sqrt(6), as before. Residuals are taken log by log, never across the end
    of one log and the start of the next."""
    if len(t) < 3:
        return np.zeros((0, *x.shape[1:]))
    dt0, dt1 = np.diff(t)[:-1], np.diff(t)[1:]
    a = dt1 / (dt0 + dt1)
    b = 1.0 - a
    shape = (-1,) + (1,) * (x.ndim - 1)
    e = x[1:-1] - a.reshape(shape) * x[:-2] - b.reshape(shape) * x[2:]
    return np.asarray(e / np.sqrt(1.0 + a * a + b * b).reshape(shape), dtype=np.float64)


def even_differences(t: Array, x: Array, order: int) -> Array:
    """The ``order``-th differences of ``x`` (rows at times ``t``) over evenly spaced samples
    only: each difference's samples one median interval apart (within a quarter of it). The
    pose's fixes (about 1 s apart) are read this way: a fix missing leaves a gap, and a
    difference across it holds the motion."""
    dt = np.diff(t)
    if dt.size < order:
        return np.zeros((0, *x.shape[1:]))
    h = float(np.median(dt))
    even = np.abs(dt - h) <= 0.25 * h
    ok = np.ones(dt.size - order + 1, dtype=bool)
    for j in range(order):
        ok &= even[j : j + ok.size]
    return np.diff(x, n=order, axis=0)[ok]


def resolutions(logs: list[PreparedLog]) -> tuple[float, float]:
    """(wheel, joint) angle resolution found in the data (0 if not quantised)."""
    phi = np.concatenate([p.log.phi for p in logs])
    theta = np.concatenate([p.log.theta for p in logs])
    return resolution(phi), resolution(theta)


def noise_floor(logs: list[PreparedLog]) -> dict[str, float]:
    """Standard deviation of each residual signal expected from sensor noise alone."""
    phi = np.concatenate([p.log.phi for p in logs])
    theta = np.concatenate([p.log.theta for p in logs])
    res_w, res_j = resolution(phi), resolution(theta)
    e_w = np.concatenate([interpolation_residuals(p.log.t, p.log.phi) for p in logs])
    e_j = np.concatenate([interpolation_residuals(p.log.t, p.log.theta) for p in logs])
    s_w = np.maximum(_spread(e_w), res_w / np.sqrt(12))
    s_j = np.maximum(_spread(e_j), res_j / np.sqrt(12))
    out: dict[str, float] = {}
    for i, name in enumerate(SIGNALS[:6]):
        out[name] = float(max(s_w[i] * np.sqrt(2), 1e-6))  # increment = difference of two
    for i, name in enumerate(SIGNALS[6:11]):
        out[name] = float(max(s_j[i], 1e-6))
    fixes = [np.isfinite(p.log.pose[:, 0]) for p in logs]
    diffs = [
        even_differences(p.log.t[m][1:], p.log.pose[m][1:], 3)
        for p, m in zip(logs, fixes, strict=True)
    ]
    diffs = [d for d in diffs if len(d) >= 3]
    # a third difference of white noise has sqrt(20) times its standard deviation
    s_p = (
        np.median(np.array([_spread(d) / np.sqrt(20.0) for d in diffs]), axis=0)
        if diffs
        else np.full(3, np.nan)
    )
    for i, name in enumerate(SIGNALS[11:]):
        out[name] = float(max(s_p[i] * np.sqrt(2), 1e-4)) if np.isfinite(s_p[i]) else 1e-2
    return out


TwinStates = tuple[Array, Array, Array]
"""A twin drive's true wheel angles (N, 6), joint angles (N, 5) and pose (N, 3)."""


def twin_states(p: PreparedLog, cfg: RoverConfig) -> TwinStates:
    """The model driven from rest by ``p``'s logged commands on the log's declared ground
    (:func:`rover_env.calibration.ground.log_ground`): its true angles and pose at
    the log's sample times (:func:`twin_sensed` reads them through sensors), as MuJoCo's
    sensors read them: at the start of each row's last substep (a step computes its sensors
    and body poses before it integrates).

    Built as a replay is (no collisions, sensor stage or visual parts: the ground the log
    declares is the tire layer's alone) and driven in one :meth:`~RoverSim.drive_read`, each
    row's last substep apart: the same states to the bit as the sensed drive one checked
    step per row (tests/test_twin.py), for less (stop 109: twins took 13 s of a delay case's
    156 s with one worker)."""
    from rover_env.calibration.ground import log_ground
    from rover_env.sim.model import stable_config
    from rover_env.sim.recorder import relative_pose
    from rover_env.sim.simulator import RoverSim

    log = p.log
    sim = RoverSim(
        stable_config(cfg),
        log_ground(log),
        backend="auto",
        contacts=False,
        sensors=False,
        visuals=False,
    )
    sim.reset()
    n = np.diff(np.round(log.t / sim.dt).astype(np.int64))
    # Each row as its substeps but the last, then the last: the joints' coordinates read
    # after the first part are what the sensors read, the body's pose after the second (its
    # kinematics are computed at the start of the substep).
    ix = sim.index
    qi = np.concatenate([ix.wheel_qpos, ix.joint_qpos])
    q, pos, quat = sim.drive_read(
        np.repeat(log.cmd[: len(n)], 2, axis=0),
        np.column_stack([np.maximum(n - 1, 0), np.minimum(n, 1)]).ravel(),
        np.arange(2 * len(n) + 1),
        qi,
        int(ix.seg_body[2]),
        quat=True,
    )
    q, pos, quat = q[np.r_[0, 1 : len(q) : 2]], pos[0::2], quat[0::2]
    for k in np.flatnonzero(n == 0) + 1:  # no substep: the sensors hold what they held
        q[k], pos[k], quat[k] = q[k - 1], pos[k - 1], quat[k - 1]
    nw = len(ix.wheel_qpos)
    return q[:, :nw], q[:, nw:] + sim.joint_zero, relative_pose(pos, quat)


def twins_of(logs: list[PreparedLog], cfg: RoverConfig, used: set[int]) -> dict[int, TwinStates]:
    """:func:`twin_states` of the logs numbered in ``used``, side by side inside
    :func:`~rover_env.calibration.replay.parallel_replays` (each drive is one simulation from
    rest; the numbers do not depend on where it runs).

    A twin made before of the same log object under the same configuration is taken from
    :data:`_TWINS` (read-only arrays; a twin is a pure function of the two). Why: the
    odometry stage twins the named model's drives, whose held-out one the winner's replay
    floor twinned already (stop 109)."""
    order = sorted(used)
    model = json.dumps(to_dict(cfg), sort_keys=True, default=str)
    got = {i: _TWINS.get((model, id(logs[i])), [logs[i]]) for i in order}
    todo = [i for i in order if got[i] is None]
    for i, states in zip(todo, pool_map(twin_states, [(logs[i], cfg) for i in todo]), strict=True):
        for a in states:
            a.setflags(write=False)
        _TWINS.put((model, id(logs[i])), [logs[i]], states)
        got[i] = states
    return {i: v for i, v in got.items() if v is not None}


_TWINS: Kept[TwinStates] = Kept(32)
"""Recent twins by configuration and log (:func:`twins_of`)."""


def twin_sensed(
    p: PreparedLog,
    states: TwinStates,
    noise: dict[str, float],
    res: tuple[float, float],
    rng: np.random.Generator,
    encoder_phase: Array | None = None,
) -> DriveLog:
    """The drive as the model itself would have logged it through the same sensors: its
    twin's states (:func:`twin_states`) read through the resolution and noise found in the
    real logs, its pose through the estimated pose noise at the times the real log has pose.
    Replaying this twin gives the residual a perfect model would leave (the "replay floor":
    sensor noise seen through the window initialisation), against which the real residual is
    tested.

    ``encoder_phase`` (6,): where each wheel's travel starts on its encoder's grid, as a
    fraction of a count; None starts every wheel on a count. An encoder's quantisation error
    is a function of the true angle, so one twin trajectory gives independent draws of it
    only through its phase (:func:`rover_env.calibration.noise_interval.noise_draws`)."""
    from rover_env.estimation.sensors import quantize

    log = p.log
    ph0, th0, pose0 = states
    ph = ph0 - ph0[0]
    if encoder_phase is not None and res[0] > 0:
        ph = ph + np.asarray(encoder_phase, dtype=np.float64) * res[0]
    ph = quantize(ph, res[0]) if res[0] > 0 else ph
    th = th0.copy()
    j_noise = np.array([noise[j] for j in JOINTS])
    th = th + rng.normal(0.0, 1.0, th.shape) * np.sqrt(np.maximum(j_noise**2 - res[1] ** 2 / 12, 0))
    th = quantize(th, res[1]) if res[1] > 0 else th
    have = np.isfinite(log.pose[:, 0])
    ps = np.array([noise[s] for s in ("pose_x", "pose_y", "pose_yaw")]) / np.sqrt(2)
    pose = pose0 + rng.normal(0.0, 1.0, pose0.shape) * ps
    pose[~have] = np.nan
    pose[0] = np.where(have[0], 0.0, np.nan)
    # The source log's path: relative references in its YAML (terrain, rover) resolve alike.
    return DriveLog(log.t, log.cmd, ph, th, pose, log.meta, path=log.path)


@dataclass
class Stacked:
    """All scored residual rows of a set of windows, with their window and regime labels."""

    resid: Array
    """(n, 14): wheels (6), joints (5), pose (3; NaN on rows without a pose sample)."""
    window: NDArray[np.intp]
    regime: dict[str, NDArray[np.bool_]]


def stack(results: list[WindowResult], logs: list[PreparedLog]) -> Stacked:
    rows, wins = [], []
    reg: dict[str, list[NDArray[np.bool_]]] = {r: [] for r in REGIMES}
    for wi, r in enumerate(results):
        p = logs[r.window.log_index]
        n, m = len(r.idx), len(r.pose_idx)
        block = np.full((n + m, 14), np.nan)
        block[:n, :11] = r.resid
        block[n:, 11:] = r.pose_resid
        rows.append(block)
        wins.append(np.full(n + m, wi))
        idx = np.concatenate([r.idx, r.pose_idx])
        for name in REGIMES:
            reg[name].append(p.regimes[name][idx])
    if not rows:
        return Stacked(np.zeros((0, 14)), np.zeros(0, dtype=np.intp), {})
    return Stacked(
        np.concatenate(rows),
        np.concatenate(wins).astype(np.intp),
        {k: np.concatenate(v) for k, v in reg.items()},
    )


def signal_scale(st: Stacked, floor: dict[str, float]) -> dict[str, float]:
    """Per-signal scale: the larger of the signal's RMS residual in ``st`` and its floor."""
    scale = {}
    for j, name in enumerate(SIGNALS):
        col = st.resid[:, j]
        col = col[np.isfinite(col)]
        rms = float(np.sqrt(np.mean(col**2))) if col.size else 0.0
        scale[name] = max(rms, floor[name])
    return scale


def residual_vector(results: list[WindowResult], scale: dict[str, float]) -> Array:
    """All residuals divided by their signal's scale, as one vector (for least squares)."""
    sw = np.array([scale[s] for s in SIGNALS[:11]])
    sp = np.array([scale[s] for s in SIGNALS[11:]])
    parts = []
    for r in results:
        parts.append((r.resid / sw).ravel())
        parts.append((r.pose_resid / sp).ravel())
    return np.concatenate(parts) if parts else np.zeros(0)


def window_losses(results: list[WindowResult], scale: dict[str, float]) -> Array:
    """Sum of squared scaled residuals per window."""
    return np.array([float(np.sum(residual_vector([r], scale) ** 2)) for r in results])


def signal_window_ms(results: list[WindowResult], signal: str) -> Array:
    """Mean square of one signal's residual in each window (NaN where it has no sample)."""
    j = SIGNALS.index(signal)
    out = np.full(len(results), np.nan)
    for i, r in enumerate(results):
        col = r.resid[:, j] if j < 11 else r.pose_resid[:, j - 11]
        col = col[np.isfinite(col)]
        if col.size:
            out[i] = float(np.mean(col**2))
    return out


def window_slices(results: list[WindowResult]) -> list[slice]:
    """Where each window's residuals sit in :func:`residual_vector`'s output."""
    out, a = [], 0
    for r in results:
        n = r.resid.size + r.pose_resid.size
        out.append(slice(a, a + n))
        a += n
    return out


@dataclass
class Cell:
    rms: float
    n: int
    ratio: float
    """RMS / noise floor."""
    p: float
    """p-value of "noise only" (conservative chi-square, one dof per window)."""


def table(st: Stacked, noise: dict[str, float]) -> dict[str, dict[str, Cell]]:
    """RMS, ratio to noise and noise-test p per signal (rows) and regime (columns)."""
    out: dict[str, dict[str, Cell]] = {}
    for j, sig in enumerate(SIGNALS):
        out[sig] = {}
        for reg in REGIMES:
            mask = st.regime.get(reg, np.zeros(0, dtype=bool)) & np.isfinite(st.resid[:, j])
            if mask.sum() < 3:
                out[sig][reg] = Cell(float("nan"), int(mask.sum()), float("nan"), float("nan"))
                continue
            r = st.resid[mask, j]
            w = st.window[mask]
            ms = np.array([np.mean(r[w == k] ** 2) for k in np.unique(w)])
            stat = float(np.sum(ms) / noise[sig] ** 2)
            p = float(stats.chi2.sf(stat, len(ms)))
            rms = float(np.sqrt(np.mean(r**2)))
            out[sig][reg] = Cell(rms, int(mask.sum()), rms / noise[sig], p)
    return out
