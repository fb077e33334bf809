"""A batched, torch-native rover env on MuJoCo Warp: N rovers tracking speed and yaw-rate
commands, observations, rewards and resets on the simulation's device (no host copies).

Not a Gymnasium env (a Gymnasium vector env hands numpy arrays across): :meth:`reset`
returns the observations and :meth:`step` takes actions and returns ``(obs, reward,
terminated, truncated)``, all ``torch.Tensor`` on ``device``; worlds that end are put back to
the settled start (:meth:`WarpRoverSim.reset_worlds`) within the same call, and their next
observation is the new episode's (the convention of Isaac Lab / rsl_rl style envs).

The observation is the Gymnasium env's (``rover_env.envs.episode.OBS_NAMES``, 46 entries in
the same order): the slip estimator's wheel and joint rates, slip ratios, speed and yaw rate
(:class:`rover_env.warp.estimator.TorchSlipEstimator`, sampled at ``estimator_rate`` within
each step as the CPU env samples it), the joint angles it was given, each segment's gravity
direction and angular rates (the IMUs), the command and the previous action. The sensors
are the CPU env's: encoder and potentiometer quantisation and potentiometer and IMU noise
(``SensorConfig``, ``imu_noise``), drawn from the env's torch generator.

The task is the plain env's (``rover_env.tasks.tracking.RandomTracking``): a command
(forward speed uniform in [0.3, 1] x ``max_speed``, yaw rate uniform in +-``max_yaw_rate``,
a third straight) held for a whole episode here. Actions in [-1, 1]^4 scale to the driven
wheels' speed targets (+-``max_wheel_speed``). Reward: ``exp(-(v - v_cmd)^2 / s_v^2) +
exp(-(w - w_cmd)^2 / s_w^2)`` minus a small action-rate penalty; termination when a segment
tilts past 75 deg (RoverSim.flipped).
"""

from __future__ import annotations

import math
from pathlib import Path

import torch
import warp as wp

from rover_env.config import RoverConfig, TerrainConfig
from rover_env.envs.episode import OBS_NAMES
from rover_env.estimation.estimator import EstimatorConfig
from rover_env.estimation.sensors import SensorConfig
from rover_env.warp.estimator import TorchSlipEstimator
from rover_env.warp.sim import WarpRoverSim

OBS_DIM = len(OBS_NAMES)
"""46: the layout of ``rover_env.envs.episode.OBS_NAMES`` (the Gymnasium env's)."""
ACT_DIM = 4


class WarpRoverEnv:
    """``n_envs`` rovers on one device; see the module docstring.

    Args:
        n_envs: number of worlds.
        rover, terrain: as :class:`WarpRoverSim` (one terrain for all).
        device: Warp/torch device, ``"cuda:0"`` or ``"cpu"``.
        control_dt: seconds per :meth:`step`, rounded to whole estimator samples (the
            CPU env's 0.1 s by default).
        estimator_rate: Hz at which the slip estimator samples the sensors (the CPU env's).
        sensors: encoder and potentiometer model (quantisation, noise); ``SensorConfig.ideal()``
            reads the state exactly.
        imu_noise: rad/s (and unit-vector) rms noise on the IMU entries.
        episode_seconds: time limit.
        max_speed, max_yaw_rate: command ranges (m/s, rad/s).
        seed: seeds the commands (torch generator on the device).
        rut_pool_tiles: as :class:`WarpRoverSim`.
    """

    def __init__(
        self,
        n_envs: int,
        rover: RoverConfig | str | Path = "proto_explorer",
        terrain: TerrainConfig | str | Path = "flat",
        device: str = "cuda:0",
        control_dt: float = 0.1,
        episode_seconds: float = 10.0,
        max_speed: float = 0.2,
        max_yaw_rate: float = 0.3,
        seed: int = 0,
        rut_pool_tiles: int = 256,
        estimator_rate: float = 50.0,
        sensors: SensorConfig | None = None,
        imu_noise: float = 0.002,
    ) -> None:
        self.sim = WarpRoverSim(
            n_envs, rover, terrain, device=device, rut_pool_tiles=rut_pool_tiles
        )
        self.n = n_envs
        self.device = torch.device(wp.device_to_torch(self.sim.device))
        # as RoverEpisode._configure: whole samples per step, whole substeps per sample
        self.substeps_per_sample = max(1, round(1.0 / (estimator_rate * self.sim.dt)))
        self.sample_dt = self.substeps_per_sample * self.sim.dt
        self.samples_per_step = max(1, round(control_dt / self.sample_dt))
        self.substeps = self.samples_per_step * self.substeps_per_sample
        self.control_dt = self.substeps * self.sim.dt
        self.sensors = SensorConfig() if sensors is None else sensors
        self.imu_noise = float(imu_noise)
        self.max_steps = round(episode_seconds / self.control_dt)
        self.max_speed, self.max_yaw_rate = float(max_speed), float(max_yaw_rate)
        self.max_wheel = float(self.sim.cfg.motor.max_wheel_speed)
        self.gen = torch.Generator(device=self.device).manual_seed(int(seed))
        d, s = self.sim.d, self.sim
        # zero-copy views of the Warp arrays
        self._qpos = wp.to_torch(d.qpos)
        self._qvel = wp.to_torch(d.qvel)
        self._xmat = wp.to_torch(d.xmat)
        self._cvel = wp.to_torch(d.cvel)
        self._xpos = wp.to_torch(d.xpos)
        self._com = wp.to_torch(d.subtree_com)
        self._targets = wp.to_torch(s.targets)
        mj = s.mjm
        self._seg = int(s.seg_body[0])
        self._root = int(mj.body_rootid[self._seg])
        self._segs = torch.as_tensor(s.seg_body, device=self.device)
        self._wheel_dof = torch.as_tensor(s.wheel_dof, device=self.device)
        joints = [mj.joint(j).id for j in ("theta_1", "theta_2", "theta_3", "theta_4", "theta_5")]
        self._joint_qpos = torch.as_tensor(mj.jnt_qposadr[joints], device=self.device)
        self._wheel_qpos = torch.as_tensor(s.wheel_qpos, device=self.device)
        window = EstimatorConfig().rate_window
        self.estimator = TorchSlipEstimator(
            self.sim.cfg,
            n_envs,
            EstimatorConfig(),
            device=self.device,
            capacity=int(window / self.sample_dt) + 2,
        )
        self._sample = torch.zeros(self.n, dtype=torch.int64, device=self.device)
        self.theta_meas = torch.zeros(self.n, 5, device=self.device)
        # the IMUs of the settled start (the kinematics arrays lag a reset: see observe)
        self._imu0 = self._imu()
        self._fresh = torch.ones(self.n, dtype=torch.bool, device=self.device)
        self._mask = torch.zeros(self.n, dtype=torch.int32, device=self.device)
        self._mask_wp = wp.from_torch(self._mask)
        self.steps = torch.zeros(self.n, dtype=torch.int64, device=self.device)
        self.command = torch.zeros(self.n, 2, device=self.device)
        self.last_action = torch.zeros(self.n, ACT_DIM, device=self.device)

    def _sample_commands(self, where: torch.Tensor) -> None:
        """New commands for the worlds where ``where`` (bool, (n,)) holds; no host sync."""
        u = torch.rand(self.n, 3, generator=self.gen, device=self.device)
        v = (0.3 + 0.7 * u[:, 0]) * self.max_speed
        w = torch.where(u[:, 1] < 1 / 3, 0.0, (2 * u[:, 2] - 1) * self.max_yaw_rate)
        self.command = torch.where(where[:, None], torch.stack([v, w], dim=1), self.command)

    def _imu(self) -> torch.Tensor:
        """Each segment's gravity direction and angular rates in its own axes (n, 2, 3, 3),
        as ``RoverIndex.gravity`` and the gyro sensors (sites at the segment frames) read
        them: from the kinematics of the last substep's start, as MuJoCo's sensor stage."""
        xmat = self._xmat[:, self._segs].reshape(self.n, 3, 3, 3)
        w_world = self._cvel[:, self._segs, 0:3]
        gyro = (xmat * w_world[..., :, None]).sum(-2)  # R^T w
        return torch.stack([-xmat[:, :, 2, :], gyro], dim=1)

    def _quantize(self, x: torch.Tensor, resolution: float) -> torch.Tensor:
        return x if resolution == 0 else torch.round(x / resolution) * resolution

    def _push(self, where: torch.Tensor | None) -> None:
        """One estimator sample of the worlds ``where`` (None: all), through the sensors
        (SensorModel.read: the counters start at zero with the settled template)."""
        c = self.sensors
        phi = self._qpos[:, self._wheel_qpos]
        theta = self._qpos[:, self._joint_qpos]
        if c.wheel_noise > 0:
            phi = phi + c.wheel_noise * torch.randn(
                phi.shape, generator=self.gen, device=self.device
            )
        if c.joint_noise > 0:
            theta = theta + c.joint_noise * torch.randn(
                theta.shape, generator=self.gen, device=self.device
            )
        phi = self._quantize(phi, c.wheel_resolution)
        theta = self._quantize(theta, c.joint_resolution)
        t = self._sample.double() * self.sample_dt
        mask = where if where is not None else None
        self.estimator.push(mask, t, phi, theta)
        self.theta_meas = (
            theta if where is None else torch.where(where[:, None], theta, self.theta_meas)
        )

    def _restart(self, where: torch.Tensor) -> None:
        """The estimator's and sensors' part of a new episode in the worlds ``where``."""
        self._sample = torch.where(where, 0, self._sample)
        self.estimator.reset(where)
        self._push(where)
        self._fresh = self._fresh | where

    def reset(self) -> torch.Tensor:
        """Every world back to the settled start with a new command; the observations."""
        self._mask.fill_(1)
        self.sim.reset_worlds(self._mask_wp)
        self.steps.zero_()
        self.last_action.zero_()
        every = torch.ones(self.n, dtype=torch.bool, device=self.device)
        self._sample_commands(every)
        self._restart(every)
        return self.observe()

    def _motion(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Segment 1's forward speed, yaw rate (own axes) and up axis in its frame, from its
        free joint's state (current after a reset too, unlike the kinematics arrays)."""
        w, x, y, z = self._qpos[:, 3:7].unbind(1)
        # the body x axis in world coordinates (R's first column), the world z axis in body
        # coordinates (R's last row); the free joint's angular velocity is in body axes
        fwd = torch.stack(
            [1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], dim=1
        )
        up = torch.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], dim=1)
        return (self._qvel[:, 0:3] * fwd).sum(dim=1), self._qvel[:, 5], up

    def true_motion(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Segment 1's true forward speed and yaw rate (its own axes), (n,) each."""
        v, w, _ = self._motion()
        return v, w

    def observe(self) -> torch.Tensor:
        """The observation (n, 46), ``OBS_NAMES`` order, from the estimator's newest
        estimate; worlds reset since the last physics step read the start's IMUs."""
        est = self.estimator.estimate()
        imu = torch.where(self._fresh[:, None, None, None], self._imu0, self._imu())
        if self.imu_noise > 0:
            imu = imu + self.imu_noise * torch.randn(
                imu.shape, generator=self.gen, device=self.device
            )
        f = self._qpos.dtype
        return torch.cat(
            [
                est.phi_rate,
                self.theta_meas,
                est.theta_rate,
                imu.reshape(self.n, 18),
                est.slip_ratio,
                est.seg_velocity[:, 1, 0:1],
                est.seg_yaw_rate[:, 1:2],
                self.command,
                self.last_action,
            ],
            dim=1,
        ).to(f)

    def step(
        self, action: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Apply ``action`` (n, 4) in [-1, 1] for ``control_dt``, sampling the estimator
        every ``sample_dt``; (obs, reward, terminated, truncated), the ended worlds reset."""
        a = action.clamp(-1.0, 1.0)
        self._targets.copy_(a * self.max_wheel)
        for _ in range(self.samples_per_step):
            self.sim.step(self.substeps_per_sample)
            self._sample += 1
            self._push(None)
        self._fresh.zero_()
        self.steps += 1
        v, w, _ = self._motion()
        reward = (
            torch.exp(-(((v - self.command[:, 0]) / 0.05) ** 2))
            + torch.exp(-(((w - self.command[:, 1]) / 0.1) ** 2))
            - 0.05 * ((a - self.last_action) ** 2).sum(dim=1)
        )
        self.last_action = a.detach().clone()
        tilt = self._xmat[:, self._segs, 2, 2]
        terminated = (tilt < math.cos(math.radians(75.0))).any(dim=1) | ~torch.isfinite(v)
        truncated = self.steps >= self.max_steps
        done = terminated | truncated
        reward = torch.where(torch.isfinite(reward), reward, torch.zeros_like(reward))
        self._mask.copy_(done.to(torch.int32))
        self.sim.reset_worlds(self._mask_wp)
        self.steps = torch.where(done, 0, self.steps)
        self.last_action = torch.where(done[:, None], 0.0, self.last_action)
        self._sample_commands(done)
        self._restart(done)
        return self.observe(), reward, terminated, truncated
