"""Four geared DC motors with a discrete PI speed loop each (SPEC names the motors, not their
numbers; all numbers are this module's choices).

- Motor: armature resistance 2 ohm, torque constant k_t = back-EMF constant 0.02 (N m/A, V s/rad),
  gear 100:1 with 70 % efficiency, rotor 5e-6 kg m^2 (0.05 kg m^2 reflected to the wheel), 12 V
  supply, a current-limiting driver at 2 A (about 2.8 N m at the wheel, three times the 0.9 N m of
  traction a wheel has on the paper's tire). Inductance neglected (quasi-static current, updated
  every physics step so the back-EMF damping is continuous). Gearbox drag 0.02 N m (Coulomb,
  smoothed over 0.05 rad/s) at the wheel.
- Speed measurement: a 256-line quadrature encoder on each motor shaft (1024 counts per motor turn,
  102 400 per wheel turn), differenced every control period and low-passed at 40 Hz.
- Speed loop at 250 Hz (every other 2 ms physics step), PI on the speed error to a voltage command
  clipped to +-12 V; anti-windup by back-calculation (the integrator is bled by the clipped excess
  at rate 1/T_t, T_t = 0.05 s), a choice distinct from a plain clamp or conditional integration.
- The motor torque limit effect scales the driver's current limit; the battery sag effect the
  supply voltage the drivers clip at (the controller's feed-forward still assumes nothing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

R_ARM = 2.0
GEAR = 100.0
EFF = 0.7
ROTOR = 5e-6
V_MAX = 12.0
I_MAX = 2.0
DRAG = 0.02
DRAG_W = 0.05
MOTOR_CPR = 1024
CONTROL_HZ = 250.0
SPEED_LP_HZ = 40.0
T_TRACK = 0.05
K_T_DATASHEET = 0.02


def reflected_inertia() -> float:
    return ROTOR * GEAR * GEAR


@dataclass
class Drives:
    """State of the four speed loops."""

    k_t: Array
    kp: Array
    ki: Array
    current_limit: Array
    v_max: float = V_MAX
    integ: Array = field(default_factory=lambda: np.zeros(4))
    voltage: Array = field(default_factory=lambda: np.zeros(4))
    speed_est: Array = field(default_factory=lambda: np.zeros(4))
    last_count: Array = field(default_factory=lambda: np.zeros(4))

    @classmethod
    def make(
        cls,
        k_t: list[float],
        kp: list[float],
        ki: list[float],
        limit_scale: float,
        supply_scale: float = 1.0,
    ) -> Drives:
        return cls(
            k_t=np.array(k_t, dtype=float),
            kp=np.array(kp, dtype=float),
            ki=np.array(ki, dtype=float),
            current_limit=np.full(4, I_MAX * limit_scale),
            v_max=V_MAX * supply_scale,
        )

    def reset_counts(self, wheel_angle: Array) -> None:
        self.last_count = np.floor(wheel_angle * GEAR * MOTOR_CPR / (2 * math.pi))

    def control(self, target: Array, wheel_angle: Array, dt: float) -> None:
        """One speed-loop period: measure, then update the voltage command."""
        count = np.floor(wheel_angle * GEAR * MOTOR_CPR / (2 * math.pi))
        raw = (count - self.last_count) * (2 * math.pi / (GEAR * MOTOR_CPR)) / dt
        self.last_count = count
        a = 1.0 - math.exp(-2 * math.pi * SPEED_LP_HZ * dt)
        self.speed_est = self.speed_est + a * (raw - self.speed_est)
        err = target - self.speed_est
        v_ff = target * K_T_DATASHEET * GEAR  # back-EMF feed-forward (datasheet constant)
        unclipped = v_ff + self.kp * err + self.integ
        self.voltage = np.clip(unclipped, -self.v_max, self.v_max)
        self.integ = self.integ + dt * (self.ki * err + (self.voltage - unclipped) / T_TRACK)

    def current(self, omega: Array) -> Array:
        """Armature current (A) for the held voltage and the wheel speed ``omega`` (rad/s)."""
        current = (self.voltage - self.k_t * GEAR * omega) / R_ARM
        return np.clip(current, -self.current_limit, self.current_limit)

    def wheel_torque(self, omega: Array) -> Array:
        """Torque at the wheel for the held voltage and the wheel speed ``omega`` (rad/s)."""
        current = self.current(omega)
        return EFF * GEAR * self.k_t * current - DRAG * np.tanh(omega / DRAG_W)
