"""The rotor inertia fitted beside a named torque limit (``diagnosis.rotor``): on this
project's own logs with a torque cut the stand-in is a heavier rotor, and it does not fit
the training drives better than the truth; without a torque limit nothing is fitted. A
named limit's interval is profiled over the rotor inertia's tolerance."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis import floor, form, split
from rover_env.calibration.diagnosis.rotor import (
    FACTORS,
    profile_rotor,
    rotor_alternative,
    rotor_text,
)
from rover_env.calibration.diagnosis.state import Diagnosis, Options, Scored
from rover_env.calibration.fit import Fit
from rover_env.generators.make_logs import make_logs

CUT = {"torque_limit": {"fraction": -0.6}}


@pytest.fixture(scope="module")
def cut_case(tmp_path_factory: pytest.TempPathFactory) -> Diagnosis:
    """The model's own 2 drives of 24 s under a torque cut of 60 %, through the floor stage."""
    root = tmp_path_factory.mktemp("rotor")
    paths = make_logs(root / "logs", CUT, drives=2, seed=6, duration=24.0, progress=False)
    d = Diagnosis([str(p) for p in paths], root / "out", Options(progress=False, workers=1))
    split.split(d)
    form.fit_model_form(d)
    floor.baseline(d)
    return d


def named(d: Diagnosis, ext: dict) -> Scored:
    (c,) = catalogue([next(iter(ext))])
    z = np.zeros(1)
    f = Fit([c], z - 0.6, z - 0.7, z - 0.5, z, 1.0, 3, ext, 0.0, "train")
    return Scored(f, 0.0, z, 0.5, 1e-4, -10.0, -10.0, len(d.train_w), significant=True)


def test_a_torque_cut_is_mimicked_by_a_heavier_rotor_not_better(cut_case: Diagnosis) -> None:
    d = cut_case
    d.chosen = [named(d, CUT)]
    alt = rotor_alternative(d)
    assert alt is not None
    a0 = d.base.motor.armature
    assert alt["armature"] in [a0 * f for f in FACTORS]
    assert alt["armature"] > a0  # slower accelerations: a heavier rotor
    tq, rotor = alt["torque_limit"], alt["rotor"]
    assert tq["d_bic"] < 0 and tq["train_gain"] > 0.5  # the truth explains the drives
    assert tq["train_gain"] >= rotor["train_gain"]  # and the stand-in not better
    assert "motor.armature" in rotor_text(alt)


def test_nothing_fitted_without_a_torque_limit(cut_case: Diagnosis) -> None:
    d = cut_case
    d.chosen = [named(d, {"rolling_resistance": {"c_rr": 0.05}})]
    assert rotor_alternative(d) is None


def test_a_named_limit_s_interval_holds_its_refits_over_the_rotor_tolerance(
    cut_case: Diagnosis,
) -> None:
    """profile_rotor (stop 59): refits at half and twice the rotor inertia, the heavier
    rotor needing the smaller cut (its wheels already accelerate slower), and an interval
    that holds all three; once per fit, only for a torque limit, off at range 1."""
    d = cut_case
    d.rotor_profile = {}
    s = named(d, CUT)
    x0 = s.fit.x.copy()
    prof = profile_rotor(d, s)
    assert prof is not None and d.rotor_profile["torque_limit"] is prof
    light, heavy = prof["refits"]
    a0 = d.base.motor.armature
    assert light["armature"] == pytest.approx(a0 / 2) and heavy["armature"] == pytest.approx(2 * a0)
    assert light["x"][0] < heavy["x"][0] < 0.0  # a heavier rotor: a smaller cut
    assert s.fit.x == pytest.approx(x0)  # the value stays the configured rotor's
    for r in (light, heavy):
        assert s.fit.ci_lo[0] <= r["lo"][0] and r["hi"][0] <= s.fit.ci_hi[0]
    assert s.fit.ci_lo[0] <= -0.7 and s.fit.ci_hi[0] >= -0.5
    assert profile_rotor(d, s) is None  # profiled already
    assert profile_rotor(d, named(d, {"rolling_resistance": {"c_rr": 0.05}})) is None
    d.rotor_profile = {}
    d.opts = replace(d.opts, rotor_range=1.0)
    assert profile_rotor(d, named(d, CUT)) is None
