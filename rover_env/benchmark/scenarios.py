"""Moved to :mod:`rover_env.tasks.scenarios` (issue 17: scenarios are tasks); re-exported."""

from rover_env.tasks.scenarios import (
    Episode,
    Jitter,
    ScenarioConfig,
    StartPose,
    load_scenario,
    scenario_names,
)

__all__ = ["Episode", "Jitter", "ScenarioConfig", "StartPose", "load_scenario", "scenario_names"]
