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
from rover_env.calibration.fit import Fit, fit
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


CUT40 = {"torque_limit": {"fraction": -0.4}}


@pytest.fixture(scope="module")
def heavy_rotor_cut_case(tmp_path_factory: pytest.TempPathFactory) -> Diagnosis:
    """A rover whose rotor is twice the configured one *and* whose limit is cut by 40 %
    (as the independent generator's case 50112: -0.42)."""
    root = tmp_path_factory.mktemp("heavy_rotor_cut")
    nominal = load_rover("proto_explorer")
    heavy = with_armature(nominal, 2.0 * nominal.motor.armature)
    paths = make_logs(
        root / "logs", CUT40, drives=2, seed=6, duration=24.0, progress=False, truth_rover=heavy
    )
    return _through_floor(root, paths)


def test_a_cut_beside_a_heavier_rotor_stands_at_that_rotor(
    heavy_rotor_cut_case: Diagnosis,
) -> None:
    """Stop 63: the limit is tested at the rotor inertia its refits favour on the training
    windows. The limit fitted with the configured rotor stands in for both (about -0.63);
    refitted from there beside twice the rotor it comes out near the truth, the training
    windows favour it, and it beats the best rotor alone on the held-out windows."""
    d = heavy_rotor_cut_case
    s = named(d, CUT40)
    s.fit = fit(d.ev, catalogue(["torque_limit"]), "train")  # the magnitude-blind search
    assert s.fit.x[0] < -0.5  # the stand-in for the cut and the rotor together
    d.chosen = [s]
    rotor_check(d)
    assert d.rotor is not None
    a0 = d.base.motor.armature
    assert d.rotor["torque_limit_armature"] == pytest.approx(2.0 * a0)
    assert d.rotor["torque_limit"]["train_gain"] > d.rotor["rotor"]["train_gain"]
    assert d.rotor["p_torque_better"] < Options.rotor_alpha
    assert d.chosen == [s] and d.rotor_withdrawn is None
    assert "refitted beside the rotor inertia 0.05 kg m²" in rotor_text(d.rotor)


def test_a_heavier_rotor_alone_stays_withdrawn_with_the_limit_refitted_beside_it(
    heavy_rotor_case: Diagnosis,
) -> None:
    """No cut, a rotor twice the configured one: the limit refitted at that rotor explains
    nothing the rotor alone does not, so the stand-in cut is still withdrawn."""
    d = heavy_rotor_case
    d.opts = replace(d.opts, rotor_alpha=Options.rotor_alpha)
    d.rotor_withdrawn = None
    s = named(d, {"torque_limit": {"fraction": -0.5}})
    d.chosen = [s]
    rotor_check(d)
    assert d.rotor is not None and d.rotor["p_torque_better"] >= Options.rotor_alpha
    assert d.chosen == [] and d.rotor_withdrawn is not None


RR = {"rolling_resistance": {"c_rr": 0.05}}


@pytest.fixture(scope="module")
def rr_case(tmp_path_factory: pytest.TempPathFactory) -> Diagnosis:
    """The model's own drives with rolling resistance 0.05, through the floor stage."""
    root = tmp_path_factory.mktemp("rotor_rr")
    paths = make_logs(root / "logs", RR, drives=2, seed=6, duration=24.0, progress=False)
    return _through_floor(root, paths)


def _pair(d: Diagnosis) -> Scored:
    """A torque limit and rolling resistance named together (as forward selection would)."""
    cands = catalogue(["rolling_resistance", "torque_limit"])
    x = np.array([0.05, -0.5])
    ext = {"rolling_resistance": {"c_rr": 0.05}, "torque_limit": {"fraction": -0.5}}
    f = Fit(cands, x, x - 0.01, x + 0.01, np.full(2, 0.005), 1.0, 3, ext, 0.0, "train")
    return Scored(f, 0.0, np.zeros(1), 0.5, 1e-4, -10.0, -10.0, len(d.train_w), significant=True)


def _withdrawing(d: Diagnosis, monkeypatch: pytest.MonkeyPatch) -> None:
    """The rotor test made to withdraw whatever limit is named (its own tests are above)."""
    from rover_env.calibration.diagnosis import select

    def withdraw(dd: Diagnosis) -> bool:
        dd.rotor = {"p_torque_better": 0.6, "armature": 2.0 * dd.base.motor.armature}
        return False

    monkeypatch.setattr(select, "rotor_test", withdraw)


def test_a_withdrawn_limit_s_partner_named_alone_stays_named(
    rr_case: Diagnosis, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Stop 63: the rotor test withdraws the limit of a pair; the partner's own single fit,
    named by itself (significant, clear of off, trading nothing), is named instead of nothing."""
    d = rr_case
    _withdrawing(d, monkeypatch)
    rr = named(d, RR)
    rr.fit.x, rr.fit.ci_lo, rr.fit.ci_hi = np.array([0.05]), np.array([0.045]), np.array([0.055])
    d.winner, d.ranked, d.chosen = rr, [rr], [_pair(d)]
    d.w_floor = d.noise
    rotor_check(d)
    assert d.chosen == [rr]
    assert d.rotor_withdrawn is not None and d.rotor_withdrawn["kept"] == "rolling_resistance"
    assert d.rotor_withdrawn["effects"] == ["rolling_resistance", "torque_limit"]


def test_a_withdrawn_limit_s_partner_not_named_alone_goes_with_it(
    rr_case: Diagnosis, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The partner's single fit did not pass the window test (or was never fitted alone):
    nothing is named, as before stop 63."""
    d = rr_case
    _withdrawing(d, monkeypatch)
    rr = named(d, RR)
    rr.significant = False
    d.winner, d.ranked, d.chosen, d.rotor_withdrawn = None, [rr], [_pair(d)], None
    rotor_check(d)
    assert d.chosen == [] and d.rotor_withdrawn is not None
    assert "kept" not in d.rotor_withdrawn
    d.ranked, d.chosen = [], [_pair(d)]
    rotor_check(d)
    assert d.chosen == []
