"""The wheel-referred motor block from a drive's datasheet (rover_env.drive_datasheet)."""

from __future__ import annotations

import dataclasses

import pytest
import yaml

import rover_env.independent.motor as gen
from rover_env.config import ConfigError
from rover_env.drive_datasheet import VoltageDrive


def generator_drive() -> VoltageDrive:
    """The independent generator's nominal drive, from its own module's constants."""
    return VoltageDrive(
        supply=gen.V_MAX,
        resistance=gen.R_ARM,
        torque_constant=gen.K_T_DATASHEET,
        gear=gen.GEAR,
        efficiency=gen.EFF,
        rotor_inertia=gen.ROTOR,
        current_limit=gen.I_MAX,
        kp=6.0,  # its drives' nominal gains (V per rad/s, V per rad)
        ki=30.0,
        tracking_time=gen.T_TRACK,
    )


def test_the_generators_drive_at_the_wheel() -> None:
    f = generator_drive().motor_fields()
    # 0.7 N m per volt: 8.4 N m at 12 V stall, 6 rad/s at no load, 2 A -> 2.8 N m, a
    # 5e-6 rotor through 100:1 -> 0.05 kg m^2, gains 0.7 x (2 + 6) and 0.7 x 30.
    assert f["stall_torque"] == pytest.approx(8.4)
    assert f["no_load_speed"] == pytest.approx(6.0)
    assert f["torque_limit"] == pytest.approx(2.8)
    assert f["armature"] == pytest.approx(gen.reflected_inertia())
    assert f["speed_gain"] == pytest.approx(5.6)
    assert f["integral_gain"] == pytest.approx(21.0)
    assert f["anti_windup"] == "back_calculation"
    # The model's tracking time is tracking_ratio x speed_gain / integral_gain: 0.05 s.
    assert f["tracking_ratio"] * f["speed_gain"] / f["integral_gain"] == pytest.approx(0.05)


def test_the_generators_torque_at_the_wheel_matches_its_motor() -> None:
    """The voltage line and the current limit against the generator's own torque law."""
    import numpy as np

    drive = generator_drive()
    m = drive.motor()
    d = gen.Drives.make([gen.K_T_DATASHEET] * 4, [6.0] * 4, [30.0] * 4, 1.0)
    omega = np.array([0.0, 1.0, 3.0, 5.0])
    d.voltage = np.full(4, gen.V_MAX)
    want = d.wheel_torque(omega) + gen.DRAG * np.tanh(omega / gen.DRAG_W)
    line = m.stall_torque * (1 - omega / m.no_load_speed)
    assert np.minimum(line, m.torque_limit) == pytest.approx(want)


def test_the_block_reads_back_as_a_motor() -> None:
    drive = generator_drive()
    block = yaml.safe_load(drive.motor_yaml())
    m = drive.motor()
    assert block["anti_windup"] == m.anti_windup
    for k in ("stall_torque", "no_load_speed", "torque_limit", "speed_gain", "integral_gain"):
        assert block[k] == pytest.approx(getattr(m, k), rel=1e-5)


def test_bad_numbers_are_refused_by_name() -> None:
    with pytest.raises(ConfigError, match="resistance"):
        dataclasses.replace(generator_drive(), resistance=0.0)
    with pytest.raises(ConfigError, match="efficiency"):
        dataclasses.replace(generator_drive(), efficiency=1.3)
    # A top speed beyond what the supply gives is refused by the configuration's own check.
    with pytest.raises(ConfigError, match="max_wheel_speed"):
        dataclasses.replace(generator_drive(), supply=6.0).motor()
