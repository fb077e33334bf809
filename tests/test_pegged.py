"""A fit that ends at its range's far end is the effect at its largest, not an estimate
(``judge.pegged``); with ``Options.pegged_last`` it is tried for the name after the
significant fits inside their ranges (stop 84: a rolling resistance at c_rr 0.3, the
range's top, took the soil's name on four spent soil singles)."""

from __future__ import annotations

import numpy as np

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis.judge import pegged
from rover_env.calibration.diagnosis.select import naming_order
from rover_env.calibration.diagnosis.state import Scored
from rover_env.calibration.fit import Fit


def _fit(name: str, *x: float) -> Fit:
    (c,) = catalogue([name])
    v = np.array(x)
    return Fit(
        [c], v, v - 0.01, v + 0.01, np.full(len(x), 0.005), 0.0, 0, c.to_ext(v), 0.0, "train"
    )


def _scored(f: Fit, d_bic: float) -> Scored:
    s = Scored(f, 0.0, np.zeros(3), 0.5, 1e-4, d_bic, d_bic, 32, significant=True)
    s.held_losses = np.ones(16)
    return s


def test_only_the_end_away_from_off_is_pegged() -> None:
    assert pegged(_fit("rolling_resistance", 0.3)) == ["rolling_resistance.c_rr"]
    assert pegged(_fit("rolling_resistance", 0.2995)) == ["rolling_resistance.c_rr"]
    assert pegged(_fit("rolling_resistance", 0.29)) == []
    assert pegged(_fit("rolling_resistance", 0.0)) == []  # at off: absent, not at its largest
    assert pegged(_fit("torque_limit", -0.8)) == ["torque_limit.fraction"]
    assert pegged(_fit("torque_limit", 1.0)) == ["torque_limit.fraction"]
    assert pegged(_fit("loose_soil", 10.0)) == ["loose_soil.inv_k_phi"]  # k_phi 1e5, softest
    assert pegged(_fit("loose_soil", 1e-4)) == []  # next to hard ground, which is off
    assert pegged(_fit("slope", 3.0, -14.0)) == ["slope.tilt_y_deg"]


def test_a_pegged_fit_is_tried_after_the_fits_inside_their_ranges() -> None:
    # Spent case 61844 (a soil single): the rolling resistance at 0.3 led the soil on
    # training ΔBIC (-56.5 against -53.5) and was named.
    rr = _scored(_fit("rolling_resistance", 0.3), -56.5)
    soil = _scored(_fit("loose_soil", 0.6), -53.5)
    slope = _scored(_fit("slope", 1.0, 0.5), -2.0)
    slope.significant = False
    ranked = [rr, soil, slope]
    assert naming_order(ranked, pegged_last=False) == [rr, soil]
    assert naming_order(ranked, pegged_last=True) == [soil, rr]
    soil.significant = False  # alone, a pegged fit is still tried
    assert naming_order(ranked, pegged_last=True) == [rr]


def test_a_pegged_leader_passed_over_is_recorded_and_reported() -> None:
    # Spent case 52917 (block 52900, a soil of k_phi 5.2e5): the rolling resistance at
    # c_rr 0.3 had training ΔBIC -79.3 against the soil's -61.8 and took the name.
    from rover_env.calibration.diagnosis.select import passed_over
    from rover_env.calibration.report_notes import passed_over_note

    rr = _scored(_fit("rolling_resistance", 0.3), -79.3)
    soil = _scored(_fit("loose_soil", 1.0 / 3.21), -61.8)
    rec = passed_over([rr, soil], soil, pegged_last=True)
    assert rec is not None
    assert rec["effect"] == "rolling_resistance" and rec["named_first"] == "loose_soil"
    assert rec["at_end"] == ["rolling_resistance.c_rr"]
    note = passed_over_note(rec)
    assert "rolling_resistance had the most evidence" in note and "loose_soil" in note
    assert passed_over([rr, soil], rr, pegged_last=True) is None  # it was named after all
    assert passed_over([rr, soil], soil, pegged_last=False) is None
    inside = _scored(_fit("rolling_resistance", 0.2), -79.3)
    assert passed_over([inside, soil], soil, pegged_last=True) is None  # not at its end


def test_beside_a_loose_soil_winner_no_tire_effect_is_tried() -> None:
    # Spent case 52917 with pegged_last: the soil named first, then a rolling resistance of
    # 0.065 beside it, the soil's own resistance under the catalogue's constants.
    from rover_env.calibration.candidates import REPLACED_BY_SOIL
    from rover_env.calibration.diagnosis.select import partner_pool

    cands = catalogue()
    beside_soil = {c.name for c in partner_pool(cands, ["loose_soil"], soil_alone=True)}
    assert not beside_soil & REPLACED_BY_SOIL
    assert {"slope", "command_lag", "command_delay", "torque_limit"} <= beside_soil
    assert "loose_soil" not in beside_soil
    off = {c.name for c in partner_pool(cands, ["loose_soil"], soil_alone=False)}
    assert "rolling_resistance" in off
    beside_rr = {c.name for c in partner_pool(cands, ["rolling_resistance"], soil_alone=True)}
    assert "loose_soil" in beside_rr and "friction" in beside_rr  # only a soil winner


def test_the_report_headline_says_a_pegged_leader_was_passed_over() -> None:
    from rover_env.calibration.report import _headline

    rec = {
        "effect": "rolling_resistance",
        "at_end": ["rolling_resistance.c_rr"],
        "value": "c_rr > 0.294 (95 %; fitted 0.3)",
        "named_first": "loose_soil",
    }
    result = {"named": [], "unexplained": [], "passed_over": rec}
    text = "\n".join(_headline(result, [], None, None))
    assert "rolling_resistance had the most evidence but ended at its range's far end" in text
    assert "loose_soil, fitted inside its range, was tried for the name first" in text
    assert "had the most evidence" not in "\n".join(
        _headline({**result, "passed_over": None}, [], None, None)
    )


def test_the_method_names_the_effects_left_out_beside_soil_only_when_they_are() -> None:
    from rover_env.calibration.candidates import REPLACED_BY_SOIL
    from rover_env.calibration.diagnosis.state import Options
    from rover_env.calibration.report_method import order_clauses

    text = order_clauses(Options())
    assert all(n in text for n in REPLACED_BY_SOIL) and "range's far end" in text
    assert order_clauses(Options(soil_alone=False, pegged_last=False)) == ""
