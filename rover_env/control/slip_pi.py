"""Slip feedback (the paper's Fig. 8): a PI per driven wheel on its estimated slip ratio.

Each wheel's open-loop target is scaled by ``1 + u`` with ``u = Kp e + I`` and ``e`` the
wheel's estimated slip S less a reference shared by all wheels (zero unless they all slip,
see below), beyond a deadband (SPEC §3 sign: S < 0 spinning, S > 0 skidding). So a
spinning wheel is slowed and a dragged one sped up, relative to its own feed-forward: slip is
a ratio, so a relative correction has the same loop gain at every speed and keeps the sign of
the target (reversing works unchanged).

Why each piece is there:

* Deadband: |S - reference| below ``deadband`` is ignored, so that estimator noise and the
  small differences it cannot resolve do not keep the integrators wandering.
* Slip radius: the estimator uses one rolling radius for all wheels, but the axles carry
  different loads and roll on radii about 1 % apart (r_e = d − δ/3) (``axle_load_radii``); the rover's
  speed-controlled wheels then fight each other (front axle spinning, middle axle dragged, at
  a few tenths of a per cent each on flat ground), which the one-radius estimate cannot see. With
  ``slip_radius: axle_load`` the loop recomputes the slip from the estimate's filtered rates
  and the measured joint angles with per-axle loaded radii (the rover model's masses and
  tire stiffness: a calibration a real rover would measure instead).
* Traction allowance: in this tire model the force curve has no peak (SPEC §3), so slip
  shared by all wheels (a slope, an acceleration, digging in) is what carries the load, and
  slowing the wheels only slows the rover at the same slip ratio: it buys neither traction
  nor energy per metre. Each rolling wheel's slip is therefore measured against a reference,
  the median slip of the usable rolling wheels clipped to +-``traction_allowance``: slip
  inconsistent between wheels (a wheel spinning on an obstacle while the others roll, axles
  of different loaded radius fighting each other) is always corrected, slip shared by all
  only beyond the allowance. The shipped allowance is 1 (never: the one case where slowing
  pays, a rover that stands while its wheels turn, is the stuck detector's, below), and
  ``traction_allowance: 0`` gives the paper's plain loop, every wheel's slip toward zero.
  The median rather than the mean, so that one spinning wheel does not drag the reference
  and make the loop speed up the three healthy wheels. The reference also absorbs errors the
  estimate shares across wheels: on bumps it reads the same -0.4 on all four wheels for
  seconds while the true slip is a few per cent (``docs/benchmark/README.md``), and a PI
  cannot tell such a common error from slip, since speeding every wheel up by the same ratio
  leaves every slip ratio unchanged.
* Slip set-point (``slip_setpoint``, default 0): the centre of the traction allowance's band,
  so the shared slip is held within ``slip_setpoint +- traction_allowance``. On hard ground
  traction costs almost no slip and the band sits around 0. On loose soil a wheel pulls only
  while it slips (Wong's s = -S of 0.2-0.6 for useful drawbar pull), so a band around 0
  would slow the wheels exactly when the slope needs their pull; with a negative set-point
  and a narrow band the loop *speeds up* wheels that slip less than the set-point and slows
  those that dig in beyond it (``configs/control/slip_pi_soil.yaml``,
  ``docs/benchmark-soil/README.md``). With 0 the loop is the hard-ground one, bit for bit.
* Common-mode leak: within the allowance only the wheels' slip *differences* are observable,
  so where the four integrators settle together is set by history (a start-up transient,
  the deadband stopping each wheel anywhere within it), and a common offset of a few tenths
  of a per cent changes the rover's speed from the feed-forward's. While the shared slip is
  within the allowance and no wheel is stuck, the median of the integrators leaks back to
  zero with time constant ``common_mode_leak_time``: the feed-forward sets the speed, the
  loop only moves wheels relative to each other. The median, so that one wheel held at a
  limit is not "leaked" into speeding up the others.
* Axle-fight mode (``axle_fight_scale``): the four wheels' slip errors split into modes.
  The common mode sets the rover's speed and the left-right mode its yaw rate. The
  "axle fight", the front axle spinning while the middle one is dragged on both sides
  alike (mode ``[1, 1, -1, -1]`` over 1L 1R 2L 2R), changes neither to first order: it only
  wastes energy in slip. It is what is left within the deadband on an even surface. With
  ``axle_fight_scale`` < 1 that mode alone is measured against a narrower deadband
  (``deadband`` times the scale), so the fight is corrected without moving the modes that
  steer: the diagonal mode, which also leaves speed and yaw alone to first order, measurably
  yaws the rover on ice when tightened (``docs/benchmark-ppo/attempts.md``), so it keeps
  ``deadband``. Applied only while all four wheels are usable and none is stuck. 1 (the
  default) is the plain per-wheel deadband.
* Turn schedule: a skid-steer turn *needs* slip (outer wheels spin, inner ones skid) and a
  PI that removes it removes the turn. The deadband widens with the commanded turn
  ``half_track |w| / max(|v|, speed_floor)`` times ``turn_deadband_gain``.
* Output limits: ``min_correction`` bounds how far a wheel may be slowed, ``max_correction``
  how far sped up; the motor's ``max_wheel_speed`` caps the result. The default lower limit
  -1 stops a wheel entirely: a wheel that makes no progress has S = -1 at any speed above
  zero, so only stopping it removes its slip. ``retry_interval`` then releases the
  integrator of a wheel held at that limit (its estimate frozen, as a stopped wheel's is)
  so it tries again instead of giving up for good; ``stuck_retry_scale`` sets a stuck
  wheel's interval apart from that of a wheel merely frozen while the rover moves.
* Anti-windup: the integrator is clamped to the output limits and stops integrating in the
  direction of a saturated output (conditional integration), so it leaves a limit on the
  first sample the error changes sign.
* Frozen integrators: while a wheel's estimate is flagged unreliable (warm-up, free wheels
  contradicting the chain, standstill, slow wheel) the integrator holds its value and the
  proportional term is off; so does it while the wheel's feed-forward is zero (nothing to
  correct, and a stop must not wind anything up).
* Speed hold (``speed_hold_gain`` > 0): trimming a wheel's slip also trims the thrust that
  slip carried, so with the feed-forward alone a PI-corrected rover runs a fraction of a per
  cent slower than the open loop. A slow integrator on the relative error of the estimated
  forward speed of the middle segment adds one correction to every wheel (bounded by
  ``speed_hold_limit``), so the loop gives that speed back. It only integrates in straight
  driving with a reliable estimate and no stuck wheel (a turn's estimate carries the chain's
  side-slip, a stuck rover must not be pushed), above ``speed_floor`` and with a relative
  error inside ``speed_hold_window`` (a start from rest or a wheel against an obstacle is not
  a steady deficit); it holds its value otherwise and is cleared when a wheel is stuck. The
  wheels' corrections relative to each other are unchanged by it.
* Stuck detector, the one exception: when the rover has stood still (FLAG_STANDSTILL, no
  warm-up or free-wheel flag) for ``stuck_time`` seconds while a wheel is driven, that wheel
  makes no progress whatever its speed, so its slip is taken as -1 (eq. 10 divides by the
  tread speed when the hub stands; the estimator's flag is about the hub's speed as a
  divisor). This is the stuck wheel the controller exists for, and the estimator flags it
  unreliable. The persistence keeps a start from rest or a turn on the spot out of it.
  Stuck wheels are driven toward zero slip (reference 0), so they are stopped.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rover_env import kinematics as kin
from rover_env.config import ConfigError, RoverConfig, load_config
from rover_env.control.base import Controller, ControllerInput
from rover_env.control.open_loop import OpenLoop
from rover_env.estimation.estimator import (
    FLAG_FREE_WHEELS,
    FLAG_STANDSTILL,
    FLAG_WARMUP,
    axle_load_radii,
    static_rolling_radius,
)

__all__ = ["SlipPI", "SlipPIConfig", "load_slip_pi_config"]

Array = npt.NDArray[np.float64]

_SLIP_RADII = ("estimator", "axle_load")
_AXLE_FIGHT = np.array([1.0, 1.0, -1.0, -1.0])
"""The axle-fight mode over 1L 1R 2L 2R: front axle against middle axle, both sides alike."""


@dataclass(frozen=True)
class SlipPIConfig:
    """Gains and limits of :class:`SlipPI`; validated on construction (ConfigError)."""

    kp: float = 0.3
    """Relative speed correction per unit of slip beyond the deadband (1)."""
    ki: float = 1.0
    """Integral gain (1/s): relative correction per unit slip per second."""
    deadband: float = 0.01
    """|S - reference| below this is ignored (estimator noise, module docstring)."""
    turn_deadband_gain: float = 0.5
    """Extra deadband per unit of commanded turn ratio half_track |w| / |v|."""
    max_deadband: float = 0.5
    axle_fight_scale: float = 1.0
    """Deadband of the axle-fight mode as a multiple of ``deadband`` (module docstring; 1:
    the same deadband as every other mode)."""
    speed_floor: float = 0.05
    """Floor (m/s) of |v| in the turn ratio, so a turn on the spot does not divide by 0."""
    min_correction: float = -1.0
    """Lowest u: a wheel is slowed to no less than (1 + min_correction) of its target."""
    max_correction: float = 0.5
    """Highest u: a wheel is sped up to no more than (1 + max_correction) of its target."""
    traction_allowance: float = 1.0
    """Largest |slip - slip_setpoint| shared by all wheels that is left alone (module
    docstring)."""
    slip_setpoint: float = 0.0
    """Slip S the shared slip is held near (SPEC sign: < 0 spinning; Wong's s = -S): the
    centre of the traction allowance's band. 0 on hard ground, where traction costs almost
    no slip; negative on loose soil, where a wheel pulls only while it slips (module
    docstring, "Slip set-point")."""
    retry_interval: float = 5.0
    """Seconds a wheel may sit frozen at ``min_correction`` before its integrator is released
    (0: never)."""
    stuck_retry_scale: float = 1.0
    """Retry interval of a wheel held because the rover is stuck, as a multiple of
    ``retry_interval`` (a frozen wheel of a moving rover keeps ``retry_interval``)."""
    slip_radius: str = "axle_load"
    """Rolling radii the slip is measured with: "estimator" uses the estimate as given;
    "axle_load" recomputes it from the same filtered rates with per-axle loaded radii
    (:func:`rover_env.estimation.estimator.axle_load_radii`), which sees the fight between
    axles of different loaded radius that one common radius hides."""
    stuck_time: float = 1.0
    """Seconds of standstill while driven before a wheel counts as stuck (0: never)."""
    common_mode_leak_time: float = 2.0
    """Time constant (s) of the common-mode leak (module docstring; 0: no leak)."""
    speed_hold_gain: float = 0.0
    """Integral gain (1/s) of the speed hold: common correction per unit relative error of
    the estimated forward speed per second (module docstring; 0: off)."""
    speed_hold_limit: float = 0.05
    """Largest |common correction| the speed hold may add to every wheel (1)."""
    speed_hold_window: float = 0.2
    """The speed hold integrates only while |relative speed error| is below this: larger
    errors are a start from rest, an obstacle or a stuck wheel, not a steady deficit."""

    def __post_init__(self) -> None:
        for name in (
            "kp",
            "ki",
            "deadband",
            "turn_deadband_gain",
            "max_deadband",
            "axle_fight_scale",
            "traction_allowance",
            "retry_interval",
            "stuck_retry_scale",
            "stuck_time",
            "common_mode_leak_time",
            "speed_hold_gain",
            "speed_hold_limit",
            "speed_hold_window",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"slip_pi.{name} must be a finite number >= 0, got {v!r}")
        for name in ("speed_floor",):
            v = getattr(self, name)
            if isinstance(v, bool) or not (math.isfinite(v) and v > 0):
                raise ConfigError(f"slip_pi.{name} must be a finite number > 0, got {v!r}")
        if not (math.isfinite(self.slip_setpoint) and -1.0 < self.slip_setpoint <= 0.0):
            raise ConfigError(
                f"slip_pi.slip_setpoint must lie in (-1, 0] (S < 0: spinning), "
                f"got {self.slip_setpoint!r}"
            )
        if not -1.0 <= self.min_correction <= 0.0:
            raise ConfigError(
                f"slip_pi.min_correction must lie in [-1, 0], got {self.min_correction!r}"
            )
        if not (math.isfinite(self.max_correction) and self.max_correction >= 0):
            raise ConfigError(f"slip_pi.max_correction must be >= 0, got {self.max_correction!r}")
        if self.deadband > self.max_deadband:
            raise ConfigError("slip_pi.deadband exceeds slip_pi.max_deadband")
        if self.slip_radius not in _SLIP_RADII:
            raise ConfigError(
                f"slip_pi.slip_radius must be one of {', '.join(_SLIP_RADII)}, "
                f"got {self.slip_radius!r}"
            )


def load_slip_pi_config(name_or_path: str | Path = "slip_pi") -> SlipPIConfig:
    """A shipped name (``configs/control/<name>.yaml``) or a YAML path."""
    return load_config(SlipPIConfig, name_or_path, "control")


def _deadzone(x: Array, width: Array) -> Array:
    return np.asarray(np.sign(x) * np.maximum(np.abs(x) - width, 0.0), dtype=np.float64)


class SlipPI(Controller):
    """Open-loop skid-steer feed-forward corrected per wheel by a PI on estimated slip.

    ``dt`` is the control period the integrator assumes when the input's time stamps cannot
    tell it (the first call after :meth:`reset`); afterwards it integrates over the actual
    time between calls.
    """

    name = "slip-pi"

    def __init__(
        self,
        rover_cfg: RoverConfig,
        cfg: SlipPIConfig | None = None,
        dt: float = 0.1,
        rolling_radius: npt.ArrayLike | None = None,
    ) -> None:
        self.cfg = cfg or SlipPIConfig()
        self.rover_cfg = rover_cfg
        self.feedforward = OpenLoop(rover_cfg, rolling_radius)
        self.max_wheel_speed = rover_cfg.motor.max_wheel_speed
        self.dt = float(dt)
        self.v_eps = rover_cfg.tire.v_eps
        radii = (
            axle_load_radii(rover_cfg)
            if self.cfg.slip_radius == "axle_load"
            else (static_rolling_radius(rover_cfg),) * 6
        )
        self._radii = np.asarray(radii, dtype=np.float64)
        self._chain = kin.ChainGeometry.from_config(rover_cfg, self._radii)
        self.reset()

    def reset(self) -> None:
        self.integral = np.zeros(4)
        self._t_prev: float | None = None
        self._standing = np.zeros(4)
        """Seconds each wheel has been driven while the rover stood still."""
        self._held = np.zeros(4)
        """Seconds each wheel has sat at the lower limit while stuck or frozen."""
        self.last_slip = np.zeros(4)
        self.last_active = np.zeros(4, dtype=bool)
        self.last_stuck = np.zeros(4, dtype=bool)
        self.last_correction = np.zeros(4)
        self.speed_hold = 0.0
        """Common relative correction of all wheels from the speed hold."""

    # ------------------------------------------------------------------ pieces
    def measured_slip(self, obs: ControllerInput) -> Array:
        """The slip ratio the loop acts on (the estimate, or re-based on per-axle radii)."""
        if self.cfg.slip_radius == "estimator":
            return obs.slip_ratio
        est = obs.estimate
        w3, v3 = kin.segment3_twist(np.asarray(est.phi_rate)[4:], self._chain)
        motion = kin.chain_motion(w3, v3, obs.theta, np.asarray(est.theta_rate), self._chain)
        nominal = kin.nominal_wheel_rates(motion, self._chain)
        return kin.slip_ratio(np.asarray(est.phi_rate)[:4], nominal, self._radii[:4], self.v_eps)

    def deadband(self, obs: ControllerInput, base: float | None = None) -> float:
        """Deadband for this command: wider in turns, which need slip. ``base`` replaces
        ``deadband`` as the straight-line width (the axle-fight mode's)."""
        c = self.cfg
        ratio = (
            self.rover_cfg.geometry.half_track
            * abs(obs.yaw_rate_command)
            / max(abs(obs.speed_command), c.speed_floor)
        )
        width = c.deadband if base is None else base
        return min(width + c.turn_deadband_gain * ratio, c.max_deadband)

    def shared_slip(self, slip: Array, ok: npt.NDArray[np.bool_]) -> float:
        """Median slip of the usable wheels (the set-point when none is usable)."""
        return float(np.median(slip[ok])) if ok.any() else self.cfg.slip_setpoint

    def reference(self, slip: Array, ok: npt.NDArray[np.bool_]) -> float:
        """Slip shared by the usable wheels, within the traction allowance of the set-point."""
        s0, a = self.cfg.slip_setpoint, self.cfg.traction_allowance
        return float(np.clip(self.shared_slip(slip, ok), s0 - a, s0 + a))

    def slip_error(
        self, x: Array, obs: ControllerInput, ok: npt.NDArray[np.bool_], all_moving: bool
    ) -> Array:
        """Each wheel's slip beyond the deadband (``x``: slip less the reference); with
        ``axle_fight_scale`` != 1 and all four wheels rolling and usable, the axle-fight mode
        is measured against its own deadband (module docstring)."""
        c = self.cfg
        e = np.where(ok, _deadzone(x, np.asarray(self.deadband(obs))), 0.0)
        if c.axle_fight_scale != 1.0 and all_moving:
            narrow = _deadzone(x, np.asarray(self.deadband(obs, c.deadband * c.axle_fight_scale)))
            e = e + _AXLE_FIGHT * (float(_AXLE_FIGHT @ (narrow - e)) / 4.0)
        return e

    # ------------------------------------------------------------------ step
    def act(self, obs: ControllerInput) -> Array:
        c = self.cfg
        ff = self.feedforward.feedforward(obs.speed_command, obs.yaw_rate_command)
        dt = self.dt if self._t_prev is None else max(obs.t - self._t_prev, 0.0)
        self._t_prev = obs.t
        driven = ff != 0
        flags = obs.flags
        soft = (flags & (FLAG_WARMUP | FLAG_FREE_WHEELS)) != 0
        standing = ((flags & FLAG_STANDSTILL) != 0) & ~soft & driven
        self._standing = np.where(standing, self._standing + dt, 0.0)
        stuck = standing & (c.stuck_time > 0) & (self._standing >= c.stuck_time)

        slip = np.asarray(self.measured_slip(obs), dtype=np.float64)
        ok = (flags == 0) & np.isfinite(slip) & driven
        slip = np.where(stuck, -1.0, np.nan_to_num(slip))
        moving = ok & ~stuck
        ok |= stuck
        # Stuck wheels are measured against zero slip, rolling ones against their shared slip.
        ref = self.reference(slip, moving)
        e = self.slip_error(slip - ref, obs, ok, moving.all())

        # Highest u the motor allows for each wheel, never below the lower limit.
        with np.errstate(divide="ignore"):
            motor_cap = np.where(driven, self.max_wheel_speed / np.abs(ff) - 1.0, np.inf)
        hi = np.maximum(np.minimum(c.max_correction, motor_cap), c.min_correction)
        lo = np.full(4, c.min_correction)
        u_raw = c.kp * e + self.integral
        # Conditional integration: never push further into a saturated limit.
        blocked = ((u_raw >= hi) & (e > 0)) | ((u_raw <= lo) & (e < 0))
        self.integral = np.clip(self.integral + np.where(ok & ~blocked, c.ki * e * dt, 0.0), lo, hi)
        shared = self.shared_slip(slip, moving)
        calm = not stuck.any() and abs(shared - c.slip_setpoint) <= c.traction_allowance
        if c.common_mode_leak_time > 0 and calm and driven.any():
            common = float(np.median(self.integral[driven]))
            leak = min(1.0, dt / c.common_mode_leak_time) * common
            self.integral = np.where(driven, np.clip(self.integral - leak, lo, hi), self.integral)
        self._hold_speed(obs, calm and driven.any() and bool(ok.any()), stuck.any(), dt)
        u = np.clip(c.kp * e + self.integral + self.speed_hold, lo, hi)
        if c.retry_interval > 0:
            held = (u <= lo) & (stuck | ~ok) & driven
            self._held = np.where(held, self._held + dt, 0.0)
            interval = np.where(stuck, c.retry_interval * c.stuck_retry_scale, c.retry_interval)
            retry = self._held >= interval
            self.integral[retry] = 0.0
            self._held[retry] = 0.0
            self._standing[retry] = 0.0
            u[retry] = 0.0
        self.last_slip, self.last_active, self.last_stuck, self.last_correction = slip, ok, stuck, u
        targets = ff * (1.0 + u)
        return np.asarray(
            np.clip(targets, -self.max_wheel_speed, self.max_wheel_speed), dtype=np.float64
        )

    def _hold_speed(self, obs: ControllerInput, active: bool, stuck: bool, dt: float) -> None:
        """Integrate the relative error of the estimated forward speed of the middle segment
        into one correction shared by all wheels (module docstring)."""
        c = self.cfg
        if c.speed_hold_gain <= 0 or stuck:
            self.speed_hold = 0.0
            return
        v_cmd = obs.speed_command
        if not active or abs(v_cmd) < c.speed_floor or obs.yaw_rate_command != 0.0:
            return  # hold: nothing trustworthy to compare with
        v_hat = float(np.asarray(obs.estimate.seg_velocity)[1, 0])
        err = (v_cmd - v_hat) / v_cmd  # > 0: too slow, in either direction of travel
        if abs(err) > c.speed_hold_window:
            return
        lim = c.speed_hold_limit
        self.speed_hold = float(np.clip(self.speed_hold + c.speed_hold_gain * err * dt, -lim, lim))


def replace(cfg: SlipPIConfig, **changes: float | str | bool) -> SlipPIConfig:
    """A copy with some fields changed (validated): the tuner's way to try gains."""
    return dataclasses.replace(cfg, **changes)  # type: ignore[arg-type]
