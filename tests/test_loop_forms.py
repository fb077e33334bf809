"""The speed loop's gains in diagnose's model form (``form.fit_speed_gain``,
``form.fit_integral_gain``): kept on the model's own drive, found where the loop is stiffer,
reported and not adopted beyond the ladder, and set by ``with_form``."""

from __future__ import annotations

import pytest

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnosis.form import FormFit, with_form
from rover_env.calibration.diagnosis.form_loop import (
    LOOP_GAIN_STEPS,
    fit_integral_gain,
    fit_speed_gain,
)
from rover_env.calibration.replay import ReplaySettings, make_windows, prepare
from rover_env.config import load_rover
from rover_env.generators.make_logs import make_logs
from rover_env.logs import read_log

CFG = load_rover()
ST = ReplaySettings()


def _form(name: str, value: float) -> FormFit:
    nominal = getattr(CFG.motor, name)
    return FormFit(name, "", nominal, value, {}, 0.0, 1.0, 0.0, True)


def test_the_loop_forms_set_the_motors_gains() -> None:
    cfg = with_form(with_form(CFG, _form("speed_gain", 6.0)), _form("integral_gain", 20.0))
    assert (cfg.motor.speed_gain, cfg.motor.integral_gain) == (6.0, 20.0)
    assert cfg.motor.torque_limit == CFG.motor.torque_limit


@pytest.fixture(scope="module")
def gains(tmp_path_factory: pytest.TempPathFactory) -> dict[str, FormFit]:
    """Both gains fitted on drives of the model itself, and the proportional gain on drives
    of the model with a loop 4 x and 16 x stiffer (beyond the ladder's x 8)."""
    out = {}
    truths = {"own": 1.0, "stiff": 4.0, "beyond": 16.0}
    for key, k in truths.items():
        truth = with_form(CFG, _form("speed_gain", k * CFG.motor.speed_gain))
        root = tmp_path_factory.mktemp(f"gain{key}")
        paths = make_logs(
            root, {}, drives=1, seed=5, duration=30.0, truth_rover=truth, progress=False
        )
        prepared = [prepare(read_log(p), CFG, p.name, ST) for p in paths]
        windows = make_windows(prepared, ST)
        noise = rs.noise_floor(prepared)
        out[key] = fit_speed_gain(CFG, prepared, windows, ST, noise)
        if key == "own":
            out["own_integral"] = fit_integral_gain(CFG, prepared, windows, ST, noise)
    return out


def test_the_gains_are_kept_on_the_models_own_drive(gains: dict[str, FormFit]) -> None:
    rungs = {k * CFG.motor.speed_gain for k in LOOP_GAIN_STEPS}
    assert rungs <= set(gains["own"].ladder), gains["own"].ladder
    assert not gains["own"].adopted, gains["own"]
    assert not gains["own_integral"].adopted, gains["own_integral"]


def test_a_stiffer_loop_is_found(gains: dict[str, FormFit]) -> None:
    stiff = gains["stiff"]
    assert stiff.adopted and stiff.d_bic < 0, stiff
    assert 5.6 < stiff.value < 11.3, stiff.value  # 8: a ladder point (x 4)


def test_a_loop_beyond_the_ladder_is_reported_not_adopted(gains: dict[str, FormFit]) -> None:
    beyond = gains["beyond"]
    assert beyond.value == max(LOOP_GAIN_STEPS) * CFG.motor.speed_gain, beyond
    assert beyond.d_bic < 0 and beyond.at_end and not beyond.adopted, beyond
