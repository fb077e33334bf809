"""An evidence candidate judged beside the named effects (``evidence_stage.beside_named``,
stop 129), on this project's own logs: refitted with the named effects held, a candidate
that is there is found at its truth and pays for itself; one that is not adds nothing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis import floor, form, split
from rover_env.calibration.diagnosis.evidence_stage import beside_named
from rover_env.calibration.diagnosis.state import Diagnosis, Options, Scored
from rover_env.calibration.fit import Fit
from rover_env.generators.make_logs import make_logs

RR = {"rolling_resistance": {"c_rr": 0.05}}
CUT = {"torque_limit": {"fraction": -0.6}}


def _through_floor(root: Path, effects: dict) -> Diagnosis:
    paths = make_logs(root / "logs", effects, drives=2, seed=6, duration=24.0, progress=False)
    d = Diagnosis([str(p) for p in paths], root / "out", Options(progress=False, workers=1))
    split.split(d)
    form.fit_model_form(d)
    floor.baseline(d)
    return d


def _scored(d: Diagnosis, ext: dict, x: float) -> Scored:
    """A single fit of ``ext``'s effect at ``x`` (its interval 0.05 either side)."""
    (c,) = catalogue([next(iter(ext))])
    v = np.array([x])
    f = Fit([c], v, v - 0.05, v + 0.05, np.full(1, 0.02), 1.0, 3, c.to_ext(v), 0.0, "train")
    return Scored(f, 0.0, np.zeros(1), 0.3, 0.05, -12.0, -12.0, len(d.train_w))


@pytest.fixture(scope="module")
def both(tmp_path_factory: pytest.TempPathFactory) -> Diagnosis:
    """The model's own drives with rolling resistance 0.05 and a torque cut of 60 %."""
    return _through_floor(tmp_path_factory.mktemp("beside_both"), {**RR, **CUT})


@pytest.fixture(scope="module")
def rr_only(tmp_path_factory: pytest.TempPathFactory) -> Diagnosis:
    """The same drives with rolling resistance 0.05 only."""
    return _through_floor(tmp_path_factory.mktemp("beside_rr"), RR)


def test_a_candidate_that_is_there_is_refitted_to_its_truth_beside_the_named(
    both: Diagnosis,
) -> None:
    """The rolling resistance named at its truth, the cut (started at 50 %) refitted beside
    it: near its truth, the named effect held as named in the fit's model, and it pays for
    itself against the named model."""
    d = both
    d.chosen = [_scored(d, RR, 0.05)]
    b = beside_named(d, _scored(d, CUT, -0.5))
    assert b.fit.ext["rolling_resistance"] == RR["rolling_resistance"]
    assert b.fit.x[0] == pytest.approx(-0.6, abs=0.08)
    assert b.d_bic < -6.0


def test_a_candidate_that_is_not_there_adds_nothing_beside_the_named(rr_only: Diagnosis) -> None:
    """With the rolling resistance named at its truth, a cut has nothing left to explain:
    its refit beside it does not pay for itself (the evidence stage then asks nothing)."""
    d = rr_only
    d.chosen = [_scored(d, RR, 0.05)]
    b = beside_named(d, _scored(d, CUT, -0.5))
    assert b.d_bic > -2.0
