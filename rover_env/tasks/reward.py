"""The reward weights of a task (the env computes the terms; see ``ProtoExplorerEnv``)."""

from __future__ import annotations

import dataclasses
import math

__all__ = ["RewardWeights"]


@dataclasses.dataclass(frozen=True)
class RewardWeights:
    """reward = tracking * (exp(-(e_v/sigma_v)^2) + exp(-(e_w/sigma_w)^2)) / 2
    - slip * g(mean |S|) - energy * electrical power [W], with g(m) = m, or
    g(m) = slip_scale * ln(1 + m / slip_scale) when ``slip_scale`` > 0."""

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
