"""Run-directory bookkeeping: what was run, with which code, and the logs a resume must trim."""

from __future__ import annotations

import csv
import platform
import shlex
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3.common.logger import CSVOutputFormat

import rover_env
from rover_env.training.callbacks import checkpoint_algo


def git_commit() -> str | None:
    """Commit of the checkout the package runs from (``+dirty`` if modified), or None."""
    src = Path(rover_env.__file__).resolve().parent.parent
    try:
        head = subprocess.run(
            ["git", "-C", str(src), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(src), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "") if head else None


def record_command(run_dir: Path, entry: dict[str, Any]) -> None:
    """Append one invocation to ``command.txt`` (a YAML list, so resumes stack up readably)."""
    import stable_baselines3
    import torch

    full = {
        "argv": shlex.join([Path(sys.executable).name, *sys.argv]),
        **entry,
        "rover_env_version": rover_env.__version__,
        "git_commit": git_commit() or "unavailable",
        "python": platform.python_version(),
        "stable_baselines3": str(stable_baselines3.__version__),
        "torch": str(torch.__version__),
        "host": platform.node(),
        "time_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
    }
    with (run_dir / "command.txt").open("a") as fh:
        fh.write(yaml.safe_dump([full], sort_keys=False))


def read_commands(run_dir: Path) -> list[dict[str, Any]]:
    path = run_dir / "command.txt"
    if not path.is_file():
        return []
    data = yaml.safe_load(path.read_text())
    return list(data) if isinstance(data, list) else []


class ResumedCSV(CSVOutputFormat):
    """SB3's ``progress.csv`` writer that keeps the rows logged up to the resumed checkpoint.

    The stock writer truncates the file, which would lose the first part of a resumed run.
    """

    def __init__(self, filename: str, keep_until: int | None) -> None:
        path = Path(filename)
        old = path.read_text().splitlines() if keep_until is not None and path.is_file() else []
        super().__init__(filename)
        if not old:
            return
        header = next(csv.reader([old[0]]))
        col = header.index("time/total_timesteps") if "time/total_timesteps" in header else None
        kept = [old[0]]
        for line in old[1:]:
            row = next(csv.reader([line]), [])
            try:
                step = float(row[col]) if col is not None else 0.0
            except (IndexError, ValueError):
                step = 0.0
            if keep_until is not None and step <= keep_until:
                kept.append(line)
        self.file.write("\n".join(kept) + "\n")
        self.file.flush()
        self.keys = header


def run_algo(run_dir: Path) -> str:
    """The algorithm of a run dir: command.txt's ``algo`` (runs before SAC/TD3: ppo), else
    the checkpoints' names."""
    commands = read_commands(run_dir)
    if commands and commands[0].get("algo"):
        return str(commands[0]["algo"])
    return checkpoint_algo(run_dir / "checkpoints") or "ppo"
