"""The ground's tilt and the rover's resistance read from the motors' reported torque, or
from the wheels' slip: the force balance along the track on steady straight runs.

Why: the wheel angles and joints read a slope through this model's springs, tire and
geometry, and a clean build of another implementation is read at up to 2.4-4.7° there
(the clean-fit allowance, ``docs/calibration/limits.md``): its centres of mass sit a few
millimetres off and the joints lean as on a slope. The force the wheels push with does not
care where the mass sits. On a steady straight run the driven wheels' ground forces add up
to what holds the rover against gravity along its track plus what it loses rolling:

    sum_i effort_i / (d - delta) = m g sin(tilt) cos(yaw - heading) + R sign(v)

``d - delta`` is the lever from the axle to the contact point (the wheel radius less the
tire's deflection at static load, ``tire.C_z``: where this model's ground force acts), yaw
the rover's heading from the pose fixes (or, where a log has one fix or none, from its
free wheels fitted to it: :mod:`rover_env.calibration.heading`), ``m`` the configured
mass. Over runs in several headings and both directions the tilt vector (``m g sin(tilt)`` along x and y) and ``R`` come
from one least-squares fit over the runs' means; a slope flips sign with the heading and a
resistance with the direction of travel, so the two separate where a drive reverses or
turns (without both, :attr:`BalanceReading.separated` is False). A drivetrain's drag and the
reported torque's scale (``tolerance``) move ``R``; the scale moves the tilt by its own
fraction, and the interval carries it. A diagnostic read, like dead reckoning's radius: it
replays nothing.

Logs without the torque (SPEC §6's) get the same balance from the wheels' slip
(``source="slip"``): on hard ground a driven wheel passes its share of the traction through
slip, ``F = C_s S`` below the tire's critical slip (SPEC §3, eq. 13 with ``l_n`` near 1), and
the free wheels (segment 3's) roll with the ground. So a run's slip, one minus the free
wheels' turn over the driven wheels', relative to the direction of travel, times the four
driven tires' ``C_s``, is the traction along the track: a slope adds it going up and takes it
going down, while a wheel radius off, a rolling resistance, soil and sensor gains add the
same slip both ways (the fit's resistance term). Exploratory seeds 74713-74724: clean
builds of the independent generator read within 0.01 % of slip forwards against backwards
on one line, a 1° slope 1.43 % (``2 m g sin(1°) / (4 C_s)`` is 1.40 %).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from rover_env.calibration.heading import SOURCES as HEADING_SOURCES
from rover_env.calibration.heading import Headings, has_heading, headings
from rover_env.calibration.residuals import resolution
from rover_env.calibration.size_profile import SizeProfile, profile
from rover_env.config import DRIVEN_WHEELS, RoverConfig
from rover_env.logs import DriveLog

Array = NDArray[np.float64]

GRAVITY = 9.81
HOLD = 1.0
"""Seconds a run's targets must have held before its samples count: the speed loops settle
and the rover stops accelerating (the generator's and this model's loops settle in 0.3-0.6 s)."""
MIN_RUN = 0.5
"""Seconds of settled samples a run needs to count."""
MOVING = 0.3
"""rad/s of mean wheel target a run needs (a parked rover's torque holds whatever it last
needed: static friction decides it, not the balance)."""
STRAIGHT = 0.05
"""Largest difference of the left and right targets, as a fraction of their mean, a straight
run allows (a turn's scrub adds torque on both sides that is not the balance's)."""
MIN_RUNS = 6
"""Runs a reading needs: three unknowns and three degrees of freedom for their scatter."""
YAW_JOINTS = (1, 4)
"""theta_2 and theta_5, the yaw joints (SPEC §1)."""
BENT = math.radians(1.0)
"""Largest yaw of a joint from its median over the log a straight run allows: a rover left
bent by a turn scrubs on a straight run, its wheels pushing against each other (exploratory,
independent generator seed 74649: 6-7° bent, 0.5-0.7 N more to roll)."""
SCALE = 0.2
"""The summed torque's scale, known to +- this fraction: each motor's torque constant to a
build's tolerance (issue 47 lists motor gains of +-20 %), and one wheel can carry most of
the balance (2L carried 60-70 % of it on the independent generator's clean straight runs,
exploratory seed 74649), so the motors' errors need not average out. The torque limit's
reading keeps ``--effort-tolerance``: its plateau is each motor's own."""
SEPARATED = 200.0
"""Largest :attr:`BalanceReading.inflation` whose tilt a diagnosis names from: runs all one
way in about one heading leave the tilt along it and the resistance one unknown between
them, the fit trading a steep tilt against a negative resistance (exploratory seed 74683:
a 0.91° slope, every run forward within 6° of one heading, read 41.7° [15.4, 68.1] at
inflation 2261). Reads at 3-144 named their slopes right on exploratory seeds 74681-74700;
those in the thousands were unseparated."""
CLEAN_TILT = 0.5
"""Degrees a slope's interval must clear before the balance names it: what clean builds of
another implementation read. On 20 clean builds of the independent generator (exploratory
seeds 74661-74680) the intervals' low ends reached 0.10° (the tilts read, up to 1.3°, only
where the runs determine the tilt poorly and its interval is wide); 0.5° leaves room for an
implementation that is not that one."""
SLIP_SCALE = 0.2
"""The driven tires' slip stiffness (``tire.C_s``), known to +- this fraction, for the slip
balance: another implementation's tire passes the same traction at its own slip (the
independent generator read 2-7 % steeper than ``C_s`` says, exploratory seeds 74713-74728);
a real tire's stiffness is the paper's figure, not a measurement of this rover."""
CLEAN_SLIP_TILT = 0.3
"""Degrees a slope's interval must clear before the slip balance names it (see
:data:`CLEAN_TILT`). On 40 clean builds, drags and soils of the independent generator
(exploratory seeds 74725-74784, ``benchmarks/balance_reads.py --source slip``) and this
model's own clean build every interval reached level; 0.3° leaves room for an
implementation whose rover slips differently forwards and backwards."""
SLIP_FLOOR = 0.0008
"""Standard deviation (unit slip) a steady run's slip is given beyond the encoders'
resolution. On 30 clean builds and drags of the independent generator (exploratory seeds
74725-74784, 402 runs) the runs scattered by 0.02 % beyond it, but runs a few seconds after
a turn, the yaw joints still up to 1° off, slipped 0.2-0.3 % more (seed 74738): two such runs
in one heading read the tilt across the track alone. At 0.08 % those two cannot; the runs'
scatter counts where it is larger. Runs that scrub more still could: block 53600's clean
build 53637 was named 2.40° from two runs 1-2 s after turns that slipped 1.3-1.5 %
(limits.md); since stop 122 a run's samples count only :data:`TURN_SETTLE` s after a turn."""
SOURCES = ("effort", "slip")
"""What a run's traction is read from: the reported torque, or the wheels' slip."""
TURN_SETTLE = 3.0
"""Seconds after the last turning row (left and right targets apart by more than
:data:`STRAIGHT` of their mean, or a pivot) before a straight run's samples count: the chain
straightens and scrubs for a few seconds after a turn. Exploratory (the clean builds and
level-ground singles of seeds 74725-74784 and of spent block 53600, 598 runs): runs starting
within 4 s of a turn strayed from their case's level by up to 1.3 % of slip (95th percentile
0.4-0.5 %), later ones by up to 0.11 % and 0.72 %; block 53600's clean build 53637 was named
2.40° from two runs 1-2 s after turns. A log's first run, with no turn before it in the
log, counts as settled (a log cut just after a turn is not)."""
FIX_GAP = 2.0
"""Seconds from the nearest pose fix beyond which a row's heading is not known (the
generator's fixes come at 1 Hz; between fixes far apart a turn may have been made)."""
Z = 1.96


@dataclass(frozen=True)
class BalanceReading:
    """What the force balance says (forces in N, the tilt in degrees). Standard errors are
    the fit's own; the intervals scale them by Student's t over :attr:`dof` (the runs are
    few) and add the scale :attr:`tolerance` of the reported torque (or, for the slip, of
    the tires' slip stiffness)."""

    runs: int
    """Steady straight runs over all logs."""
    tilt_x: float
    """Tilt vector toward +x of the log frame, degrees (the ground rises that way)."""
    tilt_y: float
    sd_x: float
    """Standard error of :attr:`tilt_x` (degrees; inf where the runs leave it undetermined)."""
    sd_y: float
    corr: float
    """Correlation of the two parts' errors."""
    resistance: float
    """``R``: the force the rover loses rolling (N), as a coefficient of its weight below;
    for the slip, the slip the same both ways times the stiffness (:attr:`offset_slip`)."""
    sd_resistance: float
    dof: int
    """Runs less the three unknowns."""
    weight: float
    """``m g`` of the configured rover (N)."""
    lever: float
    """``d - delta`` at static load (m)."""
    tolerance: float
    """The reported torque's scale (or the tires' slip stiffness), known to +- this
    fraction."""
    inflation: float
    """How much worse the runs' headings and directions determine the worst of the three
    unknowns than runs spread evenly would (its standard error over the scatter's over the
    square root of the runs): runs all forward in one heading cannot tell a tilt from a
    resistance (inflation in the thousands, or inf)."""
    scatter: float
    """Standard deviation of the runs' means about the fit (N)."""
    source: str = "effort"
    """What the traction was read from (:data:`SOURCES`)."""
    stiffness: float = 0.0
    """The driven tires' summed slip stiffness (N per unit slip) the slip balance reads the
    traction with; 0 for the torque's."""
    heading_from: str = "pose"
    """Where the runs' headings came from (:data:`HEADING_SOURCES`, comma-separated where
    the logs differ): the pose's fixes, the free wheels fitted to each log's one fix, or
    the free wheels alone."""
    turned_f: float = 0.0
    """How much better the runs fit with each log's frame turned freely than in one frame
    (an F ratio over the turns' degrees of freedom; :func:`turned_frames`); 0 where the
    logs give their start headings or fewer than two logs have runs."""
    turned_deg: tuple[float, ...] = ()
    """Each log's best turn (degrees; the first log's 0), where :attr:`turned_f` is read."""
    frames_placed: str = "given"
    """How the logs' frames were placed: "given" (their start headings, or every drive
    facing alike), "fitted" or "unread" (``diagnose --frames fit``: the turns fitted, or
    under its F ratio the drives read as facing alike;
    :mod:`rover_env.calibration.diagnosis.frames`). In either of the last two
    :attr:`heading` is not known and its interval is the whole circle; the tilt's size
    stands. Why "fitted" too: on block 54000 (registered) 5 of 7 slopes named in fitted
    frames read their heading 31-132° off (54020: the mirror of the truth, each log's runs
    on about one line), while their sizes held."""
    size_bounds: tuple[float, float] | None = None
    """In frames that share nothing (``diagnose --frames fit``, fitted or not), the size's
    95 % interval from its profile over the turns
    (:func:`rover_env.calibration.size_profile.profile`; degrees, the high end ``inf``
    where the runs bound it below only), the scale tolerance not yet added; None
    elsewhere."""

    @property
    def tilt(self) -> float:
        """Degrees, the ground's rise toward :attr:`heading`."""
        return math.hypot(self.tilt_x, self.tilt_y)

    @property
    def heading(self) -> float:
        return math.degrees(math.atan2(self.tilt_y, self.tilt_x)) if self.tilt > 0 else 0.0

    @property
    def separated(self) -> bool:
        """Whether the runs' headings and directions tell the tilt from the resistance."""
        return self.inflation <= SEPARATED

    @property
    def t_scale(self) -> float:
        """Student's t over :data:`Z`: what the few runs' standard errors are scaled by."""
        return float(stats.t.ppf(0.975, self.dof)) / Z

    def tilt_se(self) -> tuple[float, float]:
        """The tilt vector's standard errors for a 95 % interval at :data:`Z` (degrees):
        Student's t's scaling, and the scale tolerance (the reported torque's, or the tires'
        slip stiffness'), which moves the whole vector by its fraction (so each part by the
        tilt's size times it)."""
        pad = self.tolerance * self.tilt / Z
        return (
            math.hypot(self.sd_x * self.t_scale, pad),
            math.hypot(self.sd_y * self.t_scale, pad),
        )

    def tilt_interval(self) -> tuple[float, float]:
        """95 % interval of the tilt's size: the vector's standard errors combined along its
        direction, as a fitted slope's (``Fit.physical``); from zero where level lies in the
        vector's own 95 % region (Hotelling's: its two parts' covariance, F over the runs'
        degrees of freedom), since a size near zero is read above it more often than not.
        In frames that share nothing the ends are :attr:`size_bounds`' (each with the scale
        tolerance in quadrature; from zero where the profile does not reject level)."""
        t, (sx, sy) = self.tilt, self.tilt_se()
        if self.size_bounds is not None:  # frames that share nothing: the profile's
            blo, bhi = self.size_bounds
            pad = self.tolerance * t
            lo = max(t - math.hypot(max(t - blo, 0.0), pad), 0.0)
            return lo, t + math.hypot(max(bhi - t, 0.0), pad)
        if not (math.isfinite(sx) and math.isfinite(sy)):
            return 0.0, math.inf
        ux, uy = (self.tilt_x / t, self.tilt_y / t) if t > 0 else (1.0, 0.0)
        se = math.sqrt((ux * sx) ** 2 + (uy * sy) ** 2)
        return (0.0 if self.level_inside() else max(t - Z * se, 0.0)), t + Z * se

    def heading_interval(self) -> tuple[float, float]:
        """95 % interval of :attr:`heading` (degrees; ends may pass +-180): the vector's
        error across its direction over its size, scaled by Student's t (the scale
        tolerance moves the size, not the direction); the whole circle where that reaches
        half of it or the runs leave the vector open. Checked on the slopes named by spent
        blocks 53700-53900 (exploratory): 38 of 40 truths inside."""
        t, half = self.tilt, 180.0
        if t > 0 and self.frames_placed == "given":
            px, py = -self.tilt_y / t, self.tilt_x / t  # across the vector's direction
            cxy = self.corr * self.sd_x * self.sd_y
            var = (px * self.sd_x) ** 2 + (py * self.sd_y) ** 2 + 2 * px * py * cxy  # deg^2
            if math.isfinite(var):  # its standard error over the size: radians, to degrees
                half = min(half, math.degrees(Z * self.t_scale * math.sqrt(max(var, 0.0)) / t))
        return self.heading - half, self.heading + half

    def level_inside(self) -> bool:
        """Whether a level ground lies in the tilt vector's 95 % region."""
        vx, vy = self.sd_x**2, self.sd_y**2
        cxy = self.corr * self.sd_x * self.sd_y
        det = vx * vy - cxy**2
        if not (math.isfinite(det) and det > 0.0):
            return True
        x, y = self.tilt_x, self.tilt_y
        q = (vy * x * x - 2 * cxy * x * y + vx * y * y) / det
        return q <= 2.0 * float(stats.f.ppf(0.95, 2, self.dof))  # the regression's F test

    @property
    def offset_slip(self) -> float:
        """The slip balance's resistance term as the slip it is (a radius or sensor gain off
        shows here as much as the ground's drag); NaN for the torque's balance."""
        return self.resistance / self.stiffness if self.stiffness > 0 else math.nan

    @property
    def c_rr(self) -> float:
        """The resistance as a rolling-resistance coefficient (of the weight)."""
        return self.resistance / self.weight

    def c_rr_interval(self) -> tuple[float, float]:
        """95 % interval of :attr:`c_rr`, each end moved away by the scale's tolerance."""
        half = Z * self.sd_resistance * self.t_scale
        lo, hi = (self.resistance - half) / self.weight, (self.resistance + half) / self.weight
        return lo - self.tolerance * abs(lo), hi + self.tolerance * abs(hi)

    def as_json(self) -> dict[str, Any]:
        """The reading for ``result.json``. For the slip, the lever and the rolling
        coefficient mean nothing (its second term holds a radius or a sensor gain off as
        much as a drag): null there, ``offset_slip`` in their place; NaN and infinity null."""
        out = asdict(self)
        slip = self.source == "slip"
        out.update(
            tilt=self.tilt,
            heading=self.heading,
            tilt_interval=list(self.tilt_interval()),
            heading_interval=list(self.heading_interval()),
            c_rr=None if slip else self.c_rr,
            c_rr_interval=None if slip else list(self.c_rr_interval()),
            lever=None if slip else self.lever,
            separated=self.separated,
            offset_slip=self.offset_slip,
            size_bounds=None if self.size_bounds is None else list(self.size_bounds),
        )
        return {k: _finite(v) for k, v in out.items()}


def _finite(v: Any) -> Any:
    """JSON has no infinity: None in its place (a bound the runs leave open)."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, list):
        return [_finite(x) for x in v]
    return v


@dataclass(frozen=True)
class Run:
    """One steady straight run's means."""

    log: int
    t0: float
    t1: float
    force: float
    """The traction along the heading (N): the driven wheels' summed torque over the lever
    (mean over the run), or the run's slip relative to its direction times the tires' slip
    stiffness, signed by the direction (the slip balance)."""
    cos_yaw: float
    sin_yaw: float
    direction: float
    """+1 forward, -1 backward."""
    noise: float = 0.0
    """The slip balance's standard error of :attr:`force` (N): :data:`SLIP_FLOOR` and the
    encoders' resolution over the run's turn; 0 for the torque's (its runs' own scatter)."""
    rows: tuple[int, int] = (0, 0)
    """The log's rows it spans (start, stop), for its heading read again."""


def stiffness(cfg: RoverConfig) -> float:
    """The driven tires' summed slip stiffness (N per unit slip): what converts the slip
    balance's slip to traction."""
    return cfg.tire.C_s * len(DRIVEN_WHEELS)


def critical_slip(cfg: RoverConfig) -> float:
    """The driven tire's critical slip at static load, ``3 mu_x F_z / C_s`` (SPEC §3, eq. 15):
    beyond it the whole contact patch slides and traction no longer grows as ``C_s S``; a
    run slipping that much (a stall, a spinning wheel, an encoder counting backwards) says
    nothing of the tilt by the slip balance's reading."""
    f_z = cfg.masses.total * GRAVITY / 6
    return 3.0 * cfg.tire.mu_x * f_z / cfg.tire.C_s


def lever(cfg: RoverConfig) -> float:
    """The axle's height above the contact point at static load: the wheel radius less the
    tire's deflection under a sixth of the weight."""
    delta = cfg.masses.total * GRAVITY / 6 / cfg.tire.C_z
    return cfg.geometry.wheel_radius - delta


def _yaw(log: DriveLog) -> Array | None:
    """The heading at every row, interpolated between pose fixes with a yaw; NaN farther than
    :data:`FIX_GAP` from every fix (a turn between two fixes far apart is not a line). None
    with fewer than two fixes."""
    if not has_heading(log):
        return None
    yaw = log.pose[:, 2]
    have = np.isfinite(yaw)
    tf = log.t[have]
    out = np.interp(log.t, tf, np.unwrap(yaw[have]))
    k = np.clip(np.searchsorted(tf, log.t), 1, len(tf) - 1)
    near = np.minimum(np.abs(log.t - tf[k - 1]), np.abs(tf[k] - log.t))
    return np.where(near <= FIX_GAP, out, np.nan)


def _since_turn(t: Array, left: Array, right: Array) -> Array:
    """Seconds since the last turning row (inf where none came before)."""
    mean = 0.5 * (left + right)
    turning = np.abs(left - right) > STRAIGHT * np.maximum(np.abs(mean), MOVING)
    last = np.maximum.accumulate(np.where(turning, np.arange(len(t)), -1))
    return np.where(last >= 0, t - t[np.maximum(last, 0)], np.inf)


def _held(t: Array, cmd: Array) -> Array:
    """Seconds each row's targets have held unchanged."""
    changed = np.r_[True, np.any(np.abs(np.diff(cmd, axis=0)) > 1e-9, axis=1)]
    start = np.maximum.accumulate(np.where(changed, np.arange(len(t)), 0))
    return np.asarray(t - t[start], dtype=np.float64)


def runs(
    log: DriveLog,
    index: int,
    per_unit: float,
    source: str = "effort",
    slip_limit: float = math.inf,
    settle: float = TURN_SETTLE,
    yaw: Array | None = None,
) -> list[Run]:
    """The log's steady straight runs: targets held :data:`HOLD` s, equal on both sides to
    :data:`STRAIGHT`, moving, ``settle`` s after the last turn (:data:`TURN_SETTLE`); each a
    stretch of :data:`MIN_RUN` s or more with the heading known (``yaw``; by default the
    pose's, :func:`_yaw`) and, for ``source`` "effort", the torque of every driven wheel.
    ``per_unit``: the lever (m) for the torque, the tires' slip stiffness (N) for the slip;
    for the slip, runs slipping ``slip_limit`` or more either way are left out
    (:func:`critical_slip`)."""
    yaw = _yaw(log) if yaw is None else yaw
    if yaw is None or (source == "effort" and not log.has_effort):
        return []
    bent = np.abs(
        log.theta[:, list(YAW_JOINTS)] - np.median(log.theta[:, list(YAW_JOINTS)], axis=0)
    )
    left, right = log.cmd[:, [0, 2]].mean(axis=1), log.cmd[:, [1, 3]].mean(axis=1)
    mean = 0.5 * (left + right)
    ok = (
        (_held(log.t, log.cmd) >= HOLD)
        & (np.abs(mean) >= MOVING)
        & (np.abs(left - right) <= STRAIGHT * np.abs(mean))
        & np.all(bent <= BENT, axis=1)
        & np.isfinite(yaw)
        & (_since_turn(log.t, left, right) >= settle)
    )
    if source == "effort":
        ok &= np.all(np.isfinite(log.effort), axis=1)
    out: list[Run] = []
    edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(np.int8), 0]))
    res = resolution(log.phi)
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if log.t[b - 1] - log.t[a] < MIN_RUN:
            continue
        s = slice(a, b)
        direction = float(np.sign(np.mean(mean[s])))
        turned = log.phi[b - 1] - log.phi[a]
        slip = _slip(turned) if source == "slip" else 0.0
        if not abs(slip) < slip_limit:
            continue  # the patch slides (or a wheel stalls): traction is not C_s S there
        out.append(
            Run(
                log=index,
                t0=float(log.t[a]),
                t1=float(log.t[b - 1]),
                force=(
                    float(np.mean(log.effort[s].sum(axis=1)) / per_unit)
                    if source == "effort"
                    else direction * slip * per_unit
                ),
                cos_yaw=float(np.mean(np.cos(yaw[s]))),
                sin_yaw=float(np.mean(np.sin(yaw[s]))),
                direction=direction,
                noise=0.0 if source == "effort" else _slip_noise(turned, res) * per_unit,
                rows=(int(a), int(b)),
            )
        )
    return out


def _slip_noise(turned: Array, res: float) -> float:
    """A run's slip's standard error: :data:`SLIP_FLOOR` and the resolution ``res`` at both
    ends of each wheel's turn (uniform, variance ``res^2 / 12`` an end), through the four
    driven wheels' mean and the two free wheels' (``res / (2 sqrt 2 |turn|)``)."""
    driven = abs(float(np.mean(turned[: len(DRIVEN_WHEELS)])))
    q = res / (2.0 * math.sqrt(2.0) * driven) if driven > 0 else math.inf
    return math.hypot(SLIP_FLOOR, q)


def _slip(turned: Array) -> float:
    """A run's slip relative to its direction of travel from the six wheels' turn over it:
    one minus the free wheels' mean over the driven wheels' mean (WHEELS order, the free
    wheels last). Positive where the driven wheels spin ahead of the ground."""
    driven = float(np.mean(turned[: len(DRIVEN_WHEELS)]))
    free = float(np.mean(turned[len(DRIVEN_WHEELS) :]))
    return 1.0 - free / driven if driven != 0.0 else math.inf


def _solve(rs: list[Run], source: str) -> tuple[Array, Array, Array, Array, int]:
    """The runs' least squares: the tilt vector's two forces and the resistance, their
    covariance, the design's own inverse (for the inflation), the residuals and the degrees
    of freedom. The slip's runs are weighed by their known noise, and their scatter about it
    counts only where it is larger; the torque's runs are alike, their scatter all there is."""
    X = np.array([[r.cos_yaw, r.sin_yaw, r.direction] for r in rs])
    y = np.array([r.force for r in rs])
    w = np.array([1.0 / r.noise for r in rs]) if source == "slip" else np.ones(len(rs))
    coef, *_ = np.linalg.lstsq(X * w[:, None], y * w, rcond=None)
    resid = y - X @ coef
    dof = len(rs) - X.shape[1]
    s2 = float(np.sum((resid * w) ** 2)) / dof
    if source == "slip":
        s2 = max(s2, 1.0)
    try:  # not a pseudo-inverse: it drops the direction the runs leave undetermined
        inv = np.linalg.inv(X.T @ X)
        cov = s2 * np.linalg.inv((X * w[:, None]).T @ (X * w[:, None]))
    except np.linalg.LinAlgError:
        inv = np.full((3, 3), np.inf)
        cov = np.full((3, 3), np.inf)
    return coef, cov, inv, resid, dof


def turned_frames(
    rs: list[Run],
    yaws: list[Array | None],
    source: str,
    weight: float,
    prof: SizeProfile | None = None,
) -> tuple[float, tuple[float, ...]]:
    """Whether the runs read the ground turned between logs: each log's heading turned by
    its own angle (the first log's held; a 5° grid, three sweeps over the logs, then 1°
    steps; or the turns at the size profile's best (:func:`size_profile`) where those fit
    better: a search log by log can stop in a mirror's valley), and the F ratio of what
    that explains over what is left, with the turns' degrees of freedom. ``weight``:
    ``m g`` (N); ``prof``: the runs' size profile where the caller has it (else read
    here).
    Logs that started facing different ways without saying so (``start_heading_deg``) read
    one slope in as many directions; but runs in few headings can fit better turned too
    (:data:`~rover_env.calibration.diagnosis.balance_stage.TURNED_F`; docs/calibration/
    method.md, step 5)."""
    logs = sorted({r.log for r in rs})
    if len(logs) < 2:
        return 0.0, ()

    def rss(turn: Array) -> float:
        return _misfit(rs, yaws, source, turn)

    turn = np.zeros(len(yaws))
    before = best = rss(turn)
    # Three sweeps of a 5° grid over the whole turn, then two of 1° steps about each
    # log's turn (the grid's resolution alone would turn a slope's heading by up to 2.5°).
    coarse = [np.radians(np.arange(0.0, 360.0, 5.0))] * 3
    for grid in [*coarse, None, None]:
        for i in logs[1:]:
            near = turn[i] + np.radians(np.arange(-4.0, 5.0, 1.0))
            tries = [
                (rss(np.where(np.arange(len(yaws)) == i, g, turn)), g)
                for g in (near if grid is None else grid)
            ]
            best, turn[i] = min(tries, key=lambda t: t[0])
    beta = (prof or size_profile(rs, source, weight)).angles
    other = np.array([beta[j] - beta[logs[0]] if j in beta else 0.0 for j in range(len(yaws))])
    if (got := rss(other)) < best:
        best, turn = got, other
    k = len(logs) - 1
    dof = len(rs) - 3 - k
    if dof <= 0 or best <= 0.0:
        return 0.0, ()
    f = (before - best) / k / (best / dof)
    return max(f, 0.0), tuple(float(math.degrees(math.remainder(t, 2 * math.pi))) for t in turn)


def size_profile(rs: list[Run], source: str, weight: float) -> SizeProfile:
    """The tilt's size profiled over each log's free turn (:mod:`.size_profile`), the runs
    weighed as :func:`_solve` weighs them. ``weight``: ``m g`` (N)."""
    X = np.array([[r.cos_yaw, r.sin_yaw, r.direction] for r in rs])
    w = np.array([1.0 / r.noise for r in rs]) if source == "slip" else np.ones(len(rs))
    y = np.array([r.force for r in rs])
    return profile(X, y, w, np.array([r.log for r in rs]), weight, source == "slip")


def _turned(yaws: list[Array | None], turn: Array) -> list[Array | None]:
    """``yaws`` with each log's turned by its ``turn`` (rad)."""
    return [None if y is None else y + turn[j] for j, y in enumerate(yaws)]


def _misfit(rs: list[Run], yaws: list[Array | None], source: str, turn: Array) -> float:
    """The runs' weighted residual sum of squares with each log's heading turned by its
    ``turn`` (rad), the tilt and resistance fitted again (weights as :func:`_solve`'s)."""
    w = np.array([1.0 / r.noise for r in rs]) if source == "slip" else np.ones(len(rs))
    resid = _solve(_headed(rs, _turned(yaws, turn)), source)[3]
    return float(np.sum((resid * w) ** 2))


def _both_ways(
    rs: list[Run], source: str, plus: list[Array | None], minus: list[Array | None]
) -> Array:
    """What moving the runs' headings (to ``plus`` and to ``minus``, one standard deviation
    each way) adds to the tilt's covariance: the outer product of half the tilt's move."""
    half = 0.5 * (
        _solve(_headed(rs, plus), source)[0][:2] - _solve(_headed(rs, minus), source)[0][:2]
    )
    return np.asarray(np.outer(half, half), dtype=np.float64)


def _headed(rs: list[Run], yaws: list[Array | None]) -> list[Run]:
    """The runs with their headings read again from ``yaws`` (a log's heading moved)."""
    out = []
    for r in rs:
        yaw = yaws[r.log]
        if yaw is None:
            out.append(r)
            continue
        s = slice(*r.rows)
        c, n = float(np.mean(np.cos(yaw[s]))), float(np.mean(np.sin(yaw[s])))
        out.append(replace(r, cos_yaw=c, sin_yaw=n))
    return out


def _read_runs(
    logs: list[DriveLog], cfg: RoverConfig, source: str
) -> tuple[Headings, list[Array | None], list[Run]]:
    """The logs' headings, each log's heading in the shared frame, and their steady straight
    runs."""
    if source not in SOURCES:
        raise ValueError(f"source must be one of {SOURCES}, got {source!r}")
    arm, cs, sc = lever(cfg), stiffness(cfg), critical_slip(cfg)
    hd = headings(logs, cfg, [_yaw(log) for log in logs])
    yaws = hd.yaw()
    rs = [
        r
        for i, log in enumerate(logs)
        for r in runs(log, i, arm if source == "effort" else cs, source, sc, yaw=yaws[i])
    ]
    return hd, yaws, rs


@dataclass(frozen=True)
class Turns:
    """Each log's frame turned into the first read one's (:func:`frame_turns`)."""

    f: float
    """The F ratio of what the turns explain over what is left (:func:`turned_frames`)."""
    deg: tuple[float, ...]
    """Per log, its turn (degrees; 0 for the first log with a run and for logs without)."""
    sd_deg: tuple[float, ...]
    """Per log, its turn's standard deviation (degrees, :func:`turn_sd`; 0 where held)."""
    runs: tuple[int, ...]
    """Per log, its steady straight runs."""


def frame_turns(logs: list[DriveLog], cfg: RoverConfig, source: str) -> Turns | None:
    """Each log's frame turned into the first's, where the drives did not share one and the
    logs cannot say (:mod:`rover_env.calibration.diagnosis.frames`): the turns of
    :func:`turned_frames` on the steady straight runs, with their standard deviations (a
    log with no run keeps its turn at 0: nothing reads its frame). None under
    :data:`MIN_RUNS`."""
    _, yaws, rs = _read_runs(logs, cfg, source)
    if len(rs) < MIN_RUNS:
        return None
    f, turns = turned_frames(rs, yaws, source, cfg.masses.total * GRAVITY)
    deg = turns or (0.0,) * len(logs)
    counts = tuple(sum(r.log == i for r in rs) for i in range(len(logs)))
    return Turns(f, deg, turn_sd(rs, yaws, source, deg), counts)


def turn_sd(
    rs: list[Run], yaws: list[Array | None], source: str, turns: tuple[float, ...]
) -> tuple[float, ...]:
    """Each turned log's turn's standard deviation (degrees): the runs' misfit against its
    turn moved 2° both ways, the others held, the tilt and resistance fitted again; the
    curvature's Gaussian width, scaled as :func:`_solve` scales (the slip's by its known
    noise, at least). 180 where moving it costs nothing. Why: a reading in fitted frames is
    otherwise as sure of the slope's heading as if the frames had been given."""
    logs = sorted({r.log for r in rs})
    base = np.radians(np.asarray(turns, dtype=np.float64))

    def rss(i: int, by: float) -> float:
        return _misfit(rs, yaws, source, base + np.where(np.arange(len(base)) == i, by, 0.0))

    dof = len(rs) - 3 - max(len(logs) - 1, 0)
    r0 = rss(-1, 0.0)
    s2 = r0 / dof if dof > 0 else math.inf
    if source == "slip":
        s2 = max(s2, 1.0)
    step = math.radians(2.0)
    out = [0.0] * len(turns)
    for i in logs[1:]:
        curv = (rss(i, step) + rss(i, -step) - 2.0 * r0) / step**2
        sd = math.sqrt(2.0 * s2 / curv) if curv > 0.0 and math.isfinite(s2) else math.pi
        out[i] = math.degrees(min(sd, math.pi))
    return tuple(out)


def read_balance(
    logs: list[DriveLog],
    cfg: RoverConfig,
    tolerance: float,
    source: str = "effort",
    turn_sd: tuple[float, ...] = (),
    free: bool = False,
) -> tuple[BalanceReading | None, list[Run]]:
    """The force balance over ``logs`` (None where they lack the torque (for ``source``
    "effort"), the pose's yaw or :data:`MIN_RUNS` steady straight runs), and the runs it
    used. ``tolerance``: the scale of the torque (or the tires' slip stiffness) as a
    fraction. ``turn_sd``: per log, the standard deviation (degrees) of a start heading that
    was fitted, not given (:class:`Turns`); the tilt's covariance carries it. ``free``: the
    logs share no frame (``diagnose --frames fit``, whether or not their turns were fitted):
    the tilt's size and its interval are its profile's over each log's free turn
    (:func:`size_profile`), the vector's direction kept."""
    hd, yaws, rs = _read_runs(logs, cfg, source)
    arm, cs = lever(cfg), stiffness(cfg)
    if len(rs) < MIN_RUNS:
        return None, rs
    used = {hd.source[r.log] for r in rs}
    coef, cov, inv, resid, dof = _solve(rs, source)
    # The headings' own uncertainty (logs without the pose's fixes): read again with them
    # moved along each principal direction of their fit, both ways; the tilt's moves add.
    for step in hd.steps():
        cov[:2, :2] += _both_ways(rs, source, hd.yaw(step), hd.yaw(-step))
    # Fitted frames' own uncertainty, the same way: each log's turned by its SD, both ways.
    for i, sd in enumerate(np.radians(np.asarray(turn_sd, dtype=np.float64))):
        if sd > 0.0:
            one = np.where(np.arange(len(yaws)) == i, sd, 0.0)
            cov[:2, :2] += _both_ways(rs, source, _turned(yaws, one), _turned(yaws, -one))
    weight = cfg.masses.total * GRAVITY
    # The tilt vector: its size from the force along it, its parts along the heading.
    size = math.degrees(math.asin(min(1.0, math.hypot(coef[0], coef[1]) / weight)))
    head = math.atan2(coef[1], coef[0])
    deg = math.degrees(1.0 / weight)  # N of force to degrees of tilt, near level
    sd = np.sqrt(np.abs(np.diag(cov)))
    corr = (
        float(cov[0, 1] / (sd[0] * sd[1]))
        if np.all(np.isfinite(sd[:2])) and sd[0] * sd[1] > 0
        else 0.0
    )
    infl = float(np.max(np.sqrt(np.abs(np.diag(inv))))) * math.sqrt(len(rs))
    # Logs that give no start heading are read as facing alike: how much turning each frame
    # would explain tells a report that they did not (:func:`turned_frames`).
    told = any(log.meta.start_heading_deg is not None for log in logs)
    # Frames that share nothing: the size and its interval from its profile over the turns
    # (which the turns' note reads too: one profile for both).
    prof = size_profile(rs, source, weight) if free or not told else None
    tf, td = (0.0, ()) if told else turned_frames(rs, yaws, source, weight, prof)
    size = size if prof is None or not free else prof.deg
    return (
        BalanceReading(
            runs=len(rs),
            tilt_x=size * math.cos(head),
            tilt_y=size * math.sin(head),
            sd_x=float(sd[0]) * deg,
            sd_y=float(sd[1]) * deg,
            corr=corr,
            resistance=float(coef[2]),
            sd_resistance=float(sd[2]),
            dof=dof,
            weight=weight,
            lever=arm,
            tolerance=tolerance,
            inflation=infl if math.isfinite(infl) else math.inf,
            scatter=math.sqrt(float(resid @ resid) / dof),
            source=source,
            stiffness=cs if source == "slip" else 0.0,
            heading_from=", ".join(h for h in HEADING_SOURCES if h in used),
            turned_f=tf,
            turned_deg=td,
            size_bounds=(prof.lo, prof.hi) if prof is not None and free else None,
        ),
        rs,
    )
