"""A log's declared terrain is replayed, or refused with one clear error; never a silent flat.

SPEC §6 lets a log's YAML say what is known of the ground. Until issue 50 the calibration
replay ran every log on flat hard ground whatever it declared, so a drive up a slope was
"explained" by effects (a slope, friction, a torque limit) that were the declared ground.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration import residuals as rs
from rover_env.calibration.fit import Evaluator
from rover_env.calibration.ground import common_ground, log_ground
from rover_env.calibration.replay import ReplaySettings, make_windows, prepare
from rover_env.config import load_rover
from rover_env.generators.drives import drive_schedule
from rover_env.logs import DriveLog, LogError, LogMeta, read_log, write_log
from rover_env.sim.recorder import run_drive
from rover_env.sim.simulator import RoverSim


def _log(terrain: object, path: Path | None = None) -> DriveLog:
    n = 3
    log = DriveLog(
        t=np.arange(n) / 50.0,
        cmd=np.zeros((n, 4)),
        phi=np.zeros((n, 6)),
        theta=np.zeros((n, 5)),
        pose=np.full((n, 3), np.nan),
        meta=LogMeta(rover="proto_explorer", sample_rate_hz=50.0, terrain=terrain),  # type: ignore[arg-type]
    )
    if path is not None:
        write_log(log, path)
        return read_log(path)
    return log


def test_declared_grounds_are_read() -> None:
    assert log_ground(_log(None)).is_flat
    assert log_ground(_log("slope10")).slope_deg == (10.0, 0.0)
    assert log_ground(_log({"soil": "regolith"})).soil == "regolith"
    assert common_ground([_log(None), _log("flat")]) is None  # flat: the replay's default
    assert common_ground([_log({"slope_deg": [4.0, 0.0]})]) is not None


def test_a_terrain_path_is_read_beside_the_log(tmp_path: Path) -> None:
    (tmp_path / "hill.yaml").write_text("name: hill\nslope_deg: [3.0, 1.0]\n")
    log = _log("hill.yaml", tmp_path / "drive.csv")
    assert log_ground(log).slope_deg == (3.0, 1.0)


@pytest.mark.parametrize(
    ("terrain", "says"),
    [
        ("rough", "varies over the ground"),  # bumps, roughness, patches, rocks
        ("nowhere-land", "no shipped terrain configuration named 'nowhere-land'"),
        ({"slope_deg": [3.0, 0.0], "bumpiness": 1}, "unknown key(s) bumpiness"),
        ({"patches": [{"name": "ice", "center": [1, 0], "size": [1, 1], "mu_x": 0.1}]}, "ice"),
    ],
)
def test_a_ground_the_replay_cannot_honour_is_refused(
    tmp_path: Path, terrain: object, says: str
) -> None:
    log = _log(terrain, tmp_path / "drive.csv")
    with pytest.raises(LogError, match="key 'terrain'") as err:
        log_ground(log)
    assert says in str(err.value)
    assert str(tmp_path / "drive.yaml") in str(err.value)


def test_logs_on_different_grounds_are_refused_together(tmp_path: Path) -> None:
    a = _log(None, tmp_path / "a.csv")
    b = _log("slope10", tmp_path / "b.csv")
    with pytest.raises(LogError, match="differs from") as err:
        common_ground([a, b])
    assert str(tmp_path / "b.yaml") in str(err.value)


@pytest.mark.parametrize("terrain", ["slope10", {"soil": "regolith"}])
def test_a_log_replays_on_its_declared_ground(tmp_path: Path, terrain: str | dict) -> None:
    """A 12 s drive up and across the shipped 10 degree slope, or over regolith: replayed on
    the declared ground the free wheels follow the log (slope 0.004 rad RMS, soil 0.10 when
    measured); replayed flat (the old silent default) they are 1.5 and 0.8 rad off."""
    cfg = load_rover("proto_explorer")
    log = _log(terrain, tmp_path / "declared.csv")  # the simulator's ground: what it declares
    sim = RoverSim(cfg, log_ground(log), backend="auto")
    sim.reset()
    sched = drive_schedule("test", np.random.default_rng(5), 12.0, cfg.motor.max_wheel_speed)
    path = write_log(
        run_drive(sim, sched, 12.0).to_log("proto_explorer", terrain=terrain),  # type: ignore[arg-type]
        tmp_path / "drive.csv",
    )
    log = read_log(path)

    def free_wheel_rms(st: ReplaySettings) -> float:
        prep = [prepare(log, cfg, path.name, st)]
        ev = Evaluator(cfg, st, prep, {"all": make_windows(prep, st)}, log=lambda m: None)
        res = ev.run({}, "all")
        return float(np.sqrt(np.mean(np.concatenate([r.resid[:, 4:6] for r in res]) ** 2)))

    on_slope = free_wheel_rms(ReplaySettings(terrain=common_ground([log])))
    flat = free_wheel_rms(ReplaySettings())
    assert on_slope < 0.3 * flat, (on_slope, flat)
    # The floor's twin drives the declared ground too: it reproduces the log's free wheels.
    twin_phi = rs.twin_states(prepare(log, cfg, path.name, ReplaySettings()), cfg)[0]
    assert np.abs((twin_phi - twin_phi[0])[:, 4:] - log.phi[:, 4:]).max() < 0.05


def test_a_proposed_drive_is_simulated_on_the_declared_ground() -> None:
    """The evidence stage judges a proposed drive on the logs' ground, not on flat."""
    from rover_env.calibration.evidence import simulate_plan

    cfg = load_rover("proto_explorer")
    slope = log_ground(_log("slope10"))
    on_slope = simulate_plan(cfg, "accel", duration=4.0, ground=slope)
    flat = simulate_plan(cfg, "accel", duration=4.0)
    assert log_ground(on_slope).slope_deg == (10.0, 0.0)  # the log says where it was driven
    assert np.abs(on_slope.phi[:, 4:] - flat.phi[:, 4:]).max() > 0.1


def test_diagnose_refuses_a_ground_it_cannot_replay_before_any_fit(tmp_path: Path) -> None:
    """The refusal comes at diagnose's first stage, naming the log's YAML and the key."""
    from rover_env.calibration.diagnose import Options, diagnose

    paths = [tmp_path / "a.csv", tmp_path / "b.csv"]
    _log(None, paths[0])
    _log("rough", paths[1])
    with pytest.raises(LogError, match="key 'terrain'") as err:
        diagnose(paths, tmp_path / "out", Options(workers=1, progress=False))
    assert str(tmp_path / "b.yaml") in str(err.value)
