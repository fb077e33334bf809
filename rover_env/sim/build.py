"""What the simulator builds from a rover configuration before any physics: the model
extensions' configuration changes, the loose soil they lay, and which tire backend runs
(split from :mod:`rover_env.sim.simulator`, which builds from these)."""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence

from rover_env.config import RoverConfig, TerrainConfig
from rover_env.effects import LOOSE_SOIL_PRESETS, Effect, build_effects, plugin_refusals
from rover_env.sim.fast import FastBackendError, load_plugin
from rover_env.soil import SoilParams, load_soil


def physical_config(cfg: RoverConfig, effects: Sequence[Effect] | None = None) -> RoverConfig:
    """``cfg`` as the simulator builds it: the model extensions' configuration changes
    applied (a torque limit effect changes ``motor.torque_limit``), the extensions cleared.
    ``effects``: those of ``cfg.extensions`` that are on, if already built."""
    if effects is None:
        effects = [e for e in build_effects(cfg.extensions) if not e.is_off]
    phys = cfg
    for e in effects:
        phys = e.apply_config(phys)
    return dataclasses.replace(phys, extensions={}) if cfg.extensions else phys


def effect_soil(terrain: TerrainConfig, effects: Sequence[Effect]) -> SoilParams | None:
    """The loose soil the model extensions put over the whole ground (``loose_soil``): the
    terrain's own ground soil, or the effect's preset (``LOOSE_SOIL_PRESETS``) on hard
    ground, with their changes;
    None when no extension changes the soil."""
    changes: dict[str, float] = {}
    for e in effects:
        changes.update(e.soil_changes())
    if not changes:
        return None
    preset = LOOSE_SOIL_PRESETS[int(changes.pop("preset", 0.0))]
    base = load_soil(terrain.soil if terrain.soil else preset)
    return dataclasses.replace(base, name=f"{base.name} (loose_soil)", **changes)


def resolve_auto_backend(cfg: RoverConfig) -> str:
    """``backend="auto"``: the compiled plugin where it can run this model, else numpy."""
    if plugin_refusals(cfg.extensions):
        return "numpy"
    try:
        load_plugin()
    except FastBackendError as exc:
        warnings.warn(
            f"backend='auto': using the numpy tire layer (~10x slower) because the fast "
            f"plugin is unavailable: {exc}",
            RuntimeWarning,
            stacklevel=3,
        )
        return "numpy"
    return "plugin"
