"""Drive plans: speed-target schedules of the four driven wheels, seeded.

A plan is a chain of manoeuvres, each a (duration, left, right, ramp) tuple: the targets move to
``left`` (1L, 2L) and ``right`` (1R, 2R) over ``ramp`` seconds (0: a step) and hold. Every plan
starts with one second at rest. The kinds rotate with the drive index so a case of three drives
has three different characters; the numbers in each are drawn from the seed.
Wheel speeds are in rad/s (1 rad/s is about 8 cm/s on this rover); the motors reach about
6 rad/s unloaded, plans stay within +-3.5 rad/s.

A drive can also follow a given plan (``make_independent_logs(..., plan=...)``): a list of
manoeuvres as above, or a :class:`Schedule`, rows of the four targets each held from its time
until the next, as ``rover-env drive-plan`` writes them (``t,cmd_1L,cmd_1R,cmd_2L,cmd_2R``,
read by :meth:`Schedule.from_csv`). Both are plain numbers: turning another tool's plan into
them is that tool's business.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
Manoeuvre = tuple[float, float, float, float]

KINDS = ("steps", "turns", "stop_go", "reversals", "pivots", "hard", "weave")


def _manoeuvre(kind: str, rng: np.random.Generator, last: tuple[float, float]) -> Manoeuvre:
    dur = float(rng.uniform(2.5, 7.0))
    v = float(rng.uniform(0.8, 3.2))
    ramp = float(rng.choice([0.0, 0.0, rng.uniform(0.3, 2.0)]))
    if kind == "steps":
        return dur, v, v, 0.0
    if kind == "turns":
        dv = float(rng.uniform(0.3, 1.4)) * float(rng.choice([-1.0, 1.0]))
        return dur, v - dv / 2, v + dv / 2, ramp
    if kind == "stop_go":
        if abs(last[0]) + abs(last[1]) > 0 and rng.random() < 0.5:
            return float(rng.uniform(1.0, 3.0)), 0.0, 0.0, float(rng.choice([0.0, 0.5]))
        return dur, v, v * float(rng.uniform(0.8, 1.2)), ramp
    if kind == "reversals":
        sgn = -1.0 if last[0] + last[1] > 0 else 1.0
        return dur, sgn * v, sgn * v, ramp
    if kind == "pivots":
        w = float(rng.uniform(0.8, 2.0)) * float(rng.choice([-1.0, 1.0]))
        if rng.random() < 0.4:
            return dur, v, v, ramp
        return dur, -w, w, ramp
    if kind == "hard":
        if abs(last[0]) > 0.1:
            return float(rng.uniform(1.0, 3.0)), 0.0, 0.0, 0.0
        vv = float(rng.uniform(2.5, 3.5)) * float(rng.choice([-1.0, 1.0, 1.0]))
        return dur, vv, vv, 0.0
    # weave: left/right alternate around a mean, as the paper's weaving path
    dv = float(rng.uniform(0.4, 1.2))
    sgn = 1.0 if last[1] <= last[0] else -1.0
    return float(rng.uniform(2.0, 4.0)), v - sgn * dv / 2, v + sgn * dv / 2, 0.5


def plan(kind: str, duration: float, seed: int) -> list[Manoeuvre]:
    """Manoeuvres of one drive, covering ``duration`` seconds after the initial second at rest."""
    if kind not in KINDS:
        raise ValueError(f"unknown plan kind {kind!r}; known: {', '.join(KINDS)}")
    rng = np.random.default_rng([47, 2, seed, KINDS.index(kind)])
    out: list[Manoeuvre] = [(1.0, 0.0, 0.0, 0.0)]
    total, last = 1.0, (0.0, 0.0)
    while total < duration:
        m = _manoeuvre(kind, rng, last)
        out.append(m)
        total += m[0]
        last = (m[1], m[2])
    return out


def targets(manoeuvres: list[Manoeuvre], t: Array) -> Array:
    """(N, 4) targets 1L 1R 2L 2R at times ``t``."""
    left = np.zeros_like(t)
    right = np.zeros_like(t)
    t0, lp, rp = 0.0, 0.0, 0.0
    for dur, lv, rv, ramp in manoeuvres:
        sel = (t >= t0) & (t < t0 + dur)
        frac = np.clip((t[sel] - t0) / ramp, 0.0, 1.0) if ramp > 0 else np.ones(int(sel.sum()))
        left[sel] = lp + (lv - lp) * frac
        right[sel] = rp + (rv - rp) * frac
        t0, lp, rp = t0 + dur, lv, rv
    left[t >= t0] = lp
    right[t >= t0] = rp
    return np.column_stack([left, right, left, right])


def drive_kind(index: int, seed: int) -> str:
    return KINDS[(index + 3 * seed) % len(KINDS)]


@dataclass(frozen=True)
class Schedule:
    """Targets 1L 1R 2L 2R (rad/s) from ``t[k]`` until ``t[k + 1]`` (zero-order hold); the
    drive lasts until the last row's time, whose targets hold at that instant."""

    t: Array  # (M,) increasing, t[0] = 0
    cmd: Array  # (M, 4)

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=np.float64)
        cmd = np.asarray(self.cmd, dtype=np.float64)
        if t.ndim != 1 or t.size < 2 or cmd.shape != (t.size, 4):
            raise ValueError(
                f"schedule: need (M,) times and (M, 4) targets, got {t.shape}, {cmd.shape}"
            )
        if t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
            raise ValueError("schedule: times must start at 0 and increase")
        if not np.all(np.isfinite(cmd)):
            raise ValueError("schedule: targets must be finite")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "cmd", cmd)

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def at(self, t: Array) -> Array:
        """(N, 4) targets at times ``t`` (the row in force at each)."""
        k = np.searchsorted(self.t, np.asarray(t) + 1e-9, side="right") - 1
        return self.cmd[np.clip(k, 0, self.t.size - 1)]

    @classmethod
    def from_csv(cls, path: str | Path) -> Schedule:
        """A ``t,cmd_1L,cmd_1R,cmd_2L,cmd_2R`` CSV (a header row, then numbers)."""
        with Path(path).open(newline="") as fh:
            rows = list(csv.reader(fh))
        if not rows or [c.strip() for c in rows[0]] != list(CSV_HEADER):
            raise ValueError(f"{path}: header must be {','.join(CSV_HEADER)}")
        try:
            a = np.array([[float(x) for x in r] for r in rows[1:] if r], dtype=np.float64)
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None
        if a.ndim != 2 or a.shape[1] != 5:
            raise ValueError(f"{path}: every row needs 5 numbers")
        return cls(a[:, 0], a[:, 1:])


CSV_HEADER = ("t", "cmd_1L", "cmd_1R", "cmd_2L", "cmd_2R")
