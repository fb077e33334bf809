"""What the logger records (SPEC §6 columns), with this generator's own sensor forms.

- Wheel angles: an incremental encoder on each wheel shaft, ``cpr`` counts per turn (the
  nuisance draw picks the part), counted from the start of the log; the logged angle is
  ``count * 2 pi / cpr``; the shaft's position between two edges at zeroing is random per drive.
- Joint angles: potentiometers read by a 12-bit ADC over a 340 degree electrical span, each with
  its own gain error (nuisance), a fixed offset of up to +-0.2 degrees after a zeroing
  calibration, and white noise 0.05 degrees RMS; the quantisation is applied after the noise.
- Motor effort (only when asked): each driver's current sense, 10 mA RMS noise and a 12-bit ADC
  over +-5 A, reported as the torque at the wheel its datasheet constants give
  (``current x k_t x gear x efficiency``, the datasheet's k_t, not the motor's own).
- Pose: an external reference fix of segment 3's centre once a second (x, y with 5 mm RMS noise,
  yaw with 0.3 degrees RMS), in segment 3's frame at t = 0; empty between fixes.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

POT_SPAN = math.radians(340.0)
POT_BITS = 12
POT_NOISE = math.radians(0.05)
POT_OFFSET = math.radians(0.2)
POSE_XY_NOISE = 0.005
POSE_YAW_NOISE = math.radians(0.3)
POSE_RATE_HZ = 1.0
CURRENT_NOISE = 0.010
CURRENT_SPAN = 10.0
CURRENT_BITS = 12


def encoder_angles(phi: Array, cpr: int, phase: Array) -> Array:
    """(N, 6) true wheel angles since the start -> logged angles.

    ``phase`` (6,) in [0, 1): where the shaft sat between two edges when the counter was zeroed.
    """
    counts = np.floor(phi * cpr / (2 * math.pi) + phase[None, :]) - np.floor(phase)[None, :]
    return counts * (2 * math.pi / cpr)


def potentiometers(theta: Array, gain: Array, offset: Array, rng: np.random.Generator) -> Array:
    """(N, 5) true joint angles -> logged angles."""
    lsb = POT_SPAN / 2**POT_BITS
    raw = theta * gain[None, :] + offset[None, :] + rng.normal(0.0, POT_NOISE, theta.shape)
    return np.round(raw / lsb) * lsb


def pose_fixes(t: Array, pose: Array, rng: np.random.Generator) -> Array:
    """(N, 3) true pose -> fixes at whole seconds (first sample at or after each), NaN elsewhere."""
    out = np.full_like(pose, np.nan)
    period = 1.0 / POSE_RATE_HZ
    k = np.flatnonzero(np.diff(np.floor(t / period + 1e-9), prepend=-1.0) > 0)
    noise = np.column_stack(
        [
            rng.normal(0.0, POSE_XY_NOISE, (k.size, 2)),
            rng.normal(0.0, POSE_YAW_NOISE, k.size),
        ]
    )
    out[k] = pose[k] + noise
    return out


def effort(current: Array, torque_per_amp: float, rng: np.random.Generator) -> Array:
    """(N, 4) true armature currents (A) -> the drivers' reported wheel torque (N m)."""
    lsb = CURRENT_SPAN / 2**CURRENT_BITS
    sensed = np.round((current + rng.normal(0.0, CURRENT_NOISE, current.shape)) / lsb) * lsb
    return sensed * torque_per_amp
