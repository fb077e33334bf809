"""The test ledger: the test split is touched once per agent.

Selection, tuning and ablation run on the validation seeds; the test seeds
(:mod:`rover_env.seeds`) only report an agent already chosen. Each such *final* run
(``rover-env benchmark --final``, ``train/evaluate.py --final``) appends one row per agent
under test to ``docs/benchmark/test_ledger.csv``: the hash of the agent's files, the
configuration and command of the run, the date and its figures. A second final run of an
agent whose hash is already in the ledger is refused (:class:`FinalRunRefused`) unless
forced, and a forced row is marked ``repeat`` so that a reader sees the test split was
looked at more than once.

The agents under test are every controller but the first, which is the paired baseline
(a run of one controller tests that one). The hash covers what decides the agent's
actions: for ``ppo:PATH`` (``sac:``, ``td3:``) the model ``.zip``, its normalisation statistics and the run's
``config.yaml``; for a classical controller its spec and its resolved settings.
"""

from __future__ import annotations

import csv
import datetime as dt
import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "FIELDS",
    "FinalRunRefused",
    "agent_hash",
    "agents_under_test",
    "check_final",
    "default_ledger",
    "record_final",
]

FIELDS = (
    "date",
    "agent",
    "agent_hash",
    "baseline",
    "config",
    "command",
    "figures",
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


def _read(ledger: Path) -> list[dict[str, str]]:
    if not ledger.is_file():
        return []
    with ledger.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    if rows and set(FIELDS) - set(rows[0]):
        raise ValueError(f"{ledger}: columns {sorted(set(FIELDS) - set(rows[0]))} missing")
    return rows


def check_final(
    controllers: Sequence[str], ledger: Path, force: bool = False
) -> dict[str, tuple[str, bool]]:
    """``{agent: (hash, repeat)}`` for a final run; raises :class:`FinalRunRefused` when an
    agent already has a row and ``force`` is False. Call it before any test episode runs."""
    seen = {r["agent_hash"]: r for r in _read(ledger)}
    out: dict[str, tuple[str, bool]] = {}
    for spec in agents_under_test(controllers):
        digest = agent_hash(spec)
        prior = seen.get(digest)
        if prior is not None and not force:
            raise FinalRunRefused(
                f"{spec} (hash {digest}) already had its final test run on {prior['date']} "
                f"({ledger}); select and tune on validation, or pass --force to run the test "
                "split again (the row is then marked as a repeat)"
            )
        out[spec] = (digest, prior is not None)
    return out


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
    checked: dict[str, tuple[str, bool]],
    controllers: Sequence[str],
    rows: Sequence[dict[str, Any]],
    config: dict[str, Any],
    command: str,
) -> None:
    """Append one row per agent of ``checked`` (from :func:`check_final`) after the run."""
    ledger.parent.mkdir(parents=True, exist_ok=True)
    new = not ledger.is_file() or ledger.stat().st_size == 0
    date = dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    with ledger.open("a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(FIELDS))
        if new:
            w.writeheader()
        for agent, (digest, repeat) in checked.items():
            w.writerow(
                {
                    "date": date,
                    "agent": agent,
                    "agent_hash": digest,
                    "baseline": controllers[0] if len(controllers) > 1 else "",
                    "config": json.dumps(config, separators=(",", ":"), sort_keys=True),
                    "command": command,
                    "figures": _figures(rows, agent),
                    "repeat": "repeat (forced)" if repeat else "",
                }
            )
