"""The report's note beside a named torque limit: on flat drives the limit is measured
through the wheel's acceleration, so it is only as good as the configured rotor inertia."""

from __future__ import annotations

from rover_env.calibration.report import _torque_note


def test_a_named_torque_limit_names_the_rotor_inertia_it_rests_on() -> None:
    text = " ".join(_torque_note(["torque_limit"], 0.025))
    assert "motor.armature" in text and "0.025 kg m²" in text and "blocked wheel" in text


def test_no_note_without_a_torque_limit() -> None:
    assert _torque_note(["rolling_resistance", "slope"], 0.025) == []
