"""A model form is judged in units of each signal's residual under the nominal form
(``form_ladder.judged``): the dBIC a ladder reports is the one its best value's replay gives
in those units. Stop 68 judged them in units of each signal's sensor noise; on fresh cases
(block 50900) that named fewer effects right, and was reverted."""

from __future__ import annotations

import numpy as np
import pytest

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnosis.form_ladder import reprepare
from rover_env.calibration.diagnosis.form_loop import fit_speed_gain, with_speed_gain
from rover_env.calibration.fit import information_criteria
from rover_env.calibration.replay import Replayer, ReplaySettings, make_windows, prepare
from rover_env.config import load_rover
from rover_env.generators.make_logs import make_logs
from rover_env.logs import read_log

CFG = load_rover()
ST = ReplaySettings()


def test_a_form_is_judged_in_residual_units(tmp_path_factory: pytest.TempPathFactory) -> None:
    truth = with_speed_gain(CFG, 4.0 * CFG.motor.speed_gain)
    paths = make_logs(
        tmp_path_factory.mktemp("units"),
        {},
        drives=1,
        seed=5,
        duration=30.0,
        truth_rover=truth,
        progress=False,
    )
    prepared = [prepare(read_log(p), CFG, p.name, ST) for p in paths]
    windows = make_windows(prepared, ST)
    noise = rs.noise_floor(prepared)
    form = fit_speed_gain(CFG, prepared, windows, ST, noise)
    assert form.value != form.nominal, form

    base = Replayer(CFG, ST).run(prepared, windows)
    cfg = with_speed_gain(CFG, form.value)
    best = Replayer(cfg, ST).run(reprepare(prepared, cfg, ST), windows)

    def d_bic(units: dict[str, float]) -> float:
        l0, lb = rs.window_losses(base, units), rs.window_losses(best, units)
        return information_criteria(float(np.sum(np.log(lb / l0))), len(windows), 1)[1]

    scale = rs.signal_scale(rs.stack(base, prepared), noise)
    assert form.d_bic == pytest.approx(d_bic(scale), rel=1e-6, abs=1e-6)
    assert abs(d_bic(scale) - d_bic(noise)) > 1.0  # the test can tell the units apart
