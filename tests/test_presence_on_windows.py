"""Whether a named effect is more than the model's form, judged on the windows' interval
(``Options.presence_on_windows``, stop 132): the signal groups' disagreement widens the
reported interval, not the decision."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis.judge import allowance_reaches_off
from rover_env.calibration.diagnosis.select import withdraw_within_allowance
from rover_env.calibration.fit import Fit, widen_by_groups
from rover_env.calibration.noise_interval import NoiseSE, widen_by_noise

PAD = (0.0316, 0.0)
"""Rolling resistance's clean-fit pad as shipped (clean builds fit up to 0.0316)."""


def _rr(x: float, lo: float, hi: float, between: float) -> Fit:
    """Spent case 54809's rolling resistance: fitted 0.097 [0.078, 0.102] by its windows,
    free wheels 0.135 and joints 0.036 apart."""
    (c,) = catalogue(["rolling_resistance"])
    xa = np.array([x])
    f = Fit([c], xa, np.array([lo]), np.array([hi]), np.array([0.006]), 0.0, 0, c.to_ext(xa), 0.0, "train")  # fmt: skip
    f.between = between
    return f


def test_the_groups_widen_the_shown_interval_and_keep_the_windows_one() -> None:
    f = _rr(0.097, 0.078, 0.102, 0.068)
    widen_by_groups(f)
    f.allowance = {"rolling_resistance": PAD}
    _, lo, hi = f.physical()["rolling_resistance"]["c_rr"]
    assert lo == 0.0 and hi == pytest.approx(0.097 + np.hypot(0.005, 1.96 * 0.068))
    _, wlo, whi = f.physical(groups=False)["rolling_resistance"]["c_rr"]
    assert wlo == pytest.approx(0.078 - 0.0316) and whi == pytest.approx(0.102)
    assert allowance_reaches_off(f) == ["rolling_resistance.c_rr"]
    assert allowance_reaches_off(f, groups=False) == []
    widen_by_groups(f)  # finished again: the windows' interval is not the widened one
    assert f.physical(groups=False)["rolling_resistance"]["c_rr"][1] == pytest.approx(0.0464)


def test_a_fit_the_groups_did_not_widen_is_judged_the_same_either_way() -> None:
    for x, lo, hi in ((0.097, 0.078, 0.102), (0.04, 0.02, 0.06)):
        f = _rr(x, lo, hi, 0.0)
        widen_by_groups(f)
        f.allowance = {"rolling_resistance": PAD}
        assert f.windows_ci is None
        assert allowance_reaches_off(f) == allowance_reaches_off(f, groups=False)
    # Clean builds fit up to 0.0316: a windows' interval reaching below it is not named.
    assert allowance_reaches_off(f, groups=False) == ["rolling_resistance.c_rr"]


def test_sensor_noise_widens_the_windows_interval_too() -> None:
    f = _rr(0.097, 0.078, 0.102, 0.068)
    widen_by_groups(f)
    nse = NoiseSE(se=np.array([0.02]), bias=np.array([0.0]), draws=4, windows=16)
    widen_by_noise(f, nse)
    w_lo, w_hi = f.windows_ci  # type: ignore[misc]
    assert w_lo[0] == pytest.approx(0.097 - 1.96 * nse.total[0])
    assert w_hi[0] == pytest.approx(0.097 + 1.96 * nse.total[0])


def test_the_option_decides_which_interval_withdraws() -> None:
    def diag(on: bool) -> Any:
        f = _rr(0.097, 0.078, 0.102, 0.068)
        widen_by_groups(f)
        f.allowance = {"rolling_resistance": PAD}
        s = SimpleNamespace(fit=f, test="")
        return SimpleNamespace(
            opts=SimpleNamespace(name_beyond_allowance=True, presence_on_windows=on),
            chosen=[s], demoted=[], allowance_withdrawn=None, winner=s,
            w_floor={"wheel_3L": 2.0}, noise={"wheel_3L": 1.0},
            final_floor={"wheel_3L": 2.0}, say=lambda m: None,
        )  # fmt: skip

    on, off = diag(True), diag(False)
    withdraw_within_allowance(on)
    withdraw_within_allowance(off)
    assert len(on.chosen) == 1 and on.allowance_withdrawn is None
    assert off.chosen == [] and off.allowance_withdrawn["effects"] == ["rolling_resistance"]


def test_the_report_says_why_an_interval_reaching_off_is_named() -> None:
    from rover_env.calibration.report_notes import groups_note

    f = _rr(0.097, 0.078, 0.102, 0.068)
    f.groups = {"free_wheels": 0.1349, "joints": 0.03565}
    widen_by_groups(f)
    f.allowance = {"rolling_resistance": PAD}
    (line,) = groups_note([SimpleNamespace(fit=f)])  # type: ignore[list-item]
    assert "free_wheels 0.135, joints 0.0357" in line and "size is loose" in line
    clear = _rr(0.097, 0.078, 0.102, 0.0)
    clear.groups = {"free_wheels": 0.098, "joints": 0.096}
    clear.allowance = {"rolling_resistance": PAD}
    assert groups_note([SimpleNamespace(fit=clear)]) == []  # type: ignore[list-item]


def test_the_result_lists_the_names_made_on_the_windows() -> None:
    from rover_env.calibration.diagnosis.write import on_windows

    f = _rr(0.097, 0.078, 0.102, 0.068)
    widen_by_groups(f)
    f.allowance = {"rolling_resistance": PAD}
    clear = _rr(0.097, 0.078, 0.102, 0.0)
    clear.allowance = {"rolling_resistance": PAD}
    assert on_windows([SimpleNamespace(fit=f)]) == ["rolling_resistance"]  # type: ignore[list-item]
    assert on_windows([SimpleNamespace(fit=clear)]) == []  # type: ignore[list-item]


def test_the_result_keeps_the_interval_the_decision_was_made_on() -> None:
    from rover_env.calibration.diagnosis.judge import fit_dict
    from rover_env.calibration.diagnosis.state import Scored

    f = _rr(0.097, 0.078, 0.102, 0.068)
    s = Scored(f, 1.0, np.ones(4), 0.6, 1e-4, -27.6, -26.1, 32)
    assert fit_dict(s)["params_on_windows"] is None  # nothing widened it yet
    widen_by_groups(f)
    f.allowance = {"rolling_resistance": PAD}
    d = fit_dict(s)
    _, lo, hi = d["params_on_windows"]["rolling_resistance"]["c_rr"]
    assert lo == pytest.approx(0.078 - 0.0316) and hi == pytest.approx(0.102)
    assert d["params"]["rolling_resistance"]["c_rr"][1] == 0.0  # the one the user reads
