"""The motors' torque limit read from the torque the drivers report (``effort_*`` columns).

Why: on hard ground the tires pass under a third of the motors' limit, so the wheel angles show
the limit only while a wheel spins up, where a cut acts as the rotor's inertia and the speed
loop do (``docs/calibration/limits.md``). A driver that reports its torque (ROS 2
``JointState.effort``: its current times its torque constant) shows the limit itself: while a
wheel lags its target and the motor pushes toward it, the reported torque holds at the limit.

The reading takes the samples where the motor is asked for more than it gives (the wheel at
least :data:`LAG` behind its loop's target, and beyond what the encoders resolve, the torque
pushing toward it), and among those the top: the samples within a few noise widths of the
largest. A current limit is a ceiling: the torque stops there whatever the demand. So the
top is a plateau where it holds :data:`EVENTS` separate events or more (a wheel spinning up
reaches it for 20-40 ms, one or two samples at 50 Hz; the wheels of one manoeuvre, within
:data:`MERGE` of each other, are one event) whose demands (the wheel's lag) differ by
:data:`SPREAD` or more, and no two samples running anywhere go beyond it; its median is the
limit. A repeated manoeuvre's own peak torque is the same at the same demand, and so is
not taken for one. Elsewhere the largest torque given is a lower bound only. The interval is
the plateau's standard error and the reported torque's scale (``tolerance``: the driver's
torque constant and the gearhead's efficiency, known to a datasheet's tolerance): a plateau
within it of the configured limit names nothing.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rover_env.logs import DriveLog

Array = NDArray[np.float64]

LAG = 0.3
"""rad/s a wheel must lag its target for its motor to count as asked for more than it gives:
beyond a speed loop's tracking while it follows (well under 0.1 rad/s on steady drives), so
a steady climb's level torque is not taken for the limit."""
EVENTS = 3
"""Separate events at the top that make a plateau (over all wheels and logs)."""
SPREAD = 1.5
"""Ratio of the largest to the smallest demand (lag) among them: the same torque at demands
this far apart is a ceiling, not the manoeuvre's own peak."""
MERGE = 0.5
"""Seconds within which runs at the top (any wheel of one log) are one event: one manoeuvre
tests the ceiling once. Why: behind an unnamed 0.2 s command lag one reversal's two wheels,
one of them dipping out of the top and back, made three runs at demands 1.54 x apart, a false
ceiling at 1.59 N m (exploratory seed 74091; a 0.6 s lag's one manoeuvre, 74099, six runs);
cuts of 5-78 % clipped in 9-30 manoeuvres a case, each read as before (74093-74095,
74500-74506)."""
BAND_SIGMAS = 4.0
"""Half-width of the top band in noise widths."""
Z = 1.96


@dataclass(frozen=True)
class EffortReading:
    """What the reported torque says of the limit (N m at the wheel)."""

    configured: float
    """The configuration's ``motor.torque_limit``."""
    tolerance: float
    """The reported torque's scale, known to +- this fraction."""
    samples: int
    """Finite torque samples over all logs and wheels."""
    asked: int
    """Of them, samples where the motor was asked for more than it gave."""
    noise: float
    """The reported torque's noise (N m, from its second differences)."""
    largest: float
    """The largest torque given where asked for more (0 where never asked)."""
    events: int
    """Separate events at the top (asked for more): runs within :data:`MERGE` are one."""
    held: int
    """Samples at the top, asked for more."""
    spread: float
    """Largest over smallest demand (lag, rad/s) among those events (0: none)."""
    level: float | None
    """The plateau's median (N m), where the top is one (see the module); else None."""
    se: float | None

    @property
    def plateau(self) -> bool:
        return self.level is not None

    def cut(self) -> tuple[float, float, float] | None:
        """The limit's change as a fraction of the configured one, with its interval (the
        plateau's standard error and the scale's tolerance); None without a plateau."""
        if self.level is None or self.se is None:
            return None
        lo_t, hi_t = self.level - Z * self.se, self.level + Z * self.se
        return (
            self.level / self.configured - 1.0,
            lo_t / (self.configured * (1.0 + self.tolerance)) - 1.0,
            hi_t / (self.configured * (1.0 - self.tolerance)) - 1.0,
        )

    def deepest_ruled_out(self) -> float | None:
        """Without a plateau: the cut the largest torque given rules out (deeper ones are
        impossible: the motor gave more), with the scale's tolerance; None where never asked."""
        if self.largest <= 0.0:
            return None
        return self.largest / (self.configured * (1.0 + self.tolerance)) - 1.0

    def as_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["cut"] = self.cut()
        out["deepest_ruled_out"] = None if self.plateau else self.deepest_ruled_out()
        return out


SPAN = 2
"""Samples each side of the central difference that gives a wheel's rate: over 4 intervals an
encoder's count is a quarter of the rate's step it is over one (0.15 rad/s for a 512-count
wheel at 50 Hz, against 0.6)."""


def wheel_rates(log: DriveLog) -> Array:
    """(N, 4) driven wheels' rates (rad/s), central differences over :data:`SPAN` samples each
    side (one-sided at the ends)."""
    phi, t = log.phi[:, :4], log.t
    n = len(t)
    hi = np.minimum(np.arange(n) + SPAN, n - 1)
    lo = np.maximum(np.arange(n) - SPAN, 0)
    return (phi[hi] - phi[lo]) / (t[hi] - t[lo])[:, None]


def rate_step(log: DriveLog) -> float:
    """The smallest change of :func:`wheel_rates` the encoders resolve (rad/s): their count
    (the smallest step of the logged angles) over the difference's span."""
    d = np.abs(np.diff(log.phi[:, :4], axis=0))
    d = d[d > 1e-12]
    if not d.size:
        return 0.0
    return float(np.quantile(d, 0.01) / (2 * SPAN * np.median(np.diff(log.t))))


def effort_noise(logs: list[DriveLog]) -> float:
    """Noise of the reported torque: the robust spread of its second differences (white noise
    of sigma gives sqrt(6) sigma there; the drives' own changes are rare, sharp and few)."""
    parts = []
    for log in logs:
        e = log.effort
        for j in range(e.shape[1]):
            col = e[:, j]
            ok = np.isfinite(col[:-2]) & np.isfinite(col[1:-1]) & np.isfinite(col[2:])
            d2 = (col[2:] - 2 * col[1:-1] + col[:-2])[ok]
            parts.append(d2)
    d2 = np.concatenate(parts) if parts else np.zeros(0)
    if d2.size < 10:
        return math.nan
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(start, stop) of each run of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


@dataclass(frozen=True)
class _Wheel:
    """One driven wheel of one log, as the reading walks it."""

    t: Array
    effort: Array
    torque: Array
    """|effort|, 0 where not measured."""
    lag: Array
    """The loop's target less the wheel's rate (rad/s)."""
    asked: NDArray[np.bool_]
    """Asked for more than it gave: lagging by the least asked or more, the torque toward it."""


def _walk(log: DriveLog, target: Array) -> list[_Wheel]:
    """``log``'s four driven wheels against their loops' ``target`` (N, 4)."""
    lag = target - wheel_rates(log)
    least = max(LAG, 2.0 * rate_step(log))
    out = []
    for j in range(4):
        e = log.effort[:, j]
        fin = np.isfinite(e)
        out.append(
            _Wheel(
                t=log.t,
                effort=e,
                torque=np.where(fin, np.abs(e), 0.0),
                lag=lag[:, j],
                asked=fin & (np.abs(lag[:, j]) >= least) & (e * lag[:, j] > 0),
            )
        )
    return out


def _events(walks: list[list[_Wheel]], top: float) -> tuple[list[tuple[float, float]], Array]:
    """The events at the top (torque >= ``top`` while asked): (start time, demand) each, runs
    of one log within :data:`MERGE` seconds of each other (any wheel) merged; and the torque
    of every sample in them."""
    events: list[tuple[float, float]] = []
    vals: list[Array] = []
    for wheels in walks:
        runs = []
        for w in wheels:
            for s, e in _runs(w.asked & (w.torque >= top)):
                runs.append((float(w.t[s]), float(w.t[e - 1]), float(np.max(np.abs(w.lag[s:e])))))
                vals.append(w.torque[s:e])
        runs.sort()
        end = -math.inf  # of this log's event so far
        for start, stop, demand in runs:
            if start - end <= MERGE:
                events[-1] = (events[-1][0], max(events[-1][1], demand))
                end = max(end, stop)
            else:
                events.append((start, demand))
                end = stop
    return events, np.concatenate(vals) if vals else np.zeros(0)


def read_limit(
    logs: list[DriveLog],
    configured: float,
    tolerance: float,
    targets: list[Array] | None = None,
) -> EffortReading | None:
    """The reading over ``logs`` (None where none reports torque). ``targets``: each log's
    (N, 4) speed targets as the motors' loops see them (after a command delay or lag the
    model has, :func:`rover_env.calibration.replay.loop_commands`); default the logged ones.
    Why: behind a lag the logged target runs ahead of the motor's, and a pivot's steady
    torque then looked held at a limit (exploratory seed 74070, a 0.4 s lag: 0.82 N m)."""
    pairs = [
        (log, log.cmd if targets is None else targets[i])
        for i, log in enumerate(logs)
        if log.has_effort
    ]
    with_effort = [log for log, _ in pairs]
    if not with_effort:
        return None
    if not (configured > 0 and 0 <= tolerance < 1):
        raise ValueError(f"configured limit {configured} and tolerance {tolerance}: out of range")
    noise = effort_noise(with_effort)
    walks = [_walk(log, target) for log, target in pairs]
    asks = [w for ws in walks for w in ws]
    samples = sum(int(np.isfinite(a.effort).sum()) for a in asks)
    asked = sum(int(a.asked.sum()) for a in asks)
    largest = max((float(a.torque[a.asked].max()) for a in asks if a.asked.any()), default=0.0)
    band = BAND_SIGMAS * noise if math.isfinite(noise) else 0.02 * largest
    band = max(band, 0.01 * largest)
    events, vals = _events(walks, largest - band)
    demand = [dm for _, dm in events]
    spread = max(demand) / min(demand) if demand else 0.0
    # A limit is a ceiling: no two samples running anywhere go beyond it.
    above = any(e - s >= 2 for a in asks for s, e in _runs(a.torque > largest + band))
    level = se = None
    if len(events) >= EVENTS and spread >= SPREAD and not above:
        level = float(np.median(vals))
        dev = float(np.std(vals, ddof=1))
        se = 1.2533 * max(dev, noise if math.isfinite(noise) else 0.0) / math.sqrt(vals.size)
    return EffortReading(
        configured=float(configured),
        tolerance=float(tolerance),
        samples=samples,
        asked=asked,
        noise=noise,
        largest=largest,
        events=len(events),
        held=int(vals.size),
        spread=spread,
        level=level,
        se=se,
    )
