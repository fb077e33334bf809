"""The compiled sample loop (``rover_env/sim/fast/env_core.c``) bound to the envs.

One control step samples the rover ``samples_per_step`` times (50 Hz): physics, sensor
model, estimator push, true speed, slip and energy sums (:class:`rover_env.sim.sample.StepSample`).
In numpy (:func:`rover_env.sim.sample.run_samples`) that cost twice the physics. In C one
function, ``vec_sample``, is a sample of any rows; :class:`FastSampleLoop` runs a whole step
of the single env in one call (``env_step_samples``: physics, then ``vec_sample`` on the
MjData as one row), :class:`FastBatchSampler` one sample of the vector env's batch rows.
The arithmetic repeats the numpy loop's operation by operation (tests compare the two bit for
bit); sensor noise is drawn in numpy from the episode's generator in the same order as
``SensorModel.read`` draws it, so the numbers are those of the numpy loop.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rover_env.estimation.fast import FastSlipEstimator
from rover_env.estimation.sensors import SensorConfig
from rover_env.sim.batch import BatchRoverSim
from rover_env.sim.fast.build import load_core
from rover_env.sim.readers import RoverIndex
from rover_env.sim.simulator import RoverSim, SimulationError

if TYPE_CHECKING:
    from rover_env.estimation.sensors import SensorModel

Array = NDArray[np.float64]
_P = ctypes.c_void_p
_I = ctypes.c_int
_BATCH_FIELDS = (
    "sensordata",
    "plugin_state",
    "cvel",
    "xipos",
    "ximat",
    "subtree_com",
    "force",
    "qvel",
    "time",
)


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


class BatchView(ctypes.Structure):
    """Mirror of ``BatchView`` in env_core.c: row-strided views of mujoco.batch's arrays."""

    _fields_ = [
        *((name, _P) for name in _BATCH_FIELDS),
        *((f"s_{name}", ctypes.c_longlong) for name in _BATCH_FIELDS),
        ("seg2_root", _I),
    ]


def _spec(
    index: RoverIndex,
    sensors: SensorConfig,
    substeps: int,
    samples: int,
    copper: float,
    sample_dt: float,
    ctrl_vel: NDArray[np.intp] | None = None,
) -> StepSpec:
    pv = index.plugin
    if pv is None:
        raise ValueError("the C sample loop needs the plugin backend")
    truth = pv.slice.start + pv.layout.truth
    s = StepSpec()
    s.substeps, s.samples = int(substeps), int(samples)
    s.phi_adr[:] = [int(i) for i in index.phi]
    s.theta_adr[:] = [int(i) for i in index.theta]
    if ctrl_vel is not None:
        s.ctrl_vel[:] = [int(i) for i in ctrl_vel]
    s.driven_dof[:] = [int(i) for i in index.driven_dof]
    s.seg2_body = int(index.seg_body[1])
    s.truth_vx, s.truth_vw = truth, truth + 2 * pv.layout.nw
    s.wheel_noisy, s.joint_noisy = int(sensors.wheel_noise > 0), int(sensors.joint_noise > 0)
    s.wheel_res, s.joint_res = sensors.wheel_resolution, sensors.joint_resolution
    s.copper, s.sample_dt, s.v_eps = float(copper), float(sample_dt), float(index.v_eps)
    return s


def draw_sensor_noise(c: SensorConfig, rng: np.random.Generator, out: Array) -> None:
    """Noise of ``out.shape[0]`` samples into ``out`` (samples, 11), in ``SensorModel.read``'s
    order (per sample: wheels, then joints), so the numbers equal its own draws."""
    k = out.shape[0]
    if c.wheel_noise > 0 and c.joint_noise > 0:
        z = rng.standard_normal((k, 11))
        out[:, :6] = 0.0 + c.wheel_noise * z[:, :6]
        out[:, 6:] = 0.0 + c.joint_noise * z[:, 6:]
    elif c.wheel_noise > 0:
        out[:, :6] = rng.normal(0.0, c.wheel_noise, (k, 6))
    elif c.joint_noise > 0:
        out[:, 6:] = rng.normal(0.0, c.joint_noise, (k, 5))


class _CoreCall:
    """One function of the env core with the rover's ``StepSpec`` it is called with."""

    def __init__(
        self,
        fn_name: str,
        argtypes: Sequence[type],
        index: RoverIndex,
        sensors: SensorConfig,
        timing: tuple[int, int, float, float],
        ctrl_vel: NDArray[np.intp] | None = None,
    ) -> None:
        """``timing``: substeps per sample, samples per step, copper loss R/K^2, sample dt."""
        fn = getattr(load_core(), fn_name)
        fn.restype = _I
        fn.argtypes = list(argtypes)
        self._fn = fn
        self.spec = _spec(index, sensors, *timing, ctrl_vel)
        self._spec_ptr = ctypes.addressof(self.spec)
        self.sensors = sensors
        self.samples = int(timing[1])


class FastSampleLoop(_CoreCall):
    """``env_step_samples`` bound to one simulator, its index and sensor configuration."""

    def __init__(
        self,
        sim: RoverSim,
        index: RoverIndex,
        sensors: SensorConfig,
        timing: tuple[int, int, float, float],
    ) -> None:
        super().__init__("env_step_samples", [_P] * 10, index, sensors, timing, sim.index.ctrl_vel)
        self.noise = np.zeros((self.samples, 11))
        self.theta = np.zeros(5)
        self.sums = np.zeros(13)

    def draw_noise(self, model: SensorModel) -> None:
        """This step's sensor noise, in ``SensorModel.read``'s order (wheels, joints per sample)."""
        draw_sensor_noise(self.sensors, model.rng, self.noise)

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
            command.ctypes.data,
            self.theta.ctypes.data,
            self.sums.ctypes.data,
        )
        if err == 0:
            return
        if err in (1, 2):
            sim.check()  # raises with the warning's name
            raise SimulationError(f"non-finite state at t={sim.data.time:.3f}s")
        raise ValueError(f"slip estimator refused a sample at t={sim.data.time!r} (code {err})")


class FastBatchSampler(_CoreCall):
    """``vec_sample`` for the vector env: one 50 Hz sample of the listed batch rows in C."""

    def __init__(
        self,
        batch: BatchRoverSim,
        index: RoverIndex,
        sensors: SensorConfig,
        timing: tuple[int, int, float, float],
    ) -> None:
        argtypes = [_P, _P, _P, _I, _P, _I, _P, _P, _P, _P, _P]
        super().__init__("vec_sample", argtypes, index, sensors, timing)
        self.batch = batch
        self._seg2_root = int(index.seg_root[1])

    def _view(self) -> BatchView:
        b = self.batch
        arrays = {
            "sensordata": b.sensordata,
            "plugin_state": b.plugin_state,
            "cvel": b.field("cvel"),
            "xipos": b.field("xipos"),
            "ximat": b.field("ximat"),
            "subtree_com": b.field("subtree_com"),
            "force": b.field("actuator_force"),
            "qvel": b.qvel,
            "time": b.time_view,
        }
        v = BatchView()
        for name, a in arrays.items():
            inner = a.strides[1:]
            want = tuple(8 * int(np.prod(a.shape[i + 1 :])) for i in range(1, a.ndim))
            if a.dtype != np.float64 or a.strides[0] % 8 or tuple(inner) != want:
                raise ValueError(f"batch field {name}: rows must hold contiguous float64")
            setattr(v, name, a.ctypes.data)
            setattr(v, f"s_{name}", a.strides[0] // 8)
        v.seg2_root = self._seg2_root
        return v

    def begin(
        self, rows: NDArray[np.intp], models: list[SensorModel], command: Array
    ) -> tuple[BatchView, NDArray[np.int32], Array, Array, Array, Array, Array]:
        """Buffers of one control step of rovers ``rows`` (their sensor models, commands)."""
        k = rows.size
        noise = np.zeros((k, self.samples, 11))
        phi0 = np.empty((k, 6))
        for j, m in enumerate(models):
            draw_sensor_noise(self.sensors, m.rng, noise[j])
            z = m.counter_zero
            if z is None:
                raise RuntimeError("step() before the rover's first reading")
            phi0[j] = z
        cmd = np.ascontiguousarray(command, dtype=np.float64)
        return (
            self._view(),
            np.ascontiguousarray(rows, dtype=np.int32),
            noise,
            phi0,
            cmd,
            np.zeros((k, 5)),
            np.zeros((k, 13)),
        )

    def sample(
        self,
        smp: int,
        est: FastSlipEstimator,
        bufs: tuple[BatchView, NDArray[np.int32], Array, Array, Array, Array, Array],
    ) -> None:
        """Sample ``smp`` of the step whose buffers are ``bufs`` (after the batch stepped)."""
        view, rows, noise, phi0, cmd, theta, sums = bufs
        err = self._fn(
            self._spec_ptr,
            ctypes.addressof(view),
            est.handle,
            rows.size,
            rows.ctypes.data,
            smp,
            noise.ctypes.data,
            phi0.ctypes.data,
            cmd.ctypes.data,
            theta.ctypes.data,
            sums.ctypes.data,
        )
        if err:
            raise ValueError(f"slip estimator refused a sample (code {err})")
