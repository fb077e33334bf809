"""A control step's 50 Hz samples: what they measured (:class:`StepSample`) and the numpy loop.

An env's control step runs the physics in ``samples`` slices; after each slice the rover's
electronics read the encoders and potentiometers (fed to the slip estimator) and the step
sums what the reward needs: squared tracking errors, the motors' electrical energy and the
driven wheels' true |S|. :func:`run_samples` is that loop in numpy, for one simulator or
rows of a batch alike (:class:`SimRows`, :class:`BatchRows`); ``env_core.c``'s
``vec_sample`` is the same loop compiled (same bits). Both fill a :class:`StepSample`.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rover_env.sim.batch import BatchRoverSim
from rover_env.sim.readers import RoverIndex
from rover_env.sim.simulator import RoverSim
from rover_env.terrain import Terrain

Array = NDArray[np.float64]

__all__ = [
    "BatchRows",
    "SimRows",
    "StepSample",
    "run_samples",
    "wheel_friction",
]

NSUMS = 13
"""Numbers per rover of a step's sums (:meth:`StepSample.of_rows`, ``add_sample`` in C)."""


@dataclasses.dataclass
class StepSample:
    """What one control step measured for ``n`` rovers (one row each).

    Sums over the step's samples: ``err_v2``, ``err_w2`` (squared speed and yaw-rate
    tracking errors), ``energy`` (J), ``slip_abs`` (sum of each driven wheel's |S|). The last
    sample's ``speed``, ``yaw_rate`` (middle segment, its own axes) and ``slip`` (driven
    wheels' true S), and ``theta`` the joint angles as last measured. After the step
    (:meth:`SimRows.finish`, :meth:`BatchRows.finish`): the middle segment's ``position``
    (and ``position0`` before it), ``time``, ``flipped``, each wheel's normal force
    ``wheel_F_z``, sinkage ``wheel_sinkage`` and ground friction ``wheel_mu`` (mu_x, mu_y).
    """

    err_v2: Array
    err_w2: Array
    energy: Array
    slip_abs: Array
    speed: Array
    yaw_rate: Array
    slip: Array
    theta: Array
    position0: Array
    position: Array = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    time: Array = dataclasses.field(default_factory=lambda: np.zeros(0))
    flipped: NDArray[np.bool_] = dataclasses.field(default_factory=lambda: np.zeros(0, bool))
    wheel_F_z: Array = dataclasses.field(default_factory=lambda: np.zeros((0, 6)))
    wheel_sinkage: Array = dataclasses.field(default_factory=lambda: np.zeros((0, 6)))
    wheel_mu: Array = dataclasses.field(default_factory=lambda: np.zeros((0, 6, 2)))

    @classmethod
    def zeros(cls, position0: Array) -> StepSample:
        """Empty sums for the rovers starting the step at ``position0`` (n, 3)."""
        n = position0.shape[0]
        return cls(
            err_v2=np.zeros(n),
            err_w2=np.zeros(n),
            energy=np.zeros(n),
            slip_abs=np.zeros((n, 4)),
            speed=np.zeros(n),
            yaw_rate=np.zeros(n),
            slip=np.zeros((n, 4)),
            theta=np.zeros((n, 5)),
            position0=position0,
        )

    @classmethod
    def of_rows(cls, rows: Array, theta: Array, position0: Array) -> StepSample:
        """Views of the compiled loop's ``rows`` (n, 13): err_v2, err_w2, energy, |S| sums x 4,
        then the last sample's speed, yaw rate and slip x 4; ``theta`` (n, 5)."""
        return cls(
            err_v2=rows[:, 0],
            err_w2=rows[:, 1],
            energy=rows[:, 2],
            slip_abs=rows[:, 3:7],
            speed=rows[:, 7],
            yaw_rate=rows[:, 8],
            slip=rows[:, 9:13],
            theta=theta,
            position0=position0,
        )

    def add(
        self,
        command: Array,
        speed: Array,
        yaw_rate: Array,
        tau: Array,
        omega: Array,
        slip: Array,
        copper: float,
        h: float,
    ) -> None:
        """One sample: commands (n, 2), true speed and yaw rate (n,), motor torque and speed
        (n, 4), true slip of the driven wheels (n, 4); ``copper`` the motors' R/K^2, h the
        time the sample stands for."""
        dv = command[:, 0] - speed
        dw = command[:, 1] - yaw_rate
        # Scalar powers, as the single env has always squared (libm pow, not x * x).
        for i in range(dv.shape[0]):
            self.err_v2[i] += dv[i] ** 2
            self.err_w2[i] += dw[i] ** 2
        power = np.sum(np.maximum(tau * omega + copper * tau**2, 0.0), axis=-1)
        self.energy += power * h
        self.slip_abs += np.abs(slip)
        self.speed, self.yaw_rate, self.slip = speed, yaw_rate, slip


class Sensors(Protocol):
    """The rover's electronics on one sample (``rover_env.estimation.sensors.SensorModel``)."""

    def read(self, phi: Array, theta: Array) -> tuple[Array, Array]: ...


class Estimator(Protocol):
    """A slip estimator fed one sample per listed rover (``BatchSlipEstimator`` and kin)."""

    def push(self, ids: Any, t: ArrayLike, phi: ArrayLike, theta: ArrayLike) -> None: ...


class SimRows:
    """One :class:`RoverSim` read as a batch of one row (either backend)."""

    def __init__(self, sim: RoverSim, index: RoverIndex) -> None:
        self.sim, self.index = sim, index

    def position(self) -> Array:
        return self.sim.data.xpos[self.index.seg_body[1]][None].copy()

    def advance(self, substeps: int) -> None:
        self.sim.step(substeps)

    def time(self) -> Array:
        return np.array([self.sim.data.time])

    def phi_theta(self) -> tuple[Array, Array]:
        phi, theta = self.index.phi_theta(self.sim.data.sensordata)
        return phi[None], theta[None]

    def segment_velocity(self) -> tuple[Array, Array]:
        """:meth:`RoverIndex.segment_velocity` (``mj_objectVelocity``'s arithmetic)."""
        d = self.sim.data
        return self.index.segment_velocity(
            d.cvel[None], d.xipos[None], d.ximat[None], d.subtree_com[None]
        )

    def driven_slip(self) -> Array:
        if self.index.plugin is not None:
            return self.index.driven_slip(self.sim.data.plugin_state)[None]
        return self.sim.wheel_truth().S[None, :4]

    def motor(self) -> tuple[Array, Array]:
        """Torque and speed of the driven wheels' motors (1, 4)."""
        d = self.sim.data
        return d.actuator_force[None, :4], d.qvel[None, self.index.driven_dof]

    def finish(self, out: StepSample) -> None:
        """The after-step fields of ``out``."""
        sim = self.sim
        out.position = self.position()
        out.time = np.array([sim.time])
        out.flipped = np.array([sim.flipped()])
        if self.index.plugin is not None:
            state = sim.data.plugin_state[None]
            out.wheel_F_z, contact = self.index.wheel_load(state)
            out.wheel_sinkage = self.index.wheel_sinkage(state)
        else:
            wt = sim.wheel_truth()
            out.wheel_F_z, contact = wt.F_z[None].copy(), wt.contact_point[None]
            out.wheel_sinkage = wt.sinkage[None].copy()
        out.wheel_mu = wheel_friction(sim.terrain, contact)


class BatchRows:
    """Rows ``active`` of a :class:`BatchRoverSim` (its derived fields bound: ``xpos``,
    ``xmat``, ``cvel``, ``xipos``, ``ximat``, ``subtree_com``, ``actuator_force``)."""

    def __init__(
        self, batch: BatchRoverSim, index: RoverIndex, active: NDArray[np.intp], every: bool
    ) -> None:
        self.batch, self.index, self.active = batch, index, active
        self.ids = None if every else active
        """What ``batch.step`` and the estimator take: None for all rows."""

    def position(self) -> Array:
        return self.batch.field("xpos")[self.active][:, self.index.seg_body[1]]

    def advance(self, substeps: int) -> None:
        self.batch.step(substeps, ids=self.ids)

    def time(self) -> Array:
        return self.batch.time_view[self.active]

    def phi_theta(self) -> tuple[Array, Array]:
        return self.index.phi_theta(self.batch.sensordata[self.active])

    def segment_velocity(self) -> tuple[Array, Array]:
        """:meth:`RoverIndex.segment_velocity` (``mj_objectVelocity``'s arithmetic)."""
        b, a = self.batch, self.active
        return self.index.segment_velocity(
            b.field("cvel")[a], b.field("xipos")[a], b.field("ximat")[a], b.field("subtree_com")[a]
        )

    def driven_slip(self) -> Array:
        return self.index.driven_slip(self.batch.plugin_state[self.active])

    def motor(self) -> tuple[Array, Array]:
        b, a, ix = self.batch, self.active, self.index
        return b.field("actuator_force")[a, : ix.n_driven], b.qvel[a][:, ix.driven_dof]

    def finish(self, out: StepSample, terrains: list[Terrain]) -> None:
        """The after-step fields of ``out``; ``terrains``: each active row's ground."""
        b, a, ix = self.batch, self.active, self.index
        out.position = self.position()
        out.time = b.time_view[a]
        out.flipped = ix.flipped(b.field("xmat")[a])
        state = b.plugin_state[a]
        out.wheel_F_z, contact = ix.wheel_load(state)
        out.wheel_sinkage = ix.wheel_sinkage(state)
        out.wheel_mu = np.stack(
            [wheel_friction(t, c) for t, c in zip(terrains, contact, strict=True)]
        )


def run_samples(
    rows: SimRows | BatchRows,
    position0: Array,
    samples: int,
    substeps: int,
    command: Array,
    sensors: list[Sensors],
    est: Estimator,
    ids: Any,
    copper: float,
    h: float,
) -> StepSample:
    """One control step of ``rows``: ``samples`` times ``substeps`` physics substeps, each
    followed by a sensor reading (``sensors[j].read`` per row) pushed into ``est`` (rows
    ``ids``) and the sums (:meth:`StepSample.add`). ``command`` (n, 2); ``position0`` (n, 3)
    the middle segment's position at the step's start."""
    out = StepSample.zeros(position0)
    for _ in range(samples):
        rows.advance(substeps)
        phi, theta = rows.phi_theta()
        for j, s in enumerate(sensors):
            phi[j], theta[j] = s.read(phi[j], theta[j])
        est.push(ids, rows.time(), phi, theta)
        out.theta = theta
        speed, yaw_rate = rows.segment_velocity()
        out.add(command, speed, yaw_rate, *rows.motor(), rows.driven_slip(), copper, h)
    return out


def wheel_friction(terrain: Terrain, contact_point: Array) -> Array:
    """Ground friction (mu_x, mu_y) under each wheel's contact point, (..., 2)."""
    out = np.empty((*contact_point.shape[:-1], 2))
    out[..., 0], out[..., 1], _ = terrain.friction(contact_point[..., 0], contact_point[..., 1])
    return out
