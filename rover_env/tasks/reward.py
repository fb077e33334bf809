"""The reward of a control step: its weights (:class:`RewardWeights`), what a step did
(:class:`StepResult`) and one small function per term; the formula is written here only."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["REWARD_TERMS", "RewardWeights", "StepResult", "reward_terms"]


@dataclasses.dataclass(frozen=True)
class RewardWeights:
    """reward = tracking * (exp(-(e_v/sigma_v)^2) + exp(-(e_w/sigma_w)^2)) / 2
    + yaw_tracking * exp(-(e_w/sigma_w)^2) + speed_tracking * exp(-(e_v/sigma_v)^2) + progress * p
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
    speed_tracking: float = 0.0
    """Weight of the speed term alone. Why: ``tracking`` pays half its weight for the yaw
    rate, which a rover standing still meets on a straight command; where driving costs slip,
    energy and sinkage (a soft slope) stopping can then out-earn a slow climb. Paying the pace
    on its own makes the commanded pace the thing to reach (issue 46)."""
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


@dataclasses.dataclass(frozen=True)
class StepResult:
    """What one control step of one rover did, as the reward and termination read it."""

    tracking_error_speed: float
    """e_v: RMS over the step's samples of commanded minus true forward speed (m/s)."""
    tracking_error_yaw_rate: float
    """e_w: the same for the yaw rate (rad/s)."""
    mean_abs_slip: float
    """Mean |S| of the driven wheels the reward charges (true, or the estimate's)."""
    energy: float
    """Electrical energy of the motors over the step (J)."""
    distance: float
    """Path of the middle segment over the step (m)."""
    against: bool
    """Whether the rover ended the step moving against the commanded speed."""
    speed_command: float
    control_dt: float
    wheel_sinkage: NDArray[np.float64]
    """Sinkage of the six wheels into loose soil (m), 0 on hard ground."""
    flipped: bool
    out_of_arena: bool

    @property
    def terminated(self) -> bool:
        """The episode ends when the rover flips or leaves the arena."""
        return self.flipped or self.out_of_arena

    @property
    def signed_distance(self) -> float:
        """The benchmark's progress: a step moving against the command counts negative."""
        return -self.distance if self.against else self.distance


def tracking(w: RewardWeights, r: StepResult) -> float:
    """w_track * (k_v + k_w) / 2 + w_yaw * k_w + w_speed * k_v, k = exp(-(e / sigma)^2)."""
    k_w = math.exp(-((r.tracking_error_yaw_rate / w.sigma_yaw_rate) ** 2))
    k_v = math.exp(-((r.tracking_error_speed / w.sigma_speed) ** 2))
    out = w.tracking * 0.5 * (k_v + k_w)
    if w.yaw_tracking:
        out += w.yaw_tracking * k_w
    if w.speed_tracking:
        out += w.speed_tracking * k_v
    return out


def slip(w: RewardWeights, r: StepResult) -> float:
    """-w_slip * g(mean |S|) (:meth:`RewardWeights.slip_penalty`)."""
    return -w.slip * w.slip_penalty(r.mean_abs_slip)


def energy(w: RewardWeights, r: StepResult) -> float:
    """-w_energy * the motors' mean electrical power (W)."""
    return -w.energy * r.energy / r.control_dt


def progress(w: RewardWeights, r: StepResult) -> float:
    """w_progress * path speed along the command (m/s)."""
    return w.progress * r.signed_distance / r.control_dt


def stall_energy(w: RewardWeights, r: StepResult) -> float:
    """-w_stall * P * clip(1 - p / |v_cmd|, 0, 1): power not turned into progress."""
    v_cmd = abs(r.speed_command)
    p = r.signed_distance / r.control_dt
    idle = min(max(1.0 - p / v_cmd, 0.0), 1.0) if v_cmd > 1e-6 else 0.0
    return -w.stall_energy * idle * r.energy / r.control_dt


def sinkage(w: RewardWeights, r: StepResult) -> float:
    """-w_sink * the six wheels' mean sinkage (mm)."""
    return -w.sinkage * 1000.0 * float(np.mean(r.wheel_sinkage))


REWARD_TERMS = (
    ("reward_tracking", tracking, None),
    ("reward_slip", slip, None),
    ("reward_energy", energy, None),
    ("reward_progress", progress, "progress"),
    ("reward_stall_energy", stall_energy, "stall_energy"),
    ("reward_sinkage", sinkage, "sinkage"),
)
"""(info key, term, the weight that switches it on or None: always on), in summation order."""


def reward_terms(w: RewardWeights, r: StepResult) -> tuple[float, dict[str, float]]:
    """The step's reward and its terms by info key (the optional ones when weighted)."""
    terms: dict[str, float] = {}
    total = 0.0
    for key, term, switch in REWARD_TERMS:
        if switch is not None and not getattr(w, switch):
            continue
        value = term(w, r)
        total = value if not terms else total + value
        terms[key] = value
    return total, terms
