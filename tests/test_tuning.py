"""The slip-PI tuner judges gains with the benchmark's own episode loop (issue 17)."""

from __future__ import annotations

import dataclasses

import pytest

from rover_env.benchmark.run import Job, run_jobs
from rover_env.benchmark.scenarios import load_scenario
from rover_env.benchmark.tuning import evaluate, objective, tune
from rover_env.control.slip_pi import load_slip_pi_config
from rover_env.seeds import SPLITS

SEED = SPLITS["tuning"].start


def test_tuner_metrics_are_the_benchmarks() -> None:
    ep = load_scenario("ice-patch").episode(SEED, duration=1.5)
    gains = dataclasses.replace(load_slip_pi_config(), kp=0.2, ki=1.5)
    (tuned,) = evaluate(gains, [ep])
    (bench,) = run_jobs([Job("slip-pi@kp=0.2@ki=1.5", "ice-patch", SEED, 1.5)])
    assert tuned == {k: bench[k] for k in tuned}
    (ol,) = evaluate(None, [ep])
    (bench_ol,) = run_jobs([Job("open-loop", "ice-patch", SEED, 1.5)])
    assert ol == {k: bench_ol[k] for k in ol}
    with pytest.raises(ValueError, match="test seed"):
        evaluate(gains, [load_scenario("ice-patch").episode(SPLITS["test"].start, 1.0)])


def test_tune_grid_picks_the_best_point_seen() -> None:
    cases = [load_scenario("split-mu").episode(SEED, duration=1.0)]
    res = tune(cases, grid=((0.0,), (0.5, 2.0)), refine_evals=0, log=None)
    assert len(res.evaluations) == 2
    best = min(res.evaluations, key=lambda e: e["score"])
    assert (res.kp, res.ki, res.score) == (best["kp"], best["ki"], best["score"])
    ref = evaluate(None, cases)
    assert objective(ref, ref) == pytest.approx(1.0)  # open loop against itself
