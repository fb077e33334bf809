"""The test ledger: every look at the test block, counted per research question.

Selection, tuning and ablation run on the validation seeds; the test seeds
(:mod:`rover_env.seeds`) only report controllers already chosen, each final run
(``rover-env benchmark --final --question ID``, ``train/evaluate.py --final --question ID``)
answering one pre-registered question (:mod:`rover_env.benchmark.questions`). A final run
appends one row per controller of the run, the baseline included (``role``), to
``docs/benchmark/test_ledger.csv``: the run, the question, its fingerprint, the look number and
the look's alpha (:mod:`rover_env.benchmark.spending`), the hash of the controller's files,
the configuration and command, the date, the figures and the verdict.

Refused before any episode runs (:class:`FinalRunRefused`) unless forced, a forced row
marked so that a reader sees it:

* an agent (every controller but the baseline) that already had a final run on the test
  block (``repeat (forced)``);
* a look beyond the question's ``max_looks`` (``beyond max looks (forced)``; such a look
  has alpha 0 and claims nothing);
* a look at a question edited since its first look (``question edited (forced)``).

The hash covers what decides the controller's actions: for ``ppo:PATH`` (``sac:``, ``td3:``)
the model ``.zip``, its normalisation statistics and the run's ``config.yaml``; for a
classical controller its spec and its resolved settings.

Rows written before issue 46 (version 1: no question, agents only) stay readable: they read
as looks without a question on the ``spent`` block and do not count against the new one.
"""

from __future__ import annotations

import csv
import datetime as dt
import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rover_env.benchmark.questions import Question
from rover_env.seeds import split_of

__all__ = [
    "FIELDS",
    "FIELDS_V1",
    "FinalCheck",
    "FinalRunRefused",
    "agent_hash",
    "agents_under_test",
    "check_final",
    "default_ledger",
    "read_ledger",
    "record_final",
]

FIELDS_V1 = ("date", "agent", "agent_hash", "baseline", "config", "command", "figures", "repeat")
"""The columns before issue 46 (agents only, no question)."""

FIELDS = (
    "date",
    "run",
    "question",
    "question_hash",
    "look",
    "alpha_look",
    "role",
    "agent",
    "agent_hash",
    "baseline",
    "split",
    "config",
    "command",
    "figures",
    "verdict",
    "repeat",
)


class FinalRunRefused(RuntimeError):
    """A final (test-split) run of an agent that the ledger already holds."""


def default_ledger() -> Path:
    """``docs/benchmark/test_ledger.csv`` of the repository checkout (of the working
    directory when rover_env runs from an installed wheel, which has no ``docs/``)."""
    repo = Path(__file__).resolve().parents[2]
    if (repo / "docs" / "benchmark").is_dir() and (repo / "pyproject.toml").is_file():
        return repo / "docs" / "benchmark" / "test_ledger.csv"
    return Path.cwd() / "docs" / "benchmark" / "test_ledger.csv"


def agents_under_test(controllers: Sequence[str]) -> list[str]:
    """Every controller but the paired baseline (the first); a lone controller is the agent."""
    return list(controllers[1:]) if len(controllers) > 1 else list(controllers)


def agent_hash(spec: str) -> str:
    """SHA-256 (first 16 hex digits) of what decides the actions of controller ``spec``."""
    h = hashlib.sha256()
    from rover_env.policies.specs import is_learned

    kind, _, arg = spec.partition(":")
    if is_learned(spec):
        from rover_env.policies.ppo import resolve_model_path

        model, stats = resolve_model_path(arg)
        h.update(kind.encode() + b"\0" + model.read_bytes())
        if stats is not None:
            h.update(b"\0stats\0" + stats.read_bytes())
        cfg = model.parent / "config.yaml"
        if cfg.is_file():
            h.update(b"\0config\0" + cfg.read_bytes())
    else:
        from rover_env.policies.specs import controller_settings

        h.update(json.dumps(controller_settings(spec), sort_keys=True).encode())
    return h.hexdigest()[:16]


def read_ledger(ledger: Path) -> list[dict[str, str]]:
    """Every row with the version-2 columns (version-1 rows filled in: module docstring)."""
    if not ledger.is_file():
        return []
    with ledger.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        return []
    have = set(rows[0])
    if not set(FIELDS) <= have and not set(FIELDS_V1) <= have:
        raise ValueError(f"{ledger}: columns {sorted(set(FIELDS) - have)} missing")
    out = []
    for r in rows:
        if "question" not in r:
            first = str(json.loads(r["config"] or "{}").get("seeds", "")).split("..")[0]
            r = {
                **dict.fromkeys(FIELDS, ""),
                **r,
                "run": r["date"],
                "role": "agent",
                "split": split_of(int(first)) if first.isdigit() else "",
            }
        out.append({k: r.get(k) or "" for k in FIELDS})
    return out


@dataclass
class FinalCheck:
    """What :func:`check_final` allows: the look, its alpha and each controller's hash."""

    question: Question
    look: int
    alpha: float
    hashes: dict[str, str]
    marks: dict[str, str] = field(default_factory=dict)
    """Controller -> its row's ``repeat`` mark (forced refusals)."""

    def describe(self) -> str:
        q = self.question
        left = "no alpha left: nothing is claimed" if self.alpha <= 0 else f"alpha {self.alpha:.4g}"
        return (
            f"Look {self.look} of {q.max_looks} at question `{q.id}` ({q.spending} spending of "
            f"alpha {q.alpha:g} over {q.max_looks} planned looks): {left}."
        )


def check_final(
    controllers: Sequence[str],
    scenarios: Sequence[str],
    ledger: Path,
    question: Question,
    force: bool = False,
) -> FinalCheck:
    """The look a final run would be; raises :class:`FinalRunRefused` (module docstring)
    unless ``force``. Call it before any test episode runs."""
    question.check_run(controllers, scenarios)
    rows = [r for r in read_ledger(ledger) if r["split"] == "test"]
    mine = [r for r in rows if r["question"] == question.id]
    runs = list(dict.fromkeys(r["run"] for r in mine))
    look = len(runs) + 1
    marks: dict[str, str] = {}
    refusals = []
    if mine and mine[0]["question_hash"] != question.fingerprint():
        refusals.append(
            f"question {question.id} changed since its first look on {mine[0]['date']} "
            "(register a new question id)"
        )
        marks.update(dict.fromkeys(controllers, "question edited (forced)"))
    if look > question.max_looks:
        refusals.append(
            f"question {question.id} had its {question.max_looks} planned look(s) "
            f"({', '.join(runs)}); a further look has no alpha left"
        )
        marks.update(dict.fromkeys(controllers, "beyond max looks (forced)"))
    hashes = {spec: agent_hash(spec) for spec in controllers}
    tested = {r["agent_hash"]: r for r in rows if r["role"] == "agent"}
    for spec in agents_under_test(controllers):
        prior = tested.get(hashes[spec])
        if prior is not None:
            refusals.append(
                f"{spec} (hash {hashes[spec]}) already had its final test run on "
                f"{prior['date']} (question {prior['question']})"
            )
            marks[spec] = "; ".join(x for x in (marks.get(spec), "repeat (forced)") if x)
    if refusals and not force:
        raise FinalRunRefused(
            "; ".join(refusals) + f" ({ledger}); select and tune on validation, or pass "
            "--force to run the test split again (the rows are then marked)"
        )
    return FinalCheck(question, look, question.alpha_of_look(look), hashes, marks)


def _figures(rows: Sequence[dict[str, Any]], agent: str) -> str:
    """``{scenario: {metric: mean}}`` of the agent, as compact JSON."""
    from rover_env.benchmark.metrics import METRICS

    out: dict[str, dict[str, float]] = {}
    for r in rows:
        if r["controller"] != agent:
            continue
        out.setdefault(r["scenario"], {m: 0.0 for m in METRICS})
    for scen, means in out.items():
        sel = [r for r in rows if r["controller"] == agent and r["scenario"] == scen]
        for m in METRICS:
            means[m] = float(f"{sum(float(r[m]) for r in sel) / len(sel):.5g}")
    return json.dumps(out, separators=(",", ":"))


def record_final(
    ledger: Path,
    checked: FinalCheck,
    controllers: Sequence[str],
    rows: Sequence[dict[str, Any]],
    config: dict[str, Any],
    command: str,
    verdicts: Sequence[dict[str, Any]] = (),
) -> None:
    """Append one row per controller of the run (the baseline too) after the run; a
    version-1 ledger is rewritten with the version-2 columns first (its rows kept)."""
    ledger.parent.mkdir(parents=True, exist_ok=True)
    old = read_ledger(ledger)
    header = None
    if ledger.is_file():
        with ledger.open(newline="") as fh:
            header = next(csv.reader(fh), None)
    date = dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    run = f"{checked.question.id}#{checked.look} {date}"  # one per look: looks count runs
    baseline = controllers[0] if len(controllers) > 1 else ""
    q = checked.question
    new = []
    for spec in controllers:
        role = "baseline" if spec == baseline else "agent"
        mine = {v["scenario"]: v["verdict"] for v in verdicts if v["controller"] == spec}
        new.append(
            {
                "date": date,
                "run": run,
                "question": q.id,
                "question_hash": q.fingerprint(),
                "look": str(checked.look),
                "alpha_look": f"{checked.alpha:.6g}",
                "role": role,
                "agent": spec,
                "agent_hash": checked.hashes[spec],
                "baseline": baseline if role == "agent" else "",
                "split": "test",
                "config": json.dumps(config, separators=(",", ":"), sort_keys=True),
                "command": command,
                "figures": _figures(rows, spec),
                "verdict": json.dumps(mine, separators=(",", ":")) if mine else "",
                "repeat": checked.marks.get(spec, ""),
            }
        )
    rewrite = header is None or tuple(header) != FIELDS
    with ledger.open("w" if rewrite else "a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(FIELDS))
        if rewrite:
            w.writeheader()
            w.writerows(old)
        w.writerows(new)
