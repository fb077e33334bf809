"""What a controller sees and the interface every controller implements.

A controller here is the software that would run on the real rover: it gets the sensor
readings, the slip estimator's output and the task command, never the simulator's truth, so
the same object can drive the bare simulator (:mod:`rover_env.control.runner`), the Gymnasium
environment (``ProtoExplorerEnv.controller_input``) or, in principle, the rover itself.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rover_env.config import ConfigError
from rover_env.estimation.estimator import SlipEstimate

__all__ = ["CommandSchedule", "Controller", "ControllerInput"]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ControllerInput:
    """One control instant as the rover's computer sees it (no ground truth).

    ``estimate`` carries the estimated slip ratios, their reliability flags, the estimated
    segment velocities and yaw rates and the filtered wheel and joint rates (SPEC §2).
    IMU readings are optional: the controllers shipped here do not need them, and the
    environment only has noisy ones when it builds an observation (see
    ``ProtoExplorerEnv.controller_input``).
    """

    t: float
    """Time since the start of the drive (s)."""
    estimate: SlipEstimate
    theta: Array
    """(5,) measured joint angles theta_1..theta_5 (rad)."""
    speed_command: float
    """Commanded forward speed of the middle segment (m/s)."""
    yaw_rate_command: float
    """Commanded yaw rate of the middle segment (rad/s), positive turning left."""
    imu_gyro: Array | None = None
    """(3, 3) angular rate of each segment in its own axes, seg1..seg3 x y z (rad/s)."""
    imu_gravity: Array | None = None
    """(3, 3) unit gravity direction in each segment's axes."""

    def __post_init__(self) -> None:
        theta = np.array(self.theta, dtype=np.float64).reshape(-1)
        if theta.shape != (5,):
            raise ValueError(f"theta must have 5 joint angles, got shape {theta.shape}")
        object.__setattr__(self, "theta", theta)
        for name in ("imu_gyro", "imu_gravity"):
            v = getattr(self, name)
            if v is not None:
                a = np.array(v, dtype=np.float64)
                if a.shape != (3, 3):
                    raise ValueError(f"{name} must have shape (3, 3), got {a.shape}")
                object.__setattr__(self, name, a)
        for name in ("t", "speed_command", "yaw_rate_command"):
            v = float(getattr(self, name))
            if not math.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v!r}")
            object.__setattr__(self, name, v)
        if np.shape(self.estimate.slip_ratio) != (4,):
            raise ValueError("estimate must be one sample (slip_ratio of shape (4,))")

    @property
    def slip_ratio(self) -> Array:
        """(4,) estimated slip of 1L 1R 2L 2R (< 0 spinning, > 0 skidding)."""
        return np.asarray(self.estimate.slip_ratio, dtype=np.float64)

    @property
    def flags(self) -> npt.NDArray[np.int64]:
        """(4,) estimator FLAG_* bits per driven wheel; 0 is reliable."""
        return np.asarray(self.estimate.flags, dtype=np.int64)


class Controller(abc.ABC):
    """Maps a :class:`ControllerInput` to speed targets (rad/s) of 1L 1R 2L 2R.

    Controllers keep their own state (integrators, previous targets) and are called once
    per control period, in time order; :meth:`reset` starts a new drive.
    """

    name: str = "controller"

    @abc.abstractmethod
    def reset(self) -> None:
        """Forget everything learnt in the previous drive."""

    @abc.abstractmethod
    def act(self, obs: ControllerInput) -> Array:
        """Speed targets (4,) in rad/s for 1L 1R 2L 2R."""


@dataclass(frozen=True)
class CommandSchedule:
    """A piecewise-constant task command: from ``times[i]`` on, (speeds[i], yaw_rates[i]).

    Before the first time the command is zero (the rover stands still).
    """

    times: tuple[float, ...]
    speeds: tuple[float, ...]
    yaw_rates: tuple[float, ...]

    def __post_init__(self) -> None:
        n = len(self.times)
        if n == 0 or len(self.speeds) != n or len(self.yaw_rates) != n:
            raise ConfigError("command schedule: times, speeds and yaw_rates need equal, >0 length")
        vals = (*self.times, *self.speeds, *self.yaw_rates)
        if not all(math.isfinite(v) for v in vals):
            raise ConfigError("command schedule: values must be finite")
        if any(b <= a for a, b in zip(self.times, self.times[1:], strict=False)):
            raise ConfigError("command schedule: times must increase strictly")

    @classmethod
    def from_rows(cls, rows: Sequence[Sequence[float]]) -> CommandSchedule:
        """From ``[[t, speed, yaw_rate], ...]`` rows (the scenario YAML form)."""
        for i, r in enumerate(rows):
            if len(r) != 3:
                raise ConfigError(f"command schedule row {i}: need [t, speed, yaw_rate], got {r!r}")
        return cls(
            tuple(float(r[0]) for r in rows),
            tuple(float(r[1]) for r in rows),
            tuple(float(r[2]) for r in rows),
        )

    def at(self, t: float) -> tuple[float, float]:
        """(speed m/s, yaw rate rad/s) commanded at time ``t``."""
        i = int(np.searchsorted(np.asarray(self.times), t + 1e-9, side="right")) - 1
        if i < 0:
            return 0.0, 0.0
        return self.speeds[i], self.yaw_rates[i]

    def path_length(self, duration: float) -> float:
        """Commanded travel, |speed| integrated over [0, duration] (m)."""
        edges = (*self.times, math.inf)
        total = 0.0
        for i, v in enumerate(self.speeds):
            lo, hi = max(edges[i], 0.0), min(edges[i + 1], duration)
            if hi > lo:
                total += abs(v) * (hi - lo)
        return total
