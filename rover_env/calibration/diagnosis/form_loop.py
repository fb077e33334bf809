"""The speed loop's gains as model form (:attr:`.state.Options.fit_speed_loop`): the
proportional gain, then the integral gain, each on a ladder around the configuration's."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from rover_env.calibration.diagnosis.form_ladder import fit_ladder, reprepared
from rover_env.calibration.diagnosis.state import FormFit
from rover_env.calibration.replay import PreparedLog, ReplaySettings, Window
from rover_env.config import RoverConfig

LOOP_GAIN_STEPS = tuple(2.0**k for k in range(-2, 4))
"""The speed loop's gains are tried at these multiples of the configuration's (x 1/4 to x 8,
a factor 2 apart). SPEC names the motors, not their loop: a real drive's PI acts on voltage,
so the torque per rad/s it gives at the wheel also holds the motor's back-EMF damping
(k_t^2 N^2 eta / R), its gear and its current sensing, none of which the configuration's
torque-referred gains know to better than a factor 2."""


def with_speed_gain(cfg: RoverConfig, gain: float) -> RoverConfig:
    """The configuration with the speed loop's proportional gain ``gain`` (N m per rad/s)."""
    return replace(cfg, motor=replace(cfg.motor, speed_gain=gain))


def with_integral_gain(cfg: RoverConfig, gain: float) -> RoverConfig:
    """The configuration with the speed loop's integral gain ``gain`` (N m per rad)."""
    return replace(cfg, motor=replace(cfg.motor, integral_gain=gain))


def _fit_loop_gain(
    name: str,
    unit: str,
    setter: Callable[[RoverConfig, float], RoverConfig],
    nominal: float,
    cfg: RoverConfig,
    prepared: list[PreparedLog],
    windows: list[Window],
    settings: ReplaySettings,
    sensor_noise: dict[str, float],
) -> FormFit:
    """One speed-loop gain fitted on the training ``windows``, on :data:`LOOP_GAIN_STEPS`
    times ``nominal``, both ends of the search only; each value replays logs prepared again
    for it (the conditional anti-windup's saturation test reads the gains)."""
    ladder = tuple(float(nominal * k) for k in LOOP_GAIN_STEPS)
    return fit_ladder(
        name,
        unit,
        nominal,
        ladder,
        reprepared(setter, prepared, settings),
        cfg,
        prepared,
        windows,
        settings,
        sensor_noise,
        (True, True),
    )


def fit_speed_gain(
    cfg: RoverConfig,
    prepared: list[PreparedLog],
    windows: list[Window],
    settings: ReplaySettings,
    sensor_noise: dict[str, float],
) -> FormFit:
    """Fit the speed loop's proportional gain (``motor.speed_gain``) on ``windows``
    (training). Why (stop 66): the independent generator's voltage-mode PI gives about
    5.6 N m per rad/s at the wheel with its back-EMF, the configuration 2; on its clean
    case 50546 the training windows replay 9 % better at 4 (with the integral gain at 20),
    its held-out drive 24 % better at 8. On fresh cases (block 50700) a gain was adopted in
    1 of 47 diagnoses: the training windows seldom pay the BIC for it."""
    nominal = cfg.motor.speed_gain
    return _fit_loop_gain(
        "speed_gain",
        "N m s/rad",
        with_speed_gain,
        nominal,
        cfg,
        prepared,
        windows,
        settings,
        sensor_noise,
    )


def fit_integral_gain(
    cfg: RoverConfig,
    prepared: list[PreparedLog],
    windows: list[Window],
    settings: ReplaySettings,
    sensor_noise: dict[str, float],
) -> FormFit:
    """Fit the speed loop's integral gain (``motor.integral_gain``) on ``windows``
    (training), after the proportional gain."""
    nominal = cfg.motor.integral_gain
    return _fit_loop_gain(
        "integral_gain",
        "N m/rad",
        with_integral_gain,
        nominal,
        cfg,
        prepared,
        windows,
        settings,
        sensor_noise,
    )
