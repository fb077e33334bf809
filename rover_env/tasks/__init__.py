"""What an episode asks of the rover, as Task objects (dm_control's split of env and task).

An env is the simulation, the rover's sensors and one task. The task owns the command
schedule, the episode setup (ground and start pose), the time limit and the reward weights;
the env owns the physics, sensing, estimation, the reward's formula and termination by flip
or leaving the arena. Tasks here:

* :class:`~rover_env.tasks.tracking.RandomTracking`: random speed and yaw-rate commands
  changing every few seconds (``ProtoExplorer-v0``, ``ProtoExplorerRough-v0``);
* :class:`~rover_env.tasks.scenario.ScenarioTask`: one episode of a benchmark scenario
  (``configs/scenarios/*.yaml``, :mod:`~rover_env.tasks.scenarios`): its ground, start pose,
  fixed command schedule and length;
* :class:`~rover_env.tasks.mix.ScenarioMix`: a scenario drawn per episode with its seed kept
  in the seed plan's split (``ProtoExplorerScenarioMix-v0``; over the families' training
  distributions ``ProtoExplorerFamilies-v0``);
* scenario families (:mod:`~rover_env.tasks.families`): ``NAME@train`` and ``NAME@SHIFT``
  draw a whole world per seed from the distributions a scenario YAML declares.

Layer: above the controllers (it uses their ``CommandSchedule``) and below the envs; no
gymnasium here.
"""

from rover_env.tasks.base import EpisodeSetup, Task
from rover_env.tasks.mix import ScenarioMix
from rover_env.tasks.reward import RewardWeights
from rover_env.tasks.scenario import ScenarioTask
from rover_env.tasks.tracking import RandomTracking

__all__ = ["EpisodeSetup", "RandomTracking", "RewardWeights", "ScenarioMix", "ScenarioTask", "Task"]
