"""A third drive-log generator written from SPEC.md / SOIL.md alone (issue 47, item 1).

It shares no model, configuration, formula or code with the rest of ``rover_env``: its own MJCF
(:mod:`.model`), tire (:mod:`.tire`), loose soil (:mod:`.soil`), motors and speed loops
(:mod:`.motor`), sensors (:mod:`.sensors`), build tolerances (:mod:`.nuisance`), effects
(:mod:`.effects`), drive plans (:mod:`.drive`) and stepping (:mod:`.simulate`). The only import
from ``rover_env`` is the log writer's format, :mod:`rover_env.logs`.
"""

from __future__ import annotations

from typing import Any

__all__ = ["make_independent_logs"]


def __getattr__(name: str) -> Any:
    # Lazy, so the submodules' ``from rover_env.independent import ...`` makes no import circle.
    if name == "make_independent_logs":
        from rover_env.independent.generate import make_independent_logs

        return make_independent_logs
    raise AttributeError(name)
