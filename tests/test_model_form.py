"""The model-form stage of diagnose (rover_env.calibration.diagnosis.form), fitted before any
effect: the tire's relaxation length finds the truth's value on this project's logs and a
much shorter one on the second implementation's, whose tire is steady state; the speed
loop's anti-windup bound keeps the configuration's on this project's logs and takes a
much smaller one on the second implementation's, whose PI integrates conditionally."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnosis.form import (
    FLOOR_LADDER,
    WINDUP_LADDER,
    FormFit,
    carried_ladder,
    fit_relaxation,
    fit_slip_floor,
    fit_windup,
    with_form,
    with_sigma,
    with_windup,
)
from rover_env.calibration.replay import ReplaySettings, make_windows, prepare
from rover_env.config import RoverConfig
from rover_env.generators.foreign_logs import make_foreign_logs
from rover_env.generators.make_logs import make_logs
from rover_env.logs import read_log

CFG = RoverConfig()
ST = ReplaySettings()


def _fit(paths: list[Path]) -> tuple[FormFit, FormFit, FormFit]:
    prepared = [prepare(read_log(p), CFG, p.name, ST) for p in paths]
    windows = make_windows(prepared, ST)
    noise = rs.noise_floor(prepared)
    relax = fit_relaxation(CFG, prepared, windows, ST, noise)
    cfg = with_form(CFG, relax) if relax.adopted else CFG  # diagnose's order: sigma, floor
    floor = fit_slip_floor(cfg, prepared, windows, ST, noise)
    return relax, fit_windup(cfg, prepared, windows, ST, noise), floor


@pytest.fixture(scope="module")
def both(
    tmp_path_factory: pytest.TempPathFactory,
) -> dict[str, tuple[FormFit, FormFit, FormFit]]:
    root = tmp_path_factory.mktemp("model_form")
    own = make_logs(root / "own", {}, drives=1, seed=7, duration=30.0, progress=False)
    foreign = make_foreign_logs(
        root / "foreign", {}, drives=1, seed=7, duration=30.0, progress=False
    )
    return {"own": _fit(own), "foreign": _fit(foreign)}


@pytest.fixture(scope="module")
def fits(both: dict[str, tuple[FormFit, FormFit, FormFit]]) -> dict[str, FormFit]:
    return {k: v[0] for k, v in both.items()}


@pytest.fixture(scope="module")
def windups(both: dict[str, tuple[FormFit, FormFit, FormFit]]) -> dict[str, FormFit]:
    return {k: v[1] for k, v in both.items()}


@pytest.fixture(scope="module")
def floors(both: dict[str, tuple[FormFit, FormFit, FormFit]]) -> dict[str, FormFit]:
    return {k: v[2] for k, v in both.items()}


def test_slip_floor_is_none_on_this_projects_logs(floors: dict[str, FormFit]) -> None:
    f = floors["own"]
    assert f.nominal == 0.0 and set(FLOOR_LADDER) <= set(f.ladder)  # the whole ladder
    assert not f.adopted and f.d_bic > 0


def test_slip_floor_is_found_on_a_regularised_steady_state_tire(
    floors: dict[str, FormFit],
) -> None:
    # The second generator regularises its slip below 5 cm/s (foreign_logs.V_EPS).
    f = floors["foreign"]
    assert f.adopted and 0.02 <= f.value <= 0.1
    assert f.ladder[f.value] < 0 < f.gain


def test_relaxation_length_is_the_truths_on_this_projects_logs(
    fits: dict[str, FormFit],
) -> None:
    f = fits["own"]
    assert f.nominal == CFG.tire.sigma_x
    # the whole ladder the rover's step carries was tried: nothing starts at 2 cm
    assert set(carried_ladder(CFG)) <= set(f.ladder)
    assert f.nominal / 1.5 <= f.value <= f.nominal * 1.5
    # the ladder's resolution, for comparing two fits (forms_differ): a factor 2 apart
    assert f.log_spacing and f.spacing == pytest.approx(np.log(2.0))


def test_relaxation_length_is_short_on_a_steady_state_tire(fits: dict[str, FormFit]) -> None:
    f = fits["foreign"]
    assert f.adopted and f.value <= f.nominal / 2
    assert f.ladder[f.value] < 0 < f.gain  # the training windows fit better there


def test_with_sigma_sets_both_directions() -> None:
    t = with_sigma(CFG, 0.005).tire
    assert (t.sigma_x, t.sigma_y) == (0.005, 0.005)
    assert with_sigma(CFG, 0.005).motor == CFG.motor


def test_windup_bound_is_the_configurations_on_this_projects_logs(
    windups: dict[str, FormFit],
) -> None:
    f = windups["own"]
    assert set(WINDUP_LADDER) <= set(f.ladder)  # the whole ladder was tried
    assert f.nominal == CFG.motor.max_angle_error
    assert not f.adopted and f.d_bic > 0  # no bound pays for its parameter
    # Bounds well below the nominal starve the integral: every one of them fits worse.
    assert all(v > 0 for x, v in f.ladder.items() if x <= f.nominal / 8)


def test_windup_bound_is_small_on_a_conditionally_integrating_loop(
    windups: dict[str, FormFit],
) -> None:
    f = windups["foreign"]
    assert f.adopted and f.value <= f.nominal / 4
    assert f.ladder[f.value] < 0 < f.gain


def test_with_windup_sets_the_bound_only() -> None:
    c = with_windup(CFG, 0.03)
    assert c.motor.max_angle_error == 0.03
    assert c.tire == CFG.tire and c.motor.torque_limit == CFG.motor.torque_limit
