"""rover-env drive-plan: a proposed drive as commands for the real rover (CSV, ROS 2 bag, note)."""

from __future__ import annotations

import argparse
import importlib.util
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rover_env.calibration import drive_plan as dp
from rover_env.config import load_rover
from rover_env.generators.drives import _PLANS, drive_schedule

CFG = load_rover("proto_explorer")
VMAX = CFG.motor.max_wheel_speed


def _run(argv: list[str]) -> int:
    """The subcommand through its own parser (rover_env.cli also needs rover_env.bags)."""
    parser = argparse.ArgumentParser()
    dp.add_cli(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return int(args.func(args))


def _bag(path: Path) -> tuple[list[str], list[int], list[Any]]:
    from rosbags.highlevel import AnyReader

    topics, stamps, msgs = [], [], []
    with AnyReader([path]) as reader:
        for conn, ns, raw in reader.messages():
            topics.append(conn.topic)
            stamps.append(ns)
            msgs.append(reader.deserialize(raw, conn.msgtype))
    return topics, stamps, msgs


@pytest.mark.parametrize("plan", ["straight", "test"])
def test_csv_rows_are_the_schedule_and_end_in_a_stop(tmp_path: Path, plan: str) -> None:
    """Every row before the end is drive_schedule at its time, to the bit (clipped to the
    rover's max_wheel_speed as the simulator clips it; `straight` never reaches it); the
    last row, at t = duration, is a stop."""
    assert _run(["drive-plan", "--plan", plan, "--seed", "3", "--duration", "7.3",
                 "--out", str(tmp_path)]) == 0  # fmt: skip
    t, cmd = dp.read_csv(tmp_path / f"{plan}.csv")
    sched = drive_schedule(plan, np.random.default_rng(3), 7.3, VMAX)
    assert len(t) == 365 + 1 and t[-1] == 7.3
    np.testing.assert_array_equal(t[:-1], np.arange(365) / 50.0)
    want = np.array([sched(float(tk)) for tk in t[:-1]])
    if plan == "straight":
        assert np.abs(want).max() < VMAX
    else:
        assert np.abs(want).max() > VMAX  # the test plan asks for more: clipped
    np.testing.assert_array_equal(cmd[:-1], np.clip(want, -VMAX, VMAX))
    np.testing.assert_array_equal(cmd[-1], np.zeros(4))


@pytest.mark.parametrize("msg", ["float64_multi_array", "joint_state"])
@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_bag_messages_are_the_csv_rows_at_the_rate(tmp_path: Path, msg: str, storage: str) -> None:
    names = "1L=fl_wheel,1R=fr_wheel,2L=ml_wheel,2R=mr_wheel"
    argv = ["drive-plan", "--plan", "steps", "--seed", "1", "--duration", "6", "--rate", "40",
            "--out", str(tmp_path), "--topic", "/rover/wheel_cmd", "--msg", msg,
            "--joint-names", names, "--storage", storage]  # fmt: skip
    assert _run(argv) == 0
    t, cmd = dp.read_csv(tmp_path / "steps.csv")
    topics, stamps, msgs = _bag(tmp_path / "steps_bag")
    assert set(topics) == {"/rover/wheel_cmd"} and len(msgs) == len(t) == 241
    assert np.all(np.diff(stamps) == 25_000_000)  # 40 Hz, one message per row
    assert stamps[0] == 0 and stamps[-1] == 6 * 10**9
    wheels = ["fl_wheel", "fr_wheel", "ml_wheel", "mr_wheel"]
    for m, row in zip(msgs, cmd, strict=True):
        if msg == "joint_state":
            assert list(m.name) == wheels and len(m.position) == 0
            np.testing.assert_array_equal(m.velocity, row)
        else:
            assert m.layout.dim[0].label == ",".join(wheels) and m.layout.dim[0].size == 4
            np.testing.assert_array_equal(m.data, row)
    if msg == "joint_state":
        assert msgs[7].header.stamp.sec * 10**9 + msgs[7].header.stamp.nanosec == stamps[7]


def test_driven_in_simulation_the_log_carries_the_plans_commands(tmp_path: Path) -> None:
    """The CSV fed to the simulator (zero-order hold) is logged back exactly."""
    from rover_env.sim.recorder import run_drive
    from rover_env.sim.simulator import RoverSim

    assert _run(["drive-plan", "--plan", "turn-accel", "--seed", "2", "--duration", "6",
                 "--out", str(tmp_path)]) == 0  # fmt: skip
    t, cmd = dp.read_csv(tmp_path / "turn-accel.csv")

    def hold(tt: float) -> np.ndarray:
        return cmd[int(np.searchsorted(t, tt + 1e-9, side="right")) - 1]

    sim = RoverSim(CFG, "flat", backend="auto")
    sim.reset()
    log = run_drive(sim, hold, 6.0, sample_rate_hz=50.0).to_log("proto_explorer")
    np.testing.assert_allclose(log.t, t, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(log.cmd, cmd)
    assert np.ptp(log.cmd[:, 0]) > 1.0  # a drive, not a standstill


def test_ground_of_the_straight_is_the_integral_of_its_segments() -> None:
    """The straight's farthest excursion is the largest partial sum of its segments'
    travel (forward runs and back), within one sample per segment change."""
    duration, rate = 20.0, 50.0
    t, cmd, _ = dp.command_rows("straight", 5, duration, VMAX, rate)
    g = dp.ground(t, cmd, CFG.geometry)
    segs = _PLANS["straight"](np.random.default_rng(5), VMAX)
    scale = duration / sum(d for d, _ in segs)
    r = CFG.geometry.wheel_radius
    pos = np.cumsum([d * scale * r * 0.5 * (lw + rw) for d, (lw, rw) in segs])
    tol = len(segs) * r * VMAX / rate
    assert g["farthest_m"] == pytest.approx(pos.max(), abs=tol)
    assert g["x_max"] == pytest.approx(pos.max(), abs=tol) and g["x_min"] > -tol
    assert g["y_min"] == g["y_max"] == 0.0 and g["turned_deg"] == 0.0
    assert g["farthest_m"] > 0.5


def test_ground_of_a_pivot_and_an_arc() -> None:
    """Pure rotation stays at the origin; a constant turn draws its circle exactly."""
    rate, v = 50.0, 2.0
    t = np.arange(501) / rate  # 10 s
    pivot = np.tile([-v, v, -v, v], (501, 1))
    g = dp.ground(t, pivot, CFG.geometry)
    assert g["farthest_m"] < 1e-12
    assert g["turned_deg"] == pytest.approx(np.degrees(10 * CFG.geometry.wheel_radius * v / 0.225))
    arc = np.tile([1.0, 3.0, 1.0, 3.0], (501, 1))
    g = dp.ground(t, arc, CFG.geometry)
    r = CFG.geometry.wheel_radius
    radius = (r * 2.0) / (r * 2.0 / 0.45)
    assert g["y_max"] == pytest.approx(2 * radius, rel=1e-4)  # 10 s: more than half a turn
    assert g["farthest_m"] == pytest.approx(2 * radius, rel=1e-4)


def _tie() -> dict[str, Any]:
    return {
        "effects": ["slope", "rolling_resistance"],
        "p_winner_better": 0.3,
        "held_gain": [0.4, 0.38],
        "plan": "reversals",
        "why": "a slope helps one way",
        "seed": 4,
        "duration": 6.0,
    }


def _evidence() -> dict[str, Any]:
    return {
        "effect": "torque_limit",
        "plan": "accel",
        "why": "hard accelerations",
        "reason": "the held-out drive does not excite it",
        "seed": 0,
        "duration": 5.0,
        "best_signal": "wheel_1L",
        "best_per_window": 4.0,
        "best_floor_units": 20.0,
        "held_out_best_signal": "wheel_1L",
        "held_out_floor_units": 0.2,
        "separates": True,
    }


def test_report_text_says_drive_it_never_simulate_it() -> None:
    from rover_env.calibration.report import evidence_lines, tie_text

    tie = tie_text(_tie())
    assert "rover-env drive-plan --plan reversals --seed 4 --duration 6 --out DIR" in tie
    ev = "\n".join(evidence_lines([_evidence()]))
    assert "rover-env drive-plan --plan accel --seed 0 --duration 5 --out DIR" in ev
    for text in (tie, ev):
        assert "make-logs" not in text
        assert "rover-env drive-plan --report OUT --out DIR" in text
        assert "rover-env import-bag" in text and "held out beside your last own drive" in text
    assert evidence_lines([]) == []
    # a result from before the seed and duration were recorded: diagnose's convention
    old = {k: v for k, v in _tie().items() if k not in ("seed", "duration")}
    assert "--seed 0 --duration 50 " in tie_text(old)


def test_evidence_and_tie_record_the_seed_and_duration(monkeypatch: pytest.MonkeyPatch) -> None:
    from rover_env.calibration import evidence

    monkeypatch.setattr(evidence, "simulate_plan", lambda *a, **k: None)
    monkeypatch.setattr(evidence, "replay_separation", lambda *a, **k: ({}, {}))
    p = evidence.propose(CFG, "torque_limit", {}, {}, {}, seed=3, duration=7.0)
    assert (p["plan"], p["seed"], p["duration"]) == ("accel", 3, 7.0)
    src = (Path(evidence.__file__).parent / "diagnosis" / "tie.py").read_text()  # the tie
    assert '"seed": PLAN_SEED' in src and '"duration": PLAN_DURATION' in src


def test_report_mode_writes_every_proposed_drive(tmp_path: Path) -> None:
    res = tmp_path / "diag"
    res.mkdir()
    ev2 = _evidence() | {"effect": "slope", "plan": "reversals", "seed": 4, "duration": 6.0}
    (res / "result.json").write_text(json.dumps({"tie": _tie(), "evidence": [_evidence(), ev2]}))
    out = tmp_path / "plans"
    assert _run(["drive-plan", "--report", str(res), "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "accel.csv", "accel.md", "accel_bag", "reversals.csv", "reversals.md", "reversals_bag",
    ]  # fmt: skip
    t, _ = dp.read_csv(out / "reversals.csv")
    assert t[-1] == 6.0 and len(t) == 301
    t, _ = dp.read_csv(out / "accel.csv")
    assert t[-1] == 5.0
    md = (out / "reversals.md").read_text()
    assert "tie between slope and rolling_resistance" in md and "evidence for slope" in md
    assert "seed 4, 6 s" in md and "slope in question" in md
    assert "rover-env import-bag" in md and "beside your last own drive" in md
    assert "slope in question" not in (out / "accel.md").read_text()
    # the same again (into the same folder) replaces the files
    assert _run(["drive-plan", "--report", str(res / "result.json"), "--out", str(out)]) == 0


def test_bad_input_is_one_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = str(tmp_path / "o")
    cases = [
        (["--plan", "zigzag"], "unknown plan 'zigzag'"),
        (["--plan", "steps", "--joint-names", "1L=a,1R=b,2L=c"], "wheel(s) 2R"),
        (["--plan", "steps", "--joint-names", "1L=a,1R=b,2L=c,3R=d"], "'3R' is not a driven"),
        (["--plan", "steps", "--joint-names", "1L=a,1R=a,2L=c,2R=d"], "share a joint name"),
        (["--plan", "steps", "--topic", "wheel cmds"], "--topic"),
        (["--plan", "steps", "--duration", "-1"], "--duration"),
        (["--report", str(tmp_path)], "no diagnose result"),
    ]
    for extra, what in cases:
        assert _run(["drive-plan", *extra, "--out", out]) == 2, extra
        err = capsys.readouterr().err
        assert "drive-plan: error:" in err and what in err, (extra, err)
    (tmp_path / "result.json").write_text(json.dumps({"tie": None, "evidence": []}))
    assert _run(["drive-plan", "--report", str(tmp_path), "--out", out]) == 2
    assert "proposes no drive" in capsys.readouterr().err
    (tmp_path / "result.json").write_text(json.dumps({"tie": _tie()}))
    assert _run(["drive-plan", "--report", str(tmp_path), "--seed", "1", "--out", out]) == 2
    assert "come from the report" in capsys.readouterr().err
    assert not Path(out).exists() or not any(Path(out).iterdir())


@pytest.mark.skipif(
    importlib.util.find_spec("rover_env.bags") is None, reason="rover_env.bags not there yet"
)
def test_cli_main(tmp_path: Path) -> None:
    from rover_env.cli import main

    out = tmp_path / "o"
    assert main(["drive-plan", "--plan", "accel", "--duration", "5", "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == {"accel.csv", "accel.md", "accel_bag"}
    assert main(["drive-plan", "--plan", "nope", "--out", str(out)]) == 2


def test_untested_drives_are_read_unless_left_out(tmp_path: Path) -> None:
    """The drive for what the logs never tested (stop 59: an unreached torque limit) is a
    proposal drive-plan writes; the benchmark leaves it out (``untested=False``)."""
    untested = _evidence() | {
        "reason": "these drives reach the motors' limit for only cuts beyond 30 %"
    }
    (tmp_path / "result.json").write_text(
        json.dumps({"tie": None, "evidence": [], "untested": [untested]})
    )
    (prop,) = dp.proposals_from_report(tmp_path)
    assert prop.plan == "accel" and prop.effects == {"torque_limit"}
    assert "untested torque_limit" in prop.why[0] and "beyond 30 %" in prop.why[0]
    with pytest.raises(dp.DrivePlanError, match="nothing untested"):
        dp.proposals_from_report(tmp_path, untested=False)
