"""Open-loop skid-steer drive: speed targets from the commanded motion, no feedback."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from rover_env.config import RoverConfig
from rover_env.control.base import Controller, ControllerInput
from rover_env.estimation.estimator import static_rolling_radius

__all__ = ["OpenLoop", "skid_steer_targets"]

Array = npt.NDArray[np.float64]


def skid_steer_targets(
    speed: float, yaw_rate: float, half_track: float, rolling_radius: npt.ArrayLike
) -> Array:
    """No-slip wheel rates (rad/s, 1L 1R 2L 2R) for a segment moving at (speed, yaw_rate).

    Eqs. (7), (8) run backwards: a left wheel's hub moves at v - r w, a right one's at
    v + r w. Both driven axles get the middle segment's command: in a steady turn of the
    articulated chain each segment follows the same arc at the same speed and yaw rate.
    ``rolling_radius`` is one radius or four (1L 1R 2L 2R).
    """
    r_e = np.broadcast_to(np.asarray(rolling_radius, dtype=np.float64), (4,))
    hub = np.array(
        [
            speed - half_track * yaw_rate,
            speed + half_track * yaw_rate,
            speed - half_track * yaw_rate,
            speed + half_track * yaw_rate,
        ]
    )
    return np.asarray(hub / r_e, dtype=np.float64)


class OpenLoop(Controller):
    """Skid-steer kinematics with one effective rolling radius: the uncalibrated baseline.

    ``rolling_radius`` defaults to the slip estimator's (d minus the static deflection with
    the weight on six wheels), so the feed-forward and the estimator agree on what "no slip"
    means. Targets are clipped to the motor's ``max_wheel_speed``.

    ``gain`` (default 1) multiplies every target: a fixed over-speed, the simplest answer to
    slip on loose soil (a wheel needs 20-60 % of slip to pull there) and the no-learning
    reference beside agents that act on the wheels (spec ``open-loop@gain=K``).

    ``ramp`` (s, default 0: none) is a soft start: the over-speed grows linearly from 1 at
    the drive's start (``ControllerInput.t`` = 0) to ``gain`` at ``t = ramp``. Why: on the
    8 degree sand climb every fixed over-speed and the slip PI saturate the motor after
    ~3 s, so the whole difference between them is the start, where the PI's integrator
    happens to ramp its wheels up from the feed-forward over ~3 s and digs in less
    (``docs/benchmark-agents-mobility``); spec ``open-loop@gain=K@ramp=T``.
    """

    name = "open-loop"

    def __init__(
        self,
        rover_cfg: RoverConfig,
        rolling_radius: npt.ArrayLike | None = None,
        gain: float = 1.0,
        ramp: float = 0.0,
    ):
        if not (np.isfinite(gain) and gain > 0):
            raise ValueError(f"open-loop gain must be a finite number > 0, got {gain!r}")
        if not (np.isfinite(ramp) and ramp >= 0):
            raise ValueError(f"open-loop ramp must be a finite time >= 0 (s), got {ramp!r}")
        self.gain = float(gain)
        self.ramp = float(ramp)
        self.rover_cfg = rover_cfg
        r = static_rolling_radius(rover_cfg) if rolling_radius is None else rolling_radius
        self.rolling_radius = np.broadcast_to(np.asarray(r, dtype=np.float64), (4,)).copy()
        if not np.all(self.rolling_radius > 0):
            raise ValueError(f"rolling radius must be > 0, got {self.rolling_radius}")
        self.half_track = rover_cfg.geometry.half_track
        self.max_wheel_speed = rover_cfg.motor.max_wheel_speed

    def reset(self) -> None:
        """Stateless."""

    def feedforward(self, speed: float, yaw_rate: float) -> Array:
        """Unclipped targets for a command (what the slip PI corrects)."""
        return skid_steer_targets(speed, yaw_rate, self.half_track, self.rolling_radius)

    def act(self, obs: ControllerInput) -> Array:
        ff = self.feedforward(obs.speed_command, obs.yaw_rate_command)
        gain = self.gain
        if self.ramp > 0.0:
            gain = 1.0 + (gain - 1.0) * min(max(obs.t, 0.0) / self.ramp, 1.0)
        if gain != 1.0:
            ff = gain * ff
        return np.clip(ff, -self.max_wheel_speed, self.max_wheel_speed)
