"""Reproducible gain tuning of :class:`SlipPI`, judged by the benchmark's own episode loop.

Procedure (``tune``):

1. Run :class:`OpenLoop` once on every tuning case (scenarios where slip is wasted, tuning
   seeds only) for its reference mean |S|, RMS speed error and distance made good.
2. Score a gain pair (Kp, Ki) by running :class:`SlipPI` on the same cases::

       J = mean over cases of [ |S|_PI / |S|_OL
                                + speed_weight * max(0, e_v,PI - e_v,OL) / 0.05 m/s
                                + distance_weight * max(0, d_OL - d_PI) / d_OL ]

   The slip term is relative so that every scenario counts alike (a stuck rover's |S| is 50
   times a fighting axle's); the penalties charge lost speed tracking (in units of the
   env's reward width sigma_speed) and lost distance made good, never gains.
3. Evaluate a coarse grid, then refine from its best point by Nelder–Mead (bounded,
   deterministic: same cases, same seeds, same noise), and return the best point seen.

The search stays inside a stability box (:func:`stability_bounds`). Where a wheel still
rolls, its slip answers a relative speed change one for one, so each wheel's loop is a unit
plant behind the estimator's lag (half its least-squares window, 0.25 s) plus a control
period. A pure integrator keeps 45 deg of phase margin up to Ki = (pi/4) / lag and a
proportional gain keeps a gain margin of 2 up to Kp = 0.5. The objective alone would push Ki
beyond that (a stuck wheel, whose slip does not answer at all, only stops sooner): a first
unbounded run chose Ki = 8 /s, and its wheel targets chattered in a limit cycle held only by
the deadband.

Every case is a benchmark :class:`~rover_env.tasks.scenarios.Episode` (tuning seeds) run
through the environment by :func:`rover_env.benchmark.run.run_episode`, the loop and metrics
(:mod:`rover_env.benchmark.metrics`) the benchmark judges the tuned gains with: a gain pair's
metrics equal the benchmark's for ``slip-pi@kp=..@ki=..`` on the same episodes. (Until issue
17 the tuner ran its own loop on the bare simulator, ``rover_env.control.runner.run_on_sim``;
the shipped gains were tuned that way.) Everything is seeded by the cases, so the same call
gives the same gains. The command line form is ``rover-env tune-slip-pi``
(:mod:`rover_env.benchmark.cli`).
"""

from __future__ import annotations

import dataclasses
import math
import multiprocessing as mp
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from rover_env.benchmark.run import run_episode, wrapper_for
from rover_env.config import to_dict
from rover_env.control.open_loop import OpenLoop
from rover_env.control.slip_pi import SlipPI, SlipPIConfig
from rover_env.estimation.estimator import EstimatorConfig
from rover_env.executor import die_with_parent
from rover_env.policies.controllers import ClassicalController
from rover_env.seeds import refuse_final_only
from rover_env.tasks.scenarios import Episode

__all__ = ["TuningResult", "evaluate", "objective", "stability_bounds", "tune", "write_config"]

SPEED_SIGMA = 0.05
"""m/s: the env's reward width for speed error, the unit of the speed penalty."""

DEFAULT_GRID: tuple[tuple[float, ...], tuple[float, ...]] = (
    (0.0, 0.2, 0.5),
    (0.5, 1.2, 2.2),
)
"""Kp values x Ki values (1/s) of the coarse grid (inside :func:`stability_bounds`)."""


def stability_bounds(
    control_dt: float = 0.1, estimator: EstimatorConfig | None = None
) -> tuple[tuple[float, float], tuple[float, float]]:
    """((0, Kp_max), (0, Ki_max)): the search box of the module docstring."""
    est = estimator or EstimatorConfig()
    lag = est.rate_window / 2 + control_dt
    return (0.0, 0.5), (0.0, (math.pi / 4) / lag)


@dataclass
class TuningResult:
    kp: float
    ki: float
    score: float
    evaluations: list[dict[str, float]] = field(default_factory=list)
    """Every (kp, ki, score) tried, in order."""
    reference: list[dict[str, float]] = field(default_factory=list)
    """Open-loop metrics per case."""
    wall_s: float = 0.0


# --------------------------------------------------------------------------- episodes


def _controller(gains: SlipPIConfig | None) -> ClassicalController:
    if gains is None:
        return ClassicalController("open-loop", lambda cfg, dt: OpenLoop(cfg))
    return ClassicalController("slip-pi", lambda cfg, dt: SlipPI(cfg, gains, dt=dt))


def _run_case(args: tuple[SlipPIConfig | None, Episode]) -> dict[str, float]:
    gains, episode = args
    ctrl = _controller(gains)
    return run_episode(wrapper_for(episode.scenario, ctrl.action_layout, episode), ctrl, episode)


def evaluate(
    gains: SlipPIConfig | None,
    cases: Sequence[Episode],
    pool: ProcessPoolExecutor | None = None,
) -> list[dict[str, float]]:
    """Metrics of every case with SlipPI(gains), or OpenLoop when ``gains`` is None."""
    for c in cases:
        refuse_final_only([c.seed], f"tuning case {c.scenario} seed {c.seed}")
    jobs = [(gains, c) for c in cases]
    if pool is None:
        return [_run_case(j) for j in jobs]
    return list(pool.map(_run_case, jobs))


def objective(
    pi: Sequence[dict[str, float]],
    ol: Sequence[dict[str, float]],
    speed_weight: float = 1.0,
    distance_weight: float = 5.0,
) -> float:
    """J of the module docstring (lower is better)."""
    terms = []
    for p, o in zip(pi, ol, strict=True):
        slip = p["mean_abs_slip"] / max(o["mean_abs_slip"], 1e-6)
        speed = max(0.0, p["rms_speed_error"] - o["rms_speed_error"]) / SPEED_SIGMA
        dist = max(0.0, o["distance_made_good"] - p["distance_made_good"]) / max(
            o["distance_made_good"], 0.1
        )
        terms.append(slip + speed_weight * speed + distance_weight * dist)
    return float(np.mean(terms))


# --------------------------------------------------------------------------- search


def tune(
    cases: Sequence[Episode],
    base: SlipPIConfig | None = None,
    grid: tuple[Sequence[float], Sequence[float]] = DEFAULT_GRID,
    refine_evals: int = 8,
    workers: int = 1,
    log: Callable[[str], None] | None = print,
) -> TuningResult:
    """Grid then Nelder–Mead over (Kp, Ki); other fields of ``base`` stay as they are."""
    from scipy.optimize import minimize

    base = base or SlipPIConfig()
    t0 = time.perf_counter()
    say = log or (lambda _m: None)
    pool = (
        ProcessPoolExecutor(
            max_workers=workers,
            mp_context=mp.get_context("spawn"),
            initializer=die_with_parent,
            initargs=(os.getpid(),),
        )
        if workers > 1
        else None
    )
    try:
        ref = evaluate(None, cases, pool)
        say(f"open loop on {len(cases)} cases: " + _brief(ref))
        seen: dict[tuple[float, float], float] = {}
        evals: list[dict[str, float]] = []

        def score(kp: float, ki: float) -> float:
            key = (round(max(kp, 0.0), 4), round(max(ki, 0.0), 4))
            if key not in seen:
                gains = dataclasses.replace(base, kp=key[0], ki=key[1])
                res = evaluate(gains, cases, pool)
                seen[key] = objective(res, ref)
                evals.append({"kp": key[0], "ki": key[1], "score": seen[key]})
                say(f"kp={key[0]:.4f} ki={key[1]:.4f}  J={seen[key]:.4f}  " + _brief(res))
            return seen[key]

        for kp in grid[0]:
            for ki in grid[1]:
                score(kp, ki)
        (kp0, ki0), _ = min(seen.items(), key=lambda kv: kv[1])
        if refine_evals > 0:
            (_, kp_max), (_, ki_max) = stability_bounds()
            # Step 10 % of the box from the grid's best point, inwards at an upper edge.
            dk = 0.1 * kp_max if kp0 + 0.1 * kp_max <= kp_max else -0.1 * kp_max
            di = 0.1 * ki_max if ki0 + 0.1 * ki_max <= ki_max else -0.1 * ki_max
            simplex = np.array([[kp0, ki0], [kp0 + dk, ki0], [kp0, ki0 + di]])
            minimize(
                lambda x: score(float(x[0]), float(x[1])),
                np.array([kp0, ki0]),
                method="Nelder-Mead",
                bounds=[(0.0, kp_max), (0.0, ki_max)],
                options={
                    "maxfev": refine_evals,
                    "initial_simplex": simplex,
                    "xatol": 0.01,
                    "fatol": 1e-3,
                },
            )
        (kp, ki), best = min(seen.items(), key=lambda kv: kv[1])
    finally:
        if pool is not None:
            pool.shutdown()
    return TuningResult(kp, ki, best, evals, list(ref), time.perf_counter() - t0)


def _brief(rows: Sequence[dict[str, float]]) -> str:
    s = np.mean([r["mean_abs_slip"] for r in rows])
    e = np.mean([r["energy_per_metre"] for r in rows])
    d = np.mean([r["distance_made_good"] for r in rows])
    return f"mean|S|={s:.4f} E/m={e:.2f} J/m dist={d:.3f} m"


def write_config(path: str | Path, cfg: SlipPIConfig, header: str) -> Path:
    """Write ``cfg`` as YAML with ``header`` as a leading comment block."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    data: dict[str, Any] = to_dict(cfg)
    for k, v in data.items():
        if isinstance(v, float) and math.isfinite(v):
            data[k] = round(v, 4)
    comment = "".join(f"# {line}\n".replace("# \n", "#\n") for line in header.splitlines())
    p.write_text(comment + yaml.safe_dump(data, sort_keys=False))
    return p
