"""The report's note beside a named torque limit: on flat drives the limit is measured
through the wheel's acceleration, so it is only as good as the configured rotor inertia."""

from __future__ import annotations

from dataclasses import replace

from rover_env.calibration.report import _torque_note


def test_a_named_torque_limit_names_the_rotor_inertia_it_rests_on() -> None:
    text = " ".join(_torque_note(["torque_limit"], 0.025))
    assert "motor.armature" in text and "0.025 kg m²" in text and "blocked wheel" in text


def test_no_note_without_a_torque_limit() -> None:
    assert _torque_note(["rolling_resistance", "slope"], 0.025) == []


def test_the_rotor_fitted_in_its_place_is_reported_beside_it() -> None:
    alt = {
        "armature_configured": 0.025,
        "armature": 0.0707,
        "rotor": {"train_gain": 0.082, "d_bic": -0.2, "held_gain": 0.45},
        "torque_limit": {"train_gain": 0.100, "d_bic": -1.2, "held_gain": 0.477},
    }
    text = " ".join(_torque_note(["torque_limit"], 0.025, alt))
    assert "`motor.armature` 0.0707 kg m² for 0.025" in text
    assert "training windows 8.2 % better (dBIC -0.2)" in text and "held-out 47.7 % better" in text


def test_the_limit_refitted_at_the_rotor_tolerance_s_ends_is_reported() -> None:
    prof = {
        "torque_limit": {
            "armature_configured": 0.025,
            "range": 2.0,
            "refits": [
                {"armature": 0.0125, "x": [-0.81], "lo": [-0.83], "hi": [-0.79]},
                {"armature": 0.05, "x": [-0.64], "lo": [-0.67], "hi": [-0.61]},
            ],
        }
    }
    text = " ".join(_torque_note(["torque_limit"], 0.025, None, prof))
    assert "(x 2)" in text
    assert "0.0125 kg m²: -0.81 [-0.83, -0.79]; 0.05 kg m²: -0.64 [-0.67, -0.61]" in text
    assert _torque_note(["slope"], 0.025, None, prof) == []


def test_the_report_tables_each_effect_s_threshold_beside_its_detection_limit() -> None:
    from rover_env.calibration.report import visibility_lines

    fits = {
        "torque_limit": {
            "threshold": {"-": 0.178, "+": 44.0},
            "detectable": {"-": 0.971},
            "nameable": {"-": 0.971},
        },
        "slope": {
            "threshold": {"deg": 0.754},
            "detectable": {"deg": 1.5},
            "nameable": {"deg": 2.4},
        },
        "friction": {"threshold": {"+": 0.03}, "detectable": {"+": 0.05}},  # stored before stop 95
        "combined_slip": {"threshold": {}, "detectable": {}},
    }
    text = "\n".join(visibility_lines(fits))
    assert "| slope | deg 0.754 | deg 1.5 | deg 2.4 |" in text
    assert "| torque_limit | + 44, - 0.178 | - 0.971 | - 0.971 |" in text
    assert "| friction | + 0.03 | + 0.05 | – |" in text
    assert "combined_slip" not in text
    assert visibility_lines({}) == []


def test_a_form_at_the_end_of_its_range_is_said_so() -> None:
    """A form kept nominal because its best value is an open end of its ladder says why;
    one kept nominal because it does not pay its BIC does not."""
    from rover_env.calibration.diagnosis.state import FormFit
    from rover_env.calibration.report_method import model_form_line

    def form(at_end: bool, d_bic: float) -> dict[str, object]:
        f = FormFit(
            "yaw_spring",
            "N m/rad",
            10.0,
            40.0,
            {10.0: 0.0, 40.0: -0.2},
            0.17,
            1e-8,
            d_bic,
            False,
            at_end=at_end,
        )
        return f.as_json()

    line = model_form_line({"yaw_spring": form(True, -2.6)})
    assert "the end of the range tried" in line and "40 N m/rad" in line, line
    assert "end of the range" not in model_form_line({"yaw_spring": form(False, 1.2)})


def test_a_height_the_soil_explains_better_is_said_so() -> None:
    """A joint height that paid its BIC but was not adopted because the loose soil explains
    more (``form_soil.height_beside_soil``) says so in the report's model-form line; an
    adopted one does not."""
    from rover_env.calibration.diagnosis.state import FormFit
    from rover_env.calibration.report_method import model_form_line

    said = "the loose soil explains more, loose_soil k_phi 3e+05 (x) at -0.755"
    f = FormFit("joint_height", "m", 0.0, -0.031, {-0.031: -0.133}, 0.125, 0.006, -0.8, False)
    line = model_form_line({"joint_height": replace(f, beaten_by=said).as_json()})
    assert "-31 mm" in line and "not adopted before the effects: " + said in line, line
    adopted = model_form_line({"joint_height": replace(f, adopted=True).as_json()})
    assert "adopted" in adopted and "soil" not in adopted, adopted


def test_a_small_trade_is_reported_beside_the_named_effect() -> None:
    """A trade under the share (``trade_excused``) is said with its signals, their RMS
    ratios and the share, so the user sees what the named effect made worse."""
    from rover_env.calibration.report_notes import trade_note

    worse = {"theta_4": {"rms_ratio": 1.155, "p": 0.006, "windows": 16, "share": 0.0007}}
    text = trade_note({"effects": "command_lag", "worse": worse})
    assert text.startswith("command_lag takes signals left above their floor")
    assert "theta_4 to 1.16 x their RMS before" in text and "lost 0.0007 of" in text


def test_a_limit_the_rotor_test_withdrew_is_reported_as_not_named() -> None:
    """The headline for stop 62's rotor test: nothing named, the rotor that did as well and
    the p that the limit is better; the comparison sentence carries that p too."""
    from rover_env.calibration.diagnosis.rotor import rotor_text
    from rover_env.calibration.report_notes import rotor_note

    w = {"effects": ["torque_limit"], "p_torque_better": 0.42, "armature": 0.0707}
    text = rotor_note(w, None)
    assert text.startswith("**Nothing named with confidence.**")
    assert "torque_limit" in text and "`motor.armature` 0.0707 kg m²" in text and "p 0.42" in text
    alt = {
        "armature_configured": 0.025,
        "armature": 0.05,
        "beside": ["slope"],
        "rotor": {"train_gain": 0.1, "d_bic": -1.0, "held_gain": 0.2},
        "torque_limit": {"train_gain": 0.1, "d_bic": -1.0, "held_gain": 0.2},
        "p_torque_better": 0.31,
    }
    assert "slope kept as fitted" in rotor_text(alt) and "at p 0.31" in rotor_text(alt)
    assert "refitted beside" not in rotor_text(alt)
    alt["torque_limit_armature"] = 0.05
    assert "the torque limit (refitted beside the rotor inertia 0.05 kg m²" in rotor_text(alt)


def test_a_partner_named_alone_after_the_limit_s_withdrawal_is_explained() -> None:
    """Stop 63: the limit withdrawn, its partner named from its own fit; the headline says
    both, with the rotor and the p."""
    from rover_env.calibration.report_notes import rotor_kept_note

    w = {"effects": ["loose_soil", "torque_limit"], "p_torque_better": 0.57, "armature": 0.1}
    text = rotor_kept_note({**w, "kept": "loose_soil"})
    assert text.startswith("A torque limit fitted beside loose_soil was not named")
    assert "`motor.armature` 0.1 kg m²" in text and "p 0.57" in text
    assert "loose_soil is named from its own fit" in text


def test_the_headline_says_each_withdrawal_beside_what_stays_named() -> None:
    """Stop 77: a name the clean-fit allowance withdrew is reported with its fit, alone
    ("Nothing named") or beside a radius odometry named after a withdrawn torque limit,
    whose rotor note then leads with "Not named with confidence" instead."""
    from types import SimpleNamespace

    import numpy as np

    from rover_env.calibration.candidates import catalogue
    from rover_env.calibration.fit import Fit
    from rover_env.calibration.report import _headline

    (c,) = catalogue(["rolling_radius"])
    x = np.array([-0.05])
    radius = SimpleNamespace(
        fit=Fit([c], x, x - 0.01, x + 0.01, x * 0 + 0.005, 0.0, 0, c.to_ext(x), 0.0, "odometry")
    )
    allowed = {"effects": ["command_delay"], "params": {"command_delay": "delay=0.02 [0, 0.025]"}}
    base = {"unexplained": [], "above_floor": []}
    alone = "\n".join(
        _headline({**base, "named": [], "allowance_withdrawn": allowed}, [], [], None)
    )
    assert alone.startswith("**Nothing named.** Fitted and significant but not named")
    assert "command_delay delay=0.02 [0, 0.025]" in alone and 'reaches "off"' in alone
    assert "No candidate explains" not in alone
    rotor = {"effects": ["torque_limit"], "p_torque_better": 0.4, "armature": 0.05}
    both = "\n".join(
        _headline(
            {
                **base,
                "named": ["rolling_radius"],
                "rotor_withdrawn": rotor,
                "allowance_withdrawn": allowed,
            },
            [radius],  # type: ignore[list-item]
            [],
            None,
        )
    )
    assert both.startswith("**Named:** rolling_radius")
    assert "**Not named with confidence:** The best fit, torque_limit" in both
    assert "**Nothing named" not in both and "Fitted and significant but not named" in both
    none = "\n".join(_headline({**base, "named": []}, [], [], None))
    assert none.startswith("**No candidate explains the gap significantly.**")
    # A table measured otherwise is said after the verdict, which it does not change.
    differs = ["torque_forms: measured with off, here on"]
    other = "\n".join(_headline({**base, "named": [], "allowance_differs": differs}, [], [], None))
    assert other.startswith("**No candidate explains the gap significantly.**")
    assert "measured otherwise (torque_forms: measured with off, here on)" in other


def test_the_allowance_note_says_what_became_of_the_pairs_other_effect() -> None:
    """Stop 78: a pair's effect withdrawn by its allowance leaves the other named by its own
    fit ("kept") or not named ("beside"); the note says which."""
    from rover_env.calibration.report_notes import allowance_note

    w = {"effects": ["slope"], "params": {"slope": "deg=0.79 [0, 3.3]"}}
    plain = allowance_note(w, beside=False)
    assert "kept" not in plain and "fitted beside it" not in plain
    kept = allowance_note({**w, "kept": "command_lag"}, beside=True)
    assert "command_lag, fitted beside it, is named by its own fit." in kept
    assert not kept.startswith("**Nothing named.**")
    gone = allowance_note({**w, "beside": ["command_lag"]}, beside=False)
    assert "Not named either: command_lag, fitted beside it." in gone
    assert gone.startswith("**Nothing named.**")
    after = allowance_note({**w, "next": "rolling_resistance"}, beside=True)
    assert "rolling_resistance, next in the naming order, is named by its own fit." in after
    assert "next in the naming order" not in plain


def test_a_name_is_provisional_while_the_diagnosis_asks_for_a_drive() -> None:
    """Stop 130: with a drive asked for (here the balance's crossing drive and an evidence
    drive), ``result.json``'s ``provisional`` lists them and the headline says the names
    can change; with none asked, or nothing named, nothing is provisional. Block 54500's
    clean 54505 was named a friction at first and withdrawn after the crossing drive."""
    from types import SimpleNamespace

    import numpy as np

    from rover_env.calibration.candidates import catalogue
    from rover_env.calibration.diagnosis.write import pending_drives
    from rover_env.calibration.fit import Fit
    from rover_env.calibration.report import _headline

    (c,) = catalogue(["friction"])
    x = np.array([-0.277])
    s = SimpleNamespace(fit=Fit([c], x, x - 0.03, x + 0.03, x * 0 + 0.01, 0.0, 0, c.to_ext(x), 0.0, "train"))  # fmt: skip
    asks = {
        "balance": {"plan": "reversals", "seed": 0, "duration": 50.0, "why_drive": "wide"},
        "evidence": [{"plan": "steps", "seed": 1, "effect": "command_delay", "why": "w"}],
    }
    pending = pending_drives(asks)
    assert [(p["plan"], p["seed"], p["for"]) for p in pending] == [
        ("steps", 1, ["command_delay"]), ("reversals", 0, ["slope"])
    ]  # fmt: skip
    assert pending_drives({}) == []
    base = {"unexplained": [], "above_floor": [], "named": ["friction"]}
    text = "\n".join(_headline({**base, "provisional": pending}, [s], [], None))  # type: ignore[list-item]
    assert text.startswith("**Named, provisionally:** friction")
    assert "`reversals` seed 0 for slope" in text and "`steps` seed 1 for command_delay" in text
    final = "\n".join(_headline({**base, "provisional": []}, [s], [], None))  # type: ignore[list-item]
    assert final.startswith("**Named:** friction") and "can change" not in final
