"""The joints in diagnose's model form. The sensors' zeros (``JointSpec.zero``): what the
sensors read, what the replay compares, diagnose's closed-form fit of them
(``form.fit_joint_zeros``), which must find zeros injected into the model's own logs, and
their profiling out of every fit. The yaw joints' leaf springs (``form.fit_yaw_spring``):
kept on the model's own drive, found where the springs are stiffer."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnosis.form import (
    JOINT_HEIGHT_LADDER,
    SPRING_LADDER,
    ZERO_PREFIX,
    FormFit,
    fit_com_height,
    fit_joint_height,
    fit_joint_zeros,
    fit_yaw_spring,
    forms_differ,
    nominal_com_height,
    with_form,
    with_joint_zero,
)
from rover_env.calibration.evaluator import Evaluator
from rover_env.calibration.replay import (
    PreparedLog,
    ReplaySettings,
    WindowResult,
    make_windows,
    prepare,
)
from rover_env.config import JOINTS, ConfigError, JointSpec, RoverConfig
from rover_env.generators.make_logs import make_logs
from rover_env.logs import read_log
from rover_env.sim.simulator import RoverSim

CFG = RoverConfig()
ST = ReplaySettings()
TRUTH = {"theta_1": 0.02, "theta_4": -0.015}
"""Zeros injected (rad): about a degree, a hand-set potentiometer's error."""


def test_a_zero_outside_the_stops_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"joint\.zero"):
        JointSpec(limit=0.6, zero=0.7)


def test_the_sensor_reads_the_angle_plus_its_zero() -> None:
    cfg = with_joint_zero(CFG, "theta_4", 0.03)
    a, b = RoverSim(CFG), RoverSim(cfg)
    a.reset()
    b.reset()
    a.step(200)
    b.step(200)
    np.testing.assert_allclose(b.joint_angles(), a.joint_angles(), atol=1e-12)  # physics
    d = b.sensors().theta - a.sensors().theta
    np.testing.assert_allclose(d, [0.0, 0.0, 0.0, 0.03, 0.0], atol=1e-12)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory: pytest.TempPathFactory) -> list[FormFit]:
    truth = CFG
    for j, z in TRUTH.items():
        truth = with_joint_zero(truth, j, z)
    root = tmp_path_factory.mktemp("zeros")
    paths = make_logs(root, {}, drives=1, seed=3, duration=25.0, truth_rover=truth, progress=False)
    prepared = [prepare(read_log(p), CFG, p.name, ST) for p in paths]
    windows = make_windows(prepared, ST)
    return fit_joint_zeros(CFG, prepared, windows, ST, rs.noise_floor(prepared))


def test_injected_zeros_are_found(fitted: list[FormFit]) -> None:
    got = {f.name.removeprefix(ZERO_PREFIX): f.value for f in fitted}
    assert list(got) == list(JOINTS)
    for j in JOINTS:
        assert abs(got[j] - TRUTH.get(j, 0.0)) < 1e-3, (j, got[j])


def test_each_injected_zero_pays_for_itself_on_its_own_sensor(fitted: list[FormFit]) -> None:
    by = {f.name.removeprefix(ZERO_PREFIX): f for f in fitted}
    for j in TRUTH:
        assert by[j].adopted and by[j].d_bic < -10 and by[j].gain > 0.9, by[j]


def test_a_fitted_zero_goes_into_the_configuration(fitted: list[FormFit]) -> None:
    cfg = CFG
    for f in fitted:
        cfg = with_form(cfg, f)
    assert cfg.joints["theta_4"].zero == pytest.approx(fitted[3].value)
    assert cfg.joints["theta_4"].stiffness == CFG.joints["theta_4"].stiffness


def _zero(j: str, v: float) -> FormFit:
    return FormFit(ZERO_PREFIX + j, "rad", 0.0, v, {}, 0.5, 0.01, -20.0, True)


def test_zeros_alone_never_make_the_forms_differ() -> None:
    """Every fit profiles its own zeros, so zeros refitted beside a winner need no second
    pass; another adopted form does."""
    a = [_zero("theta_4", -0.033)]
    assert not forms_differ(a, [_zero("theta_4", -0.010)])
    sigma = FormFit("relaxation_length", "m", 0.02, 0.005, {}, 0.2, 0.01, -5.0, True)
    assert forms_differ([*a, sigma], a)


@pytest.fixture(scope="module")
def clean_logs(tmp_path_factory: pytest.TempPathFactory) -> list[PreparedLog]:
    root = tmp_path_factory.mktemp("clean")
    paths = make_logs(root, {}, drives=2, seed=5, duration=20.0, progress=False)
    return [prepare(read_log(p), CFG, p.name, ST) for p in paths]


def _rms(results: list[WindowResult]) -> np.ndarray:
    return np.sqrt(np.mean(np.vstack([r.resid[:, 6:11] for r in results]) ** 2, axis=0))


def test_profiled_fits_do_not_see_a_constant_sensor_offset(clean_logs: list[PreparedLog]) -> None:
    """A joint sensor 20 mrad off is what profiling takes out, on the training windows and,
    with the training windows' shift, on the held-out ones; unprofiled it dominates."""
    off = np.array([0.02, 0.0, -0.02, 0.02, 0.0])
    shifted = [
        prepare(dataclasses.replace(p.log, theta=p.log.theta + off), CFG, p.name, ST)
        for p in clean_logs
    ]
    windows = make_windows(clean_logs, ST)
    sets = {
        "train": [w for w in windows if w.log_index == 0],
        "held": [w for w in windows if w.log_index == 1],
    }
    for which in ("train", "held"):
        clean = Evaluator(CFG, ST, clean_logs, sets, profile_zeros=True).run({}, which)
        ev = Evaluator(CFG, ST, shifted, sets, profile_zeros=True)
        raw = Evaluator(CFG, ST, shifted, sets).run({}, which)
        prof = ev.run({}, which)
        assert np.all(_rms(raw)[off != 0] > 0.015)
        np.testing.assert_allclose(_rms(prof), _rms(clean), rtol=0.3, atol=5e-4)
        np.testing.assert_allclose(ev.zero_shift({}, which), -off, atol=2e-3)


def test_the_yaw_spring_form_sets_both_yaw_joints() -> None:
    cfg = with_form(CFG, FormFit("yaw_spring", "N m/rad", 10.0, 15.0, {}, 0.2, 0.01, -5.0, True))
    assert cfg.joints["theta_2"].stiffness == cfg.joints["theta_5"].stiffness == 15.0
    assert cfg.joints["theta_4"].stiffness == CFG.joints["theta_4"].stiffness


@pytest.fixture(scope="module")
def springs(tmp_path_factory: pytest.TempPathFactory) -> list[FormFit]:
    """The yaw spring fitted on turning drives of the model itself at 10 N m/rad, of the
    model with springs at 20, and with springs at 100 (beyond the ladder's 40)."""
    out = []
    for k in (10.0, 20.0, 100.0):
        truth = with_form(CFG, FormFit("yaw_spring", "N m/rad", 10.0, k, {}, 0, 1, 0, True))
        root = tmp_path_factory.mktemp(f"springs{k:.0f}")
        paths = make_logs(
            root, {}, drives=1, seed=4, duration=30.0, truth_rover=truth, progress=False
        )
        prepared = [prepare(read_log(p), CFG, p.name, ST) for p in paths]
        windows = make_windows(prepared, ST)
        out.append(fit_yaw_spring(CFG, prepared, windows, ST, rs.noise_floor(prepared)))
    return out


def test_the_yaw_spring_is_kept_on_the_models_own_drive(springs: list[FormFit]) -> None:
    own = springs[0]
    assert set(SPRING_LADDER) <= set(own.ladder)
    assert not own.adopted, own


def test_a_stiffer_yaw_spring_is_found(springs: list[FormFit]) -> None:
    stiff = springs[1]
    assert stiff.adopted and stiff.d_bic < 0, stiff
    assert 17.0 < stiff.value < 23.5, stiff.value  # 20: a ladder point


def test_a_spring_beyond_the_ladder_is_reported_not_adopted(springs: list[FormFit]) -> None:
    """The windows ask for more than the ladder's top: the best rung is that end, which the
    stage reports (``at_end``) and does not adopt, since the form cannot supply it."""
    beyond = springs[2]
    assert beyond.value == max(SPRING_LADDER), beyond
    assert beyond.d_bic < 0 and beyond.at_end and not beyond.adopted, beyond
    assert not springs[1].at_end


@pytest.fixture(scope="module")
def heights(tmp_path_factory: pytest.TempPathFactory) -> list[FormFit]:
    """The joints' height fitted on drives of the model itself (joints on the axle line) and
    of the model with its joints 6 cm above the axles."""
    out = []
    for h in (0.0, 0.06):
        truth = with_form(CFG, FormFit("joint_height", "m", 0.0, h, {}, 0, 1, 0, True))
        root = tmp_path_factory.mktemp(f"height{h:.2f}")
        paths = make_logs(
            root, {}, drives=1, seed=4, duration=30.0, truth_rover=truth, progress=False
        )
        prepared = [prepare(read_log(p), CFG, p.name, ST) for p in paths]
        windows = make_windows(prepared, ST)
        out.append(fit_joint_height(CFG, prepared, windows, ST, rs.noise_floor(prepared)))
    return out


def test_the_geometry_forms_set_the_heights() -> None:
    cfg = with_form(CFG, FormFit("joint_height", "m", 0.0, 0.05, {}, 0.2, 0.01, -5.0, True))
    cfg = with_form(cfg, FormFit("com_height", "m", 0.08, 0.03, {}, 0.2, 0.01, -5.0, True))
    assert (cfg.geometry.joint_height, cfg.geometry.com_height) == (0.05, 0.03)
    assert nominal_com_height(cfg) == 0.03
    assert 0.07 < nominal_com_height(CFG) < 0.1


def test_the_joint_height_is_kept_on_the_models_own_drive(heights: list[FormFit]) -> None:
    own = heights[0]
    assert set(JOINT_HEIGHT_LADDER) <= set(own.ladder)
    assert not own.adopted, own


def test_a_raised_joint_is_found(heights: list[FormFit]) -> None:
    raised = heights[1]
    assert raised.adopted and raised.d_bic < 0, raised
    assert 0.045 < raised.value < 0.075, raised.value  # 0.06: a ladder point


def test_the_centre_of_mass_is_found_beside_a_slope(tmp_path: Path) -> None:
    """On a 6 deg slope across the drive, a rover whose centres of mass sit 3 cm above the
    axles (this model's: 8-9 cm): fitted beside the slope (as the forms are fitted again
    beside a named one) the height is found; on the same logs without the slope in the
    model it is not adopted (it cannot stand in for the slope)."""
    slope = {"slope": {"deg": 6.0, "heading_deg": 90.0}}
    truth = with_form(CFG, FormFit("com_height", "m", 0.08, 0.03, {}, 0, 1, 0, True))
    paths = make_logs(
        tmp_path, slope, drives=1, seed=4, duration=30.0, truth_rover=truth, progress=False
    )
    beside = dataclasses.replace(CFG, extensions=slope)
    prepared = [prepare(read_log(p), beside, p.name, ST) for p in paths]
    windows = make_windows(prepared, ST)
    noise = rs.noise_floor(prepared)
    found = fit_com_height(beside, prepared, windows, ST, noise)
    assert found.adopted and 0.015 < found.value < 0.045, found
    alone = fit_com_height(
        CFG, [prepare(read_log(p), CFG, p.name, ST) for p in paths], windows, ST, noise
    )
    assert not alone.adopted, alone
