"""The single env's sample loop in C (``rover_env/sim/fast/env_core.c``: ``env_step_samples``).

One control step samples the rover ``samples_per_step`` times (50 Hz): physics, sensor
model, estimator push, true speed, slip and energy sums. In numpy that cost twice the
physics; here it is one C call per step. The arithmetic repeats the numpy loop's operation
by operation (the vector env runs that loop and its tests compare the two bit for bit);
sensor noise is drawn in numpy from the episode's generator in the same order as
``SensorModel.read`` draws it, so the numbers are those of the numpy loop.
"""

from __future__ import annotations

import ctypes
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rover_env.estimation.fast import FastSlipEstimator
from rover_env.estimation.sensors import SensorConfig
from rover_env.sim.batch import RoverIndex
from rover_env.sim.fast.build import load_core
from rover_env.sim.simulator import RoverSim, SimulationError

if TYPE_CHECKING:
    from rover_env.estimation.sensors import SensorModel

Array = NDArray[np.float64]
_P = ctypes.c_void_p
_I = ctypes.c_int


class StepSpec(ctypes.Structure):
    """Mirror of ``StepSpec`` in env_core.c."""

    _fields_ = [
        ("substeps", _I),
        ("samples", _I),
        ("phi_adr", _I * 6),
        ("theta_adr", _I * 5),
        ("ctrl_vel", _I * 4),
        ("driven_dof", _I * 4),
        ("seg2_body", _I),
        ("truth_vx", _I),
        ("truth_vw", _I),
        ("wheel_noisy", _I),
        ("joint_noisy", _I),
        ("wheel_res", ctypes.c_double),
        ("joint_res", ctypes.c_double),
        ("copper", ctypes.c_double),
        ("sample_dt", ctypes.c_double),
        ("v_eps", ctypes.c_double),
    ]


class FastSampleLoop:
    """``env_step_samples`` bound to one simulator, its index and sensor configuration."""

    def __init__(
        self,
        sim: RoverSim,
        index: RoverIndex,
        sensors: SensorConfig,
        substeps: int,
        samples: int,
        copper: float,
        sample_dt: float,
    ) -> None:
        pv = index.plugin
        if pv is None:
            raise ValueError("the C sample loop needs the plugin backend")
        lib = load_core()
        fn = lib.env_step_samples
        fn.restype = _I
        fn.argtypes = [_P] * 11
        self._fn = fn
        nw = pv.layout.nw
        truth = pv.slice.start + pv.layout.truth
        s = self.spec = StepSpec()
        s.substeps, s.samples = int(substeps), int(samples)
        s.phi_adr[:] = [int(i) for i in index.phi]
        s.theta_adr[:] = [int(i) for i in index.theta]
        s.ctrl_vel[:] = [int(i) for i in sim._ctrl_vel]
        s.driven_dof[:] = [int(i) for i in index.driven_dof]
        s.seg2_body = int(index.seg_body[1])
        s.truth_vx, s.truth_vw = truth, truth + 2 * nw
        s.wheel_noisy, s.joint_noisy = int(sensors.wheel_noise > 0), int(sensors.joint_noise > 0)
        s.wheel_res, s.joint_res = sensors.wheel_resolution, sensors.joint_resolution
        s.copper, s.sample_dt, s.v_eps = float(copper), float(sample_dt), float(index.v_eps)
        self._spec_ptr = ctypes.addressof(s)
        self.sensors = sensors
        self.samples = int(samples)
        self.noise = np.zeros((self.samples, 11))
        self.theta = np.zeros(5)
        self.sums = np.zeros(13)
        self._flag = ctypes.c_int(1)
        self._flag_ptr = ctypes.addressof(self._flag)

    def draw_noise(self, model: SensorModel) -> None:
        """This step's sensor noise, in ``SensorModel.read``'s order (wheels, joints per sample)."""
        c, rng = self.sensors, model.rng
        k = self.samples
        if c.wheel_noise > 0 and c.joint_noise > 0:
            z = rng.standard_normal((k, 11))
            self.noise[:, :6] = 0.0 + c.wheel_noise * z[:, :6]
            self.noise[:, 6:] = 0.0 + c.joint_noise * z[:, 6:]
        elif c.wheel_noise > 0:
            self.noise[:, :6] = rng.normal(0.0, c.wheel_noise, (k, 6))
        elif c.joint_noise > 0:
            self.noise[:, 6:] = rng.normal(0.0, c.joint_noise, (k, 5))

    def run(
        self,
        sim: RoverSim,
        est: FastSlipEstimator,
        targets: Array,
        phi0: Array,
        command: Array,
    ) -> None:
        """One control step; results in :attr:`sums` and :attr:`theta`."""
        err = self._fn(
            sim.model._address,
            sim.data._address,
            self._spec_ptr,
            est.handle,
            targets.ctypes.data,
            self.noise.ctypes.data,
            phi0.ctypes.data,
            self._flag_ptr,
            command.ctypes.data,
            self.theta.ctypes.data,
            self.sums.ctypes.data,
        )
        if err == 0:
            return
        if err in (1, 2):
            sim._check()  # raises with the warning's name
            raise SimulationError(f"non-finite state at t={sim.data.time:.3f}s")
        raise ValueError(f"slip estimator refused a sample at t={sim.data.time!r} (code {err})")
