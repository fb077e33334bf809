"""A batched, torch-native rover env on MuJoCo Warp: N rovers tracking speed and yaw-rate
commands, observations, rewards and resets on the simulation's device (no host copies).

Not a Gymnasium env (a Gymnasium vector env hands numpy arrays across): :meth:`reset`
returns the observations and :meth:`step` takes actions and returns ``(obs, reward,
terminated, truncated)``, all ``torch.Tensor`` on ``device``; worlds that end are put back to
the settled start (:meth:`WarpRoverSim.reset_worlds`) within the same call, and their next
observation is the new episode's (the convention of Isaac Lab / rsl_rl style envs).

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
from rover_env.warp.sim import WarpRoverSim

OBS_DIM = 19
"""command (2), segment 1's forward speed and yaw rate (2), its up axis in its own frame
(3), wheel rates / max (6), joint angles (5), episode time / length (1)."""
ACT_DIM = 4


class WarpRoverEnv:
    """``n_envs`` rovers on one device; see the module docstring.

    Args:
        n_envs: number of worlds.
        rover, terrain: as :class:`WarpRoverSim` (one terrain for all).
        device: Warp/torch device, ``"cuda:0"`` or ``"cpu"``.
        control_dt: seconds per :meth:`step` (substeps of the model's timestep).
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
        control_dt: float = 0.05,
        episode_seconds: float = 10.0,
        max_speed: float = 0.2,
        max_yaw_rate: float = 0.3,
        seed: int = 0,
        rut_pool_tiles: int = 256,
    ) -> None:
        self.sim = WarpRoverSim(
            n_envs, rover, terrain, device=device, rut_pool_tiles=rut_pool_tiles
        )
        self.n = n_envs
        self.device = torch.device(wp.device_to_torch(self.sim.device))
        self.substeps = max(1, round(control_dt / self.sim.dt))
        self.control_dt = self.substeps * self.sim.dt
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

    def reset(self) -> torch.Tensor:
        """Every world back to the settled start with a new command; the observations."""
        self._mask.fill_(1)
        self.sim.reset_worlds(self._mask_wp)
        self.steps.zero_()
        self.last_action.zero_()
        self._sample_commands(torch.ones(self.n, dtype=torch.bool, device=self.device))
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

    def observe(self) -> torch.Tensor:
        v, w, up = self._motion()
        rates = self._qvel[:, self._wheel_dof] / self.max_wheel
        t = (self.steps.float() / self.max_steps)[:, None]
        return torch.cat(
            [self.command, v[:, None], w[:, None], up, rates, self._qpos[:, self._joint_qpos], t],
            dim=1,
        )

    def step(
        self, action: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Apply ``action`` (n, 4) in [-1, 1] for ``control_dt``; (obs, reward, terminated,
        truncated), the ended worlds already reset."""
        a = action.clamp(-1.0, 1.0)
        self._targets.copy_(a * self.max_wheel)
        self.sim.step(self.substeps)
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
        return self.observe(), reward, terminated, truncated
