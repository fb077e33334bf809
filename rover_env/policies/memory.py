"""Memory a stateless policy can be given from its own observations: the stall clock.

A stalled rover and one crawling over a ripple's face look alike in one observation (estimated
speed near 0, the driven wheels slipping); only how long it has lasted tells them apart. The
shipped agents see one observation, and on soft-patch they push on through every stall
(issue 18, stops 27-36) where the slip PI eases off after a few seconds. The stall clock is
that duration: seconds since the estimated forward speed of the middle segment (observation
``speed_estimate``) was last at or above ``speed`` m/s, capped at ``cap`` s. It is computed
from what the rover senses (the estimator's speed and the control clock), so it is no
privileged information; it is what a rover's fault protection counts.

Used by the scenario-mix training env (``env_kwargs.stall_clock``, one observation appended)
and by the ``ppo:`` controller, which reads the same key from the run's config.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from rover_env.envs.proto_explorer import OBS_NAMES

__all__ = ["StallClock", "stall_clock_from"]

Obs = npt.NDArray[np.float32]

_I_SPEED = OBS_NAMES.index("speed_estimate")


class StallClock:
    """Seconds since the estimated speed was last >= ``speed`` (m/s), capped at ``cap`` (s)."""

    def __init__(self, speed: float = 0.02, cap: float = 10.0) -> None:
        if not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"stall_clock.speed must be > 0 m/s, got {speed!r}")
        if not (math.isfinite(cap) and cap > 0):
            raise ValueError(f"stall_clock.cap must be > 0 s, got {cap!r}")
        self.speed = float(speed)
        self.cap = float(cap)
        self.t = 0.0

    def reset(self) -> None:
        """A new episode: the clock at 0."""
        self.t = 0.0

    def update(self, obs: npt.ArrayLike, dt: float) -> float:
        """Advance by one control step of ``dt`` s whose observation is ``obs``; the clock."""
        v = float(np.asarray(obs, dtype=np.float64).reshape(-1)[_I_SPEED])
        self.t = 0.0 if abs(v) >= self.speed else min(self.t + dt, self.cap)
        return self.t

    def extend(self, obs: npt.ArrayLike, dt: float) -> Obs:
        """``obs`` with the clock after this step appended (47 values)."""
        o = np.asarray(obs, dtype=np.float32).reshape(-1)
        return np.append(o, np.float32(self.update(o, dt))).astype(np.float32)


def stall_clock_from(spec: Any, where: str = "stall_clock") -> StallClock | None:
    """A :class:`StallClock` from a config value: None/false (no clock), true (defaults) or
    ``{speed: m/s, cap: s}``; anything else is one error naming ``where``."""
    if spec is None or spec is False:
        return None
    if spec is True:
        return StallClock()
    if isinstance(spec, Mapping):
        unknown = set(spec) - {"speed", "cap"}
        if unknown:
            raise ValueError(f"{where}: unknown key(s) {sorted(unknown)}; use speed, cap")
        try:
            return StallClock(float(spec.get("speed", 0.02)), float(spec.get("cap", 10.0)))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}: {exc}") from None
    raise ValueError(f"{where}: expected true, false or {{speed, cap}}, got {spec!r}")
