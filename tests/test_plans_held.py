"""A proposed drive the logs already hold is not asked for again (:mod:`rover_env.calibration.plans_held`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration.diagnosis.split import split
from rover_env.calibration.diagnosis.state import Diagnosis, Options
from rover_env.calibration.drive_plan import command_rows
from rover_env.calibration.evidence import PLAN_DURATION, PLAN_SEED
from rover_env.calibration.plans_held import ask, held_plans, held_text, match
from rover_env.calibration.report import tie_text
from rover_env.config import load_rover
from rover_env.logs import DriveLog, LogMeta, write_log

VMAX = load_rover("proto_explorer").motor.max_wheel_speed
R = load_rover("proto_explorer").geometry.wheel_radius


def driven(plan: str, seed: int, rate: float = 50.0, wait: float = 0.0, lag: int = 0) -> DriveLog:
    """A log whose targets are ``drive-plan``'s rows for (plan, seed), recorded at ``rate``
    after ``wait`` s of rest, each target seen ``lag`` samples late; wheels that turn as
    asked, the pose at 1 Hz straight ahead (no physics: only the commands are matched)."""
    rows_t, rows, _ = command_rows(plan, seed, PLAN_DURATION, VMAX, 50.0)
    t = np.arange(0.0, wait + PLAN_DURATION + 2.0, 1.0 / rate)
    k = np.clip(np.searchsorted(rows_t, t - wait, side="right") - 1 - lag, 0, len(rows) - 1)
    cmd = np.where((t >= wait)[:, None], rows[k], 0.0)
    front = np.cumsum(np.concatenate([[0.0], cmd[:-1, 0]]) / rate)
    phi = np.tile(front[:, None], (1, 6))
    pose = np.full((t.size, 3), np.nan)
    every = np.isclose(t % 1.0, 0.0) | np.isclose(t % 1.0, 1.0)
    pose[every] = np.column_stack([R * front[every], 0 * t[every], 0 * t[every]])
    meta = LogMeta(rover="proto_explorer", sample_rate_hz=rate, terrain="flat")
    return DriveLog(t, cmd, phi, np.zeros((t.size, 5)), pose, meta)


def test_a_log_holds_the_draw_it_drove_and_no_other() -> None:
    assert match(driven("reversals", 1), VMAX) == ("reversals", 1)
    assert match(driven("reversals", 0), VMAX) == ("reversals", 0)  # the pivot's length differs
    # recorded at 10 Hz, 3 s after the recording started, each target one sample late
    assert match(driven("steps", 2, rate=10.0, wait=3.0, lag=1), VMAX) == ("steps", 2)
    assert match(driven("steps", PLAN_SEED + 12), VMAX) is None  # a draw not looked for
    # The reversals plan draws only its pivot's length: draws 0.2 s apart are one drive to
    # a 10 Hz recorder, and the first that agrees is the one held.
    plan, seed = match(driven("reversals", 6, rate=10.0), VMAX) or ("", -1)
    assert plan == "reversals" and 0 <= seed < 6
    other = driven("accel", 0)
    other.cmd[: other.t.size // 3] *= 0.8  # a third of it driven otherwise: not that drive
    assert match(other, VMAX) is None
    short = driven("accel", 0)
    short.cmd[short.t > 0.8 * PLAN_DURATION] = 0.0  # stopped early
    assert match(short, VMAX) is None


def test_a_held_plan_asks_for_its_next_draw_and_says_so() -> None:
    held = held_plans([driven("reversals", 0), driven("straight", 0)], ["a.csv", "b.csv"], VMAX)
    assert held == {
        "reversals": [{"seed": 0, "log": "a.csv"}],
        "straight": [{"seed": 0, "log": "b.csv"}],
    }
    rec = ask({"plan": "reversals", "seed": PLAN_SEED, "duration": PLAN_DURATION}, held)
    assert rec["seed"] == PLAN_SEED + 1 and rec["held"] == [{"seed": 0, "log": "a.csv"}]
    assert "already hold this plan's draw seed 0 (a.csv)" in held_text(rec)
    fresh = ask({"plan": "steps", "seed": PLAN_SEED, "duration": PLAN_DURATION}, held)
    assert fresh["seed"] == PLAN_SEED and "held" not in fresh and held_text(fresh) == ""
    two = {"reversals": [{"seed": 0, "log": "a.csv"}, {"seed": 1, "log": "c.csv"}]}
    assert ask({"plan": "reversals"}, two)["seed"] == 2
    gap = {"reversals": [{"seed": 1, "log": "c.csv"}]}
    assert ask({"plan": "reversals"}, gap)["seed"] == 0  # the first draw not held
    tie = {
        "effects": ["slope", "rolling_resistance"],
        "held_gain": [0.3, 0.2],
        "p_winner_better": 0.2,
        "plan": "reversals",
        "why": "the same line both ways",
        "unseparated": None,
        "duration": PLAN_DURATION,
    }
    text = tie_text(ask(tie, held))
    assert "--plan reversals --seed 1 " in text and "already hold" in text
    bal = ask({"read": False, "runs": 3, "why_not": "few runs", "plan": "reversals"}, held)
    assert bal["seed"] == 1  # the balance's drive too (the report quotes it where read)


@pytest.mark.parametrize("seed", [0, 3])
def test_the_diagnosis_knows_which_draws_its_logs_hold(tmp_path: Path, seed: int) -> None:
    paths = []
    for i, (plan, s) in enumerate((("test", 40), ("test", 41), ("reversals", seed))):
        paths.append(write_log(driven(plan, s), tmp_path / f"drive_{i:02d}.csv"))
    d = Diagnosis([str(p) for p in paths], tmp_path / "out", Options(progress=False))
    split(d)
    assert d.held_plans == {"reversals": [{"seed": seed, "log": "drive_02.csv"}]}
    json.dumps(d.held_plans)  # as result.json writes it
    rec = ask({"read": True, "plan": "reversals", "duration": PLAN_DURATION}, d.held_plans)
    assert rec["seed"] == (1 if seed == 0 else 0)


def test_asked_drives_join_the_held_out_drive_and_training_stays(tmp_path: Path) -> None:
    """Stop 131: a drive a diagnosis asked for is held out beside the last of the user's
    own drives, not instead of it (block 54700's crossing drive, asked for a slope, took
    back command delays the user's held-out drive had confirmed)."""
    from rover_env.calibration.diagnosis.evidence_stage import held_out_logs
    from rover_env.calibration.diagnosis.split import held_out_indices as held_idx

    own = [("test", 40), ("test", 41), ("test", 42)]
    names = ["drive_00.csv", "drive_01.csv", "drive_02.csv", "a_asked.csv"]
    paths = [write_log(driven(p, s), tmp_path / n) for (p, s), n in zip(own, names, strict=False)]
    paths.append(write_log(driven("reversals", 0), tmp_path / names[3]))  # sorts first
    d = Diagnosis([str(p) for p in paths], tmp_path / "out", Options(progress=False))
    split(d)
    want = "training: drive_00.csv, drive_01.csv; held out: a_asked.csv (asked), drive_02.csv"
    assert d.split == want
    held = {d.files[w.log_index].name for w in d.held_w}
    assert held == {"a_asked.csv", "drive_02.csv"} == set(held_out_logs(d))
    assert {d.files[w.log_index].name for w in d.train_w} == {"drive_00.csv", "drive_01.csv"}
    # Without an asked drive, or with fewer than two own drives: the last log alone.
    assert held_idx(["a", "b", "c"], set()) == [2]
    assert held_idx(["a", "b"], {"b"}) == [1]
    assert held_idx(["a", "b", "c", "d"], {"b", "d"}) == [1, 2, 3]
    # --interleave: every log alternates its windows, as before.
    d = Diagnosis(
        [str(p) for p in paths], tmp_path / "o2", Options(progress=False, interleave=True)
    )
    split(d)
    assert d.split.startswith("every log") and held_out_logs(d) == ()
