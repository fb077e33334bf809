"""The evaluator every fit replays through: window sets under extension sets, with a cache,
a cost account and the joint sensors' zeros profiled out (:attr:`Evaluator.profile_zeros`)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from rover_env.calibration.candidates import Extensions, merge
from rover_env.calibration.replay import PreparedLog, Replayer, ReplaySettings, Window, WindowResult
from rover_env.calibration.residuals import residual_vector
from rover_env.config import RoverConfig

Array = NDArray[np.float64]


@dataclass
class Evaluator:
    """Replays window sets under extension sets, with a cache and a cost account."""

    base: RoverConfig
    settings: ReplaySettings
    logs: list[PreparedLog]
    sets: dict[str, list[Window]]
    scale: dict[str, float] = field(default_factory=dict)
    log: Callable[[str], None] = print
    cache: dict[tuple[str, str], list[WindowResult]] = field(default_factory=dict)
    replays: int = 0
    seconds: float = 0.0
    profile_zeros: bool = False
    """Profile the joint sensors' zeros out of every replay (:meth:`zero_shift`): each
    joint's residual less its mean over the training windows replayed under the same
    extensions, so every fit carries its own zeros.

    Why (stop 54): zeros fitted once, before any effect, take whatever constant the first
    model leaves on a joint. An 8 deg slope bends the leaf springs by a steady amount on
    average, and a zero adopted before the slope was fitted took it: beside a 0.4 s lag
    the slope then came out at 5.7 deg instead of 7.6 and was not named. Profiled, a zero
    takes only what no effect explains: its constant against the effect's variation with
    heading and load."""

    def config(self, ext: Extensions) -> RoverConfig:
        from dataclasses import replace

        return replace(self.base, extensions=merge(self.base.extensions, ext))

    def _replay(self, ext: Extensions, which: str) -> list[WindowResult]:
        key = (json.dumps(ext, sort_keys=True), which)
        if key not in self.cache:
            t0 = time.perf_counter()
            rp = Replayer(self.config(ext), self.settings, backend="auto")
            self.cache[key] = rp.run(self.logs, self.sets[which])
            self.replays += 1
            self.seconds += time.perf_counter() - t0
        return self.cache[key]

    def zero_shift(self, ext: Extensions, which: str = "held") -> Array:
        """(5,) what profiling takes off each joint's residual (rad): the mean over the
        training windows under ``ext``; on a training set its own windows, elsewhere the
        full training set's (the subset's where only it was replayed: a numpy-only model's
        full training replay would cost 20 x)."""
        key = json.dumps(ext, sort_keys=True)
        if which.startswith("train"):
            ref = which
        else:
            ref = (
                "train_sub"
                if (key, "train_sub") in self.cache
                and (
                    key,
                    "train",
                )
                not in self.cache
                else "train"
            )
        rows = np.vstack([r.resid[:, 6:11] for r in self._replay(ext, ref)])
        return np.asarray(rows.mean(axis=0), dtype=np.float64)

    def run(self, ext: Extensions, which: str) -> list[WindowResult]:
        raw = self._replay(ext, which)
        if not self.profile_zeros:
            return raw
        key = (json.dumps(ext, sort_keys=True), which + " (zeros profiled)")
        if key not in self.cache:
            shift = self.zero_shift(ext, which)
            self.cache[key] = [less_joint_shift(r, shift) for r in raw]
        return self.cache[key]

    def vector(self, ext: Extensions, which: str) -> Array:
        return residual_vector(self.run(ext, which), self.scale)


def less_joint_shift(r: WindowResult, shift: Array) -> WindowResult:
    """``r`` with ``shift`` taken off its joints' residuals and simulated angles: the
    sensors reading ``shift`` less at every angle."""
    from dataclasses import replace

    resid, sim = r.resid.copy(), r.sim.copy()
    resid[:, 6:11] -= shift
    sim[:, 6:11] -= shift
    return replace(r, resid=resid, sim=sim)
