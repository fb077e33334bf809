"""Pre-registered research questions: what a final (test-block) run answers.

Every final run names one question of ``configs/benchmarks/questions.yaml`` (``--question
ID``). A question fixes, before its first look: its text, the paired baseline, the scenarios
(family or shift) it is asked on, the verdict metrics, the family-wise ``alpha``, the
spending rule across looks and the number of looks planned (:mod:`rover_env.benchmark.spending`).
The test ledger counts the looks per question and stores the question's fingerprint at its
first look; a later look at an edited question is refused (register a new id instead).

.. code-block:: yaml

    questions:
      - id: soil-agent-vs-pi
        text: Does a learnt agent beat the set-point slip PI on loose soil at the commanded pace?
        baseline: slip-pi:slip_pi_soil
        controllers: ["ppo:*"]        # fnmatch patterns the agents under test must match
        scenarios: [sand-slope, soft-patch, sand-turns]
        metrics: [success, energy_per_metre, mean_sinkage]
        alpha: 0.05
        spending: obrien-fleming      # or pocock
        max_looks: 2
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from rover_env.benchmark.metrics import METRICS
from rover_env.benchmark.spending import RULES, look_alpha
from rover_env.config import ConfigError, configs_dir, from_dict, load_yaml, to_dict

__all__ = ["Question", "default_questions", "load_questions", "question"]


@dataclass(frozen=True)
class Question:
    """One pre-registered question (module docstring)."""

    id: str
    text: str
    baseline: str
    scenarios: tuple[str, ...]
    alpha: float = 0.05
    spending: str = "obrien-fleming"
    max_looks: int = 1
    metrics: tuple[str, ...] = ("success", "energy_per_metre", "mean_sinkage")
    controllers: tuple[str, ...] = ("*",)
    shift: str = ""
    """The distribution shift or family the question is asked under (a label, e.g. "nominal")."""

    def __post_init__(self) -> None:
        if not self.id or not self.text.strip():
            raise ConfigError("a question needs an id and a text")
        if not 0.0 < self.alpha < 1.0:
            raise ConfigError(f"question {self.id}: alpha must be in (0, 1), got {self.alpha}")
        if self.spending not in RULES:
            raise ConfigError(
                f"question {self.id}: spending {self.spending!r}; have {', '.join(RULES)}"
            )
        if self.max_looks < 1:
            raise ConfigError(f"question {self.id}: max_looks must be >= 1")
        bad = [m for m in self.metrics if m not in METRICS]
        if bad or not self.metrics:
            raise ConfigError(f"question {self.id}: unknown metrics {bad}; have {list(METRICS)}")
        if not self.scenarios:
            raise ConfigError(f"question {self.id}: no scenarios")

    def fingerprint(self) -> str:
        """SHA-256 (16 hex digits) of everything the question fixes before its first look."""
        text = json.dumps(to_dict(self), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def alpha_of_look(self, look: int) -> float:
        """Nominal two-sided alpha of look ``look`` (0 beyond ``max_looks``)."""
        return look_alpha(self.spending, self.alpha, self.max_looks, look)

    def check_run(self, controllers: Sequence[str], scenarios: Sequence[str]) -> None:
        """ValueError unless the run asks this question: its baseline first, agents matching
        ``controllers``, and exactly the question's scenarios."""
        if not controllers or controllers[0] != self.baseline:
            raise ValueError(
                f"question {self.id}: the run's first controller (the paired baseline) must be "
                f"{self.baseline}, got {controllers[0] if controllers else 'none'}"
            )
        for c in controllers[1:]:
            if not any(fnmatch.fnmatchcase(c, p) for p in self.controllers):
                raise ValueError(
                    f"question {self.id}: controller {c} matches none of {list(self.controllers)}"
                )
        if sorted(scenarios) != sorted(self.scenarios):
            raise ValueError(
                f"question {self.id}: asked on scenarios {list(self.scenarios)}, "
                f"the run has {list(scenarios)}"
            )


def default_questions() -> Path:
    """``configs/benchmarks/questions.yaml``."""
    return configs_dir() / "benchmarks" / "questions.yaml"


def load_questions(path: str | Path | None = None) -> dict[str, Question]:
    """Every question of the file, by id (ConfigError naming the file and the entry)."""
    p = Path(path) if path is not None else default_questions()
    if not p.is_file():
        raise ConfigError(f"questions file not found: {p}")
    data = load_yaml(p)
    items = data.get("questions") if isinstance(data, dict) else None
    if not isinstance(items, list):
        raise ConfigError(f"{p}: expected a top-level 'questions:' list")
    out: dict[str, Question] = {}
    for i, item in enumerate(items):
        q = from_dict(Question, item, f"{p}: questions[{i}]")
        if q.id in out:
            raise ConfigError(f"{p}: questions[{i}]: id {q.id!r} given twice")
        out[q.id] = q
    return out


def question(qid: str, path: str | Path | None = None) -> Question:
    """The question ``qid`` of the questions file (ConfigError listing the ids otherwise)."""
    qs = load_questions(path)
    if qid not in qs:
        raise ConfigError(
            f"no question {qid!r} in {path or default_questions()}; have {', '.join(qs)} "
            "(register it there, with its alpha, spending rule and looks, before the first look)"
        )
    return qs[qid]
