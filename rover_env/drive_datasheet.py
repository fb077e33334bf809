"""A rover's drive from its datasheet: the wheel-referred ``motor`` block of a rover
configuration (:class:`rover_env.config.MotorSpec`) for a geared DC motor whose speed PI
sets its voltage (a PWM bridge with back-EMF feed-forward) behind a current-limiting driver.

Why: SPEC names the motors, not their numbers, and the configuration's drive is referred
to the wheel, where a datasheet's motor is not. The conversion is easy to get wrong (the
back-EMF adds to the proportional gain; the tracking time is a ratio of the wheel-referred
integral time), and what it gets wrong reads as an effect: on the independent generator's
clean logs the torque limit fitted alone is a cut of about -0.6 under the configuration's
drive and about 0 under that generator's own drive written this way (docs/calibration/limits.md,
stop 91).

    from rover_env.drive_datasheet import VoltageDrive
    drive = VoltageDrive(supply=12, resistance=2, torque_constant=0.02, gear=100,
                         efficiency=0.7, rotor_inertia=5e-6, current_limit=2,
                         kp=6, ki=30, tracking_time=0.05)
    print(drive.motor_yaml())   # paste under ``motor:`` in your rover's YAML
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from rover_env.config import ConfigError, MotorSpec


@dataclass(frozen=True)
class VoltageDrive:
    """The numbers of a motor's datasheet and its drive's firmware, in SI units at the motor
    unless said otherwise. The speed loop is a PI on the wheel's speed error (rad/s at the
    wheel, as the drive's encoder and gear give it) to a voltage, with the target's back-EMF
    added (feed-forward), clipped at the supply; the driver clips the current after it, out
    of the loop's sight; the integral is bled by back-calculation."""

    supply: float
    """Supply voltage the bridge clips at (V)."""
    resistance: float
    """Armature resistance (ohm)."""
    torque_constant: float
    """k_t (N m/A), equal to the back-EMF constant (V s/rad)."""
    gear: float
    """Gear ratio, motor turns per wheel turn."""
    efficiency: float
    """Gearbox efficiency (0-1]."""
    rotor_inertia: float
    """Rotor inertia at the motor (kg m^2)."""
    current_limit: float
    """The driver's current limit (A)."""
    kp: float
    """Proportional gain: volts per rad/s of wheel-speed error."""
    ki: float
    """Integral gain: volts per rad of accumulated wheel-angle error."""
    tracking_time: float
    """Back-calculation's tracking time T_t (s): the integral is bled by the clipped excess
    at rate 1 / T_t."""

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(
                    f"drive datasheet: {f.name} must be a finite number > 0, got {v!r}"
                )
        if self.efficiency > 1:
            raise ConfigError(f"drive datasheet: efficiency must be <= 1, got {self.efficiency!r}")

    @property
    def torque_per_volt(self) -> float:
        """Wheel torque per volt across the armature at standstill (N m/V)."""
        return self.efficiency * self.gear * self.torque_constant / self.resistance

    def motor_fields(self) -> dict[str, float | str]:
        """The :class:`~rover_env.config.MotorSpec` fields this drive sets (the rest, such as
        ``max_wheel_speed`` and ``max_angle_error``, stay the configuration's). At the wheel:
        the voltage line's stall torque and no-load speed, the driver's current limit, the
        rotor reflected through the gear (N^2 J), the loop's gains times the torque per volt
        (the proportional gain with the back-EMF's k_t N, which the feed-forward turns into
        damping of the speed error), and the tracking time over the integral time."""
        c = self.torque_per_volt
        speed_gain = c * (self.torque_constant * self.gear + self.kp)
        integral_gain = c * self.ki
        return {
            "voltage": self.supply,
            "stall_torque": c * self.supply,
            "no_load_speed": self.supply / (self.torque_constant * self.gear),
            "torque_limit": self.efficiency * self.gear * self.torque_constant * self.current_limit,
            "armature": self.rotor_inertia * self.gear**2,
            "speed_gain": speed_gain,
            "integral_gain": integral_gain,
            "anti_windup": "back_calculation",
            "tracking_ratio": self.tracking_time / (speed_gain / integral_gain),
        }

    def motor(self, base: MotorSpec | None = None) -> MotorSpec:
        """``base`` (default: the shipped one) with this drive's fields; checked as any
        configuration is (a ``max_wheel_speed`` beyond the no-load speed is refused)."""
        import dataclasses

        return dataclasses.replace(base or MotorSpec(), **self.motor_fields())  # type: ignore[arg-type]

    def motor_yaml(self) -> str:
        """The fields as lines of a rover YAML's ``motor:`` block."""
        out = []
        for k, v in self.motor_fields().items():
            out.append(f"  {k}: {v}" if isinstance(v, str) else f"  {k}: {v:.6g}")
        return "\n".join(out)
