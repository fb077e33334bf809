"""The reward weights of a task (the env computes the terms; see ``ProtoExplorerEnv``)."""

from __future__ import annotations

import dataclasses
import math

__all__ = ["RewardWeights"]


@dataclasses.dataclass(frozen=True)
class RewardWeights:
    """reward = tracking * (exp(-(e_v/sigma_v)^2) + exp(-(e_w/sigma_w)^2)) / 2
    + yaw_tracking * exp(-(e_w/sigma_w)^2) + progress * p
    - slip * g(mean |S|) - energy * electrical power [W] - sinkage * mean sinkage [mm]
    - stall_energy * P * clip(1 - p / |v_cmd|, 0, 1),
    with g(m) = m, or g(m) = slip_scale * ln(1 + m / slip_scale) when ``slip_scale`` > 0,
    and p the step's path speed (m/s), negative when the rover moves against the command.

    The defaults are the tracking reward of every env so far. ``progress``, ``yaw_tracking``
    and ``sinkage`` (default 0) give the *mobility* reward: go along the commanded direction,
    at the commanded yaw rate, at no imposed pace, paying energy, slip and sinkage. With
    progress weight P and energy weight E, a metre is worth P/E joules: the policy speeds up
    while a metre costs less than that. This is what the soil acceptance measures (success,
    energy per metre, sinkage, |S| at a yaw-rate error), and what a slip controller allowed
    to speed a wheel up does."""

    tracking: float = 1.0
    slip: float = 1.0
    energy: float = 0.02
    sigma_speed: float = 0.05
    sigma_yaw_rate: float = 0.1
    slip_scale: float = 0.0
    """0: the slip penalty is linear in mean |S|. > 0: linear below this slip, logarithmic
    above, so that a wheel spinning at S = -1 (a stuck rover) does not outweigh by a factor of
    hundreds the few 1e-3 of slip that separate controllers on ordinary ground; training
    signals from both then have comparable size."""
    progress: float = 0.0
    """Per m/s of path speed along the commanded direction (0: the pace is the command's)."""
    yaw_tracking: float = 0.0
    """Weight of the yaw-rate term alone (with ``tracking`` 0: turn as told, at any pace)."""
    sinkage: float = 0.0
    """Per mm of the six wheels' mean sinkage into loose soil (0 on hard ground)."""
    stall_energy: float = 0.0
    """Per W of the electrical power not turned into progress: P * (1 - p / |v_cmd|) clipped
    to [0, 1] (p the path speed along the command; no charge when the command has no speed).
    Why: the benchmark divides energy by distance, so a wheel kept spinning in a stall costs
    it far more than the second-by-second ``energy`` term charges (issue 18, soft-patch)."""

    def slip_penalty(self, mean_abs_slip: float) -> float:
        """g(mean |S|) (see the class docstring), before the weight."""
        if self.slip_scale > 0:
            return self.slip_scale * math.log1p(mean_abs_slip / self.slip_scale)
        return mean_abs_slip

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"reward weight {f.name} must be finite and >= 0, got {v!r}")
        if self.sigma_speed <= 0 or self.sigma_yaw_rate <= 0:
            raise ValueError("reward sigmas must be > 0")
