"""The rotor inertia fitted beside a named torque limit (``diagnosis.rotor``): on this
project's own logs with a torque cut the stand-in is a heavier rotor, and it does not fit
the training drives better than the truth, and the limit stands the rotor test; on logs of
a rover whose rotor is twice the configured one and no cut, the cut that mimics it does not
(stop 62); without a torque limit nothing is fitted. A named limit's interval is profiled
over the rotor inertia's tolerance."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis import floor, form, split
from rover_env.calibration.diagnosis.rotor import (
    FACTORS,
    profile_rotor,
    rotor_alternative,
    rotor_test,
    rotor_text,
    with_armature,
)
from rover_env.calibration.diagnosis.select import rotor_check
from rover_env.calibration.diagnosis.state import Diagnosis, Options, Scored
from rover_env.calibration.fit import Fit
from rover_env.config import load_rover
from rover_env.generators.make_logs import make_logs

CUT = {"torque_limit": {"fraction": -0.6}}


def _through_floor(root: Path, paths: list[Path]) -> Diagnosis:
    d = Diagnosis([str(p) for p in paths], root / "out", Options(progress=False, workers=1))
    split.split(d)
    form.fit_model_form(d)
    floor.baseline(d)
    return d


@pytest.fixture(scope="module")
def cut_case(tmp_path_factory: pytest.TempPathFactory) -> Diagnosis:
    """The model's own 2 drives of 24 s under a torque cut of 60 %, through the floor stage."""
    root = tmp_path_factory.mktemp("rotor")
    paths = make_logs(root / "logs", CUT, drives=2, seed=6, duration=24.0, progress=False)
    return _through_floor(root, paths)


@pytest.fixture(scope="module")
def heavy_rotor_case(tmp_path_factory: pytest.TempPathFactory) -> Diagnosis:
    """The same drives of a rover whose reflected rotor is twice the configured one, no
    cut (the independent generator's build against this configuration), through the floor."""
    root = tmp_path_factory.mktemp("heavy_rotor")
    nominal = load_rover("proto_explorer")
    heavy = with_armature(nominal, 2.0 * nominal.motor.armature)
    paths = make_logs(
        root / "logs", {}, drives=2, seed=6, duration=24.0, progress=False, truth_rover=heavy
    )
    return _through_floor(root, paths)


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


def test_a_true_cut_stands_the_rotor_test(cut_case: Diagnosis) -> None:
    """The limit's held-out windows beat the best rotor in its place (stop 62's test), and
    the test leaves the named effects as they are."""
    d = cut_case
    d.chosen = [named(d, CUT)]
    assert rotor_test(d)
    assert d.rotor is not None and d.rotor["p_torque_better"] < d.opts.rotor_alpha
    rotor_check(d)
    assert [c.name for s in d.chosen for c in s.fit.candidates] == ["torque_limit"]
    assert d.rotor_withdrawn is None


def test_a_heavier_rotor_s_stand_in_cut_is_withdrawn(heavy_rotor_case: Diagnosis) -> None:
    """No cut, a rotor twice the configured one: the cut that gives the same accelerations
    with the configured rotor (half the limit) does not beat the rotor in its place on the
    held-out windows, so nothing is named; with the test off (rotor_alpha 1) it stays."""
    d = heavy_rotor_case
    stand_in = {"torque_limit": {"fraction": -0.5}}
    d.opts = replace(d.opts, rotor_alpha=1.0)
    d.chosen = [named(d, stand_in)]
    assert rotor_test(d)  # off: the limit stands, the comparison is still made
    d.opts = replace(d.opts, rotor_alpha=Options.rotor_alpha)
    d.chosen = [named(d, stand_in)]
    rotor_check(d)
    assert d.rotor is not None and d.rotor["p_torque_better"] >= Options.rotor_alpha
    assert d.rotor["armature"] > d.base.motor.armature
    assert d.chosen == [] and [c.name for s in d.demoted for c in s.fit.candidates] == [
        "torque_limit"
    ]
    assert d.rotor_withdrawn is not None and d.rotor_withdrawn["effects"] == ["torque_limit"]


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
