"""Wheel-speed controllers that see only what the rover senses (rank 2: no gymnasium).

``OpenLoop`` turns the task command into skid-steer speed targets; ``SlipPI`` corrects them
per wheel from the estimated slip (the paper's Fig. 8). ``run_on_sim`` drives either on the
bare simulator; the environment hands them ``ProtoExplorerEnv.controller_input()``.
"""

from rover_env.control.base import CommandSchedule, Controller, ControllerInput
from rover_env.control.open_loop import OpenLoop, skid_steer_targets
from rover_env.control.runner import DriveCase, DriveTrace, run_on_sim
from rover_env.control.slip_pi import SlipPI, SlipPIConfig, load_slip_pi_config

__all__ = [
    "CommandSchedule",
    "Controller",
    "ControllerInput",
    "DriveCase",
    "DriveTrace",
    "OpenLoop",
    "SlipPI",
    "SlipPIConfig",
    "load_slip_pi_config",
    "run_on_sim",
    "skid_steer_targets",
]
