"""The env's arguments: :class:`EnvOptions` as given (the single and the vector env take the
same keywords) and :class:`EnvSettings` validated, with the per-episode terrain draw."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path
from typing import ClassVar, Literal

import numpy as np

from rover_env.config import (
    FrictionPatch,
    Obstacle,
    Roughness,
    RoverConfig,
    SimSpec,
    TerrainConfig,
    load_rover,
    load_terrain,
)
from rover_env.estimation.sensors import SensorConfig
from rover_env.tasks.reward import RewardWeights

__all__ = ["EnvOptions", "EnvSettings"]


@dataclasses.dataclass(frozen=True)
class EnvOptions:
    """The keyword arguments of ``ProtoExplorerEnv`` and ``ProtoExplorerVectorEnv`` (beyond
    backend and rendering), as given; their meaning: ``ProtoExplorerEnv``'s docstring."""

    rover: RoverConfig | str | Path = "proto_explorer"
    terrain: TerrainConfig | str | Path = "flat"
    control_frequency: float = 10.0
    reward_weights: RewardWeights | dict[str, float] | None = None
    slip_source: Literal["true", "estimate"] = "true"
    sensor_noise: Literal["default", "none"] | SensorConfig = "default"
    action_layout: Literal["wheels", "sides"] = "wheels"
    max_speed_command: float = 0.2
    max_yaw_rate_command: float = 0.3
    command_interval: tuple[float, float] = (4.0, 8.0)
    randomize_terrain: bool = False
    estimator_rate: float = 50.0
    imu_noise: float | None = None
    timestep: float | None = None
    """Physics substep (s) replacing the rover configuration's ``sim.timestep``; None keeps
    it (1 ms shipped). The step stays 1 / ``control_frequency``: docs/timestep.md."""


def _whole(ratio: float) -> bool:
    return round(ratio) >= 1 and abs(ratio - round(ratio)) < 1e-6 * ratio


def _check_periods(timestep: float, estimator_rate: float, control_frequency: float) -> None:
    """The env samples its sensors every whole number of substeps and steps every whole
    number of samples, so that a step lasts exactly 1 / control_frequency at any timestep."""
    sample = 1.0 / estimator_rate
    if not _whole(sample / timestep):
        raise ValueError(
            f"timestep {timestep:g} s must divide the sensor sample period 1 / estimator_rate"
            f" = {sample:g} s into whole substeps (e.g. 0.001, 0.002 or 0.005 at 50 Hz)"
        )
    if not _whole((1.0 / control_frequency) / sample):
        raise ValueError(
            f"1 / control_frequency = {1.0 / control_frequency:g} s must be a whole number of"
            f" sensor samples (1 / estimator_rate = {sample:g} s)"
        )


@dataclasses.dataclass(frozen=True)
class EnvSettings:
    """The validated constructor arguments of the env, shared by its single and vector forms."""

    rover_cfg: RoverConfig
    base_terrain: TerrainConfig
    randomize_terrain: bool
    control_frequency: float
    reward_weights: RewardWeights
    slip_source: str
    sensor_cfg: SensorConfig
    imu_noise: float
    action_layout: str
    max_speed_command: float
    max_yaw_rate_command: float
    command_interval: tuple[float, float]
    estimator_rate: float

    MAX_SLOPE_DEG: ClassVar[float] = 5.0

    @classmethod
    def build(
        cls,
        options: EnvOptions | None = None,
        render_mode: str | None = None,
        render_modes: Sequence[str] = (),
    ) -> EnvSettings:
        """Validate ``options`` (loading the named configurations)."""
        o = options or EnvOptions()
        rover_cfg = o.rover if isinstance(o.rover, RoverConfig) else load_rover(o.rover)
        if o.timestep is not None:
            rover_cfg = dataclasses.replace(rover_cfg, sim=SimSpec(timestep=float(o.timestep)))
        if not (math.isfinite(o.estimator_rate) and o.estimator_rate > 0):
            raise ValueError(f"estimator_rate must be > 0, got {o.estimator_rate!r}")
        if not (math.isfinite(o.control_frequency) and o.control_frequency > 0):
            raise ValueError(f"control_frequency must be > 0, got {o.control_frequency!r}")
        _check_periods(rover_cfg.sim.timestep, o.estimator_rate, o.control_frequency)
        base_terrain = (
            o.terrain if isinstance(o.terrain, TerrainConfig) else load_terrain(o.terrain)
        )
        if o.randomize_terrain and base_terrain.is_flat:
            raise ValueError("randomize_terrain needs a non-flat terrain (e.g. 'rough')")
        if o.slip_source not in ("true", "estimate"):
            raise ValueError(f"slip_source must be 'true' or 'estimate', got {o.slip_source!r}")
        if o.action_layout not in ("wheels", "sides"):
            raise ValueError(f"action_layout must be 'wheels' or 'sides', got {o.action_layout!r}")
        if render_mode is not None and render_mode not in render_modes:
            raise ValueError(f"render_mode must be one of {list(render_modes)}")
        weights = (
            o.reward_weights
            if isinstance(o.reward_weights, RewardWeights)
            else RewardWeights(**(o.reward_weights or {}))
        )
        noise = o.sensor_noise
        sensor_cfg = (
            noise
            if isinstance(noise, SensorConfig)
            else {"default": SensorConfig(), "none": SensorConfig.ideal()}[noise]
        )
        # IMU white noise (rad/s on rates, and on the unit gravity vector): MEMS-class.
        imu = (0.0 if noise == "none" else 0.002) if o.imu_noise is None else o.imu_noise
        if not (math.isfinite(imu) and imu >= 0):
            raise ValueError(f"imu_noise must be finite and >= 0, got {o.imu_noise!r}")
        interval = (float(o.command_interval[0]), float(o.command_interval[1]))
        if not 0 < interval[0] <= interval[1]:
            raise ValueError(f"command_interval must be 0 < min <= max, got {o.command_interval}")
        return cls(
            rover_cfg=rover_cfg,
            base_terrain=base_terrain,
            randomize_terrain=bool(o.randomize_terrain),
            control_frequency=o.control_frequency,
            reward_weights=weights,
            slip_source=o.slip_source,
            sensor_cfg=sensor_cfg,
            imu_noise=imu,
            action_layout=o.action_layout,
            max_speed_command=float(o.max_speed_command),
            max_yaw_rate_command=float(o.max_yaw_rate_command),
            command_interval=interval,
            estimator_rate=o.estimator_rate,
        )

    @property
    def n_act(self) -> int:
        return 4 if self.action_layout == "wheels" else 2

    def first_terrain(self) -> TerrainConfig:
        """The terrain the simulator is compiled with (the envelope when randomising)."""
        base = self.base_terrain
        return self.envelope_terrain(base) if self.randomize_terrain else base

    def envelope_terrain(self, base: TerrainConfig) -> TerrainConfig:
        """The steepest terrain the randomiser can draw: sizes the compiled heightfield."""
        rough = dataclasses.replace(base.roughness, rms=0.04)
        return dataclasses.replace(
            base, slope_deg=(self.MAX_SLOPE_DEG, self.MAX_SLOPE_DEG), roughness=rough
        )

    def random_terrain(self, rng: np.random.Generator) -> TerrainConfig:
        base = self.base_terrain
        sx, sy = base.size
        patches = []
        for i in range(int(rng.integers(2, 5))):
            mu_x = float(rng.uniform(0.1, 0.45))
            patches.append(
                FrictionPatch(
                    name=f"patch{i}",
                    center=(
                        float(rng.uniform(-sx / 3, sx / 3)),
                        float(rng.uniform(-sy / 3, sy / 3)),
                    ),
                    size=(float(rng.uniform(1.0, 4.0)), float(rng.uniform(1.0, 4.0))),
                    mu_x=mu_x,
                    mu_y=mu_x * 1.25,
                )
            )
        obstacles = []
        for ob in base.obstacles:
            r = float(rng.uniform(2.0, min(sx, sy) / 2 - 1.0))
            a = float(rng.uniform(-np.pi, np.pi))
            obstacles.append(
                Obstacle(
                    name=ob.name,
                    pos=(r * math.cos(a), r * math.sin(a), ob.pos[2]),
                    size=ob.size,
                    yaw_deg=float(rng.uniform(-180, 180)),
                )
            )
        return dataclasses.replace(
            base,
            slope_deg=(
                float(rng.uniform(-self.MAX_SLOPE_DEG, self.MAX_SLOPE_DEG)),
                float(rng.uniform(-self.MAX_SLOPE_DEG, self.MAX_SLOPE_DEG)),
            ),
            roughness=Roughness(
                rms=float(rng.uniform(0.005, 0.04)),
                correlation_length=base.roughness.correlation_length,
                modes=base.roughness.modes,
                seed=int(rng.integers(2**31)),
            ),
            patches=tuple(patches),
            obstacles=tuple(obstacles),
        )
