"""Moved to :mod:`rover_env.policies` (issue 17); re-exported for old imports."""

from rover_env.policies.controllers import ClassicalController, EnvController
from rover_env.policies.specs import make_controller, parse_specs

__all__ = ["ClassicalController", "EnvController", "make_controller", "parse_specs"]
