"""The model-form stage of diagnose (rover_env.calibration.model_form): the tire's
relaxation length, fitted before any effect, finds the truth's value on this project's logs
and a much shorter one on the second implementation's, whose tire is steady state."""

from __future__ import annotations

from pathlib import Path

import pytest

from rover_env.calibration import residuals as rs
from rover_env.calibration.foreign_logs import make_foreign_logs
from rover_env.calibration.make_logs import make_logs
from rover_env.calibration.model_form import LADDER, RelaxationFit, fit_relaxation, with_sigma
from rover_env.calibration.replay import ReplaySettings, make_windows, prepare
from rover_env.config import RoverConfig
from rover_env.logs import read_log

CFG = RoverConfig()
ST = ReplaySettings()


def _fit(paths: list[Path]) -> RelaxationFit:
    prepared = [prepare(read_log(p), CFG, p.name, ST) for p in paths]
    windows = make_windows(prepared, ST)
    return fit_relaxation(CFG, prepared, windows, ST, rs.noise_floor(prepared))


@pytest.fixture(scope="module")
def fits(tmp_path_factory: pytest.TempPathFactory) -> dict[str, RelaxationFit]:
    root = tmp_path_factory.mktemp("model_form")
    own = make_logs(root / "own", {}, drives=1, seed=7, duration=30.0, progress=False)
    foreign = make_foreign_logs(
        root / "foreign", {}, drives=1, seed=7, duration=30.0, progress=False
    )
    return {"own": _fit(own), "foreign": _fit(foreign)}


def test_relaxation_length_is_the_truths_on_this_projects_logs(
    fits: dict[str, RelaxationFit],
) -> None:
    f = fits["own"]
    assert f.nominal == CFG.tire.sigma_x
    assert set(LADDER) <= set(f.ladder)  # the whole ladder was tried: nothing starts at 2 cm
    assert f.nominal / 1.5 <= f.sigma <= f.nominal * 1.5


def test_relaxation_length_is_short_on_a_steady_state_tire(fits: dict[str, RelaxationFit]) -> None:
    f = fits["foreign"]
    assert f.adopted and f.sigma <= f.nominal / 2
    assert f.ladder[f.sigma] < 0 < f.gain  # the training windows fit better there


def test_with_sigma_sets_both_directions() -> None:
    t = with_sigma(CFG, 0.005).tire
    assert (t.sigma_x, t.sigma_y) == (0.005, 0.005)
    assert with_sigma(CFG, 0.005).motor == CFG.motor
