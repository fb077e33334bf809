"""A model's twin of a drive (``residuals.twin_states``), built and driven as a replay is,
gives the states of the sensed, row-by-row drive it replaced, to the bit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration import residuals as rs
from rover_env.calibration.ground import log_ground
from rover_env.calibration.replay import ReplaySettings, prepare
from rover_env.config import RoverConfig, TerrainConfig, load_rover
from rover_env.generators.drives import drive_schedule
from rover_env.logs import DriveLog, LogMeta, read_log, write_log
from rover_env.sim.model import stable_config
from rover_env.sim.recorder import relative_pose, run_drive
from rover_env.sim.simulator import RoverSim


def _sensed_twin(p: rs.PreparedLog, cfg: RoverConfig) -> rs.TwinStates:
    """The twin as it was made until stop 109: collisions and sensors on, one checked
    ``step`` per log row, the angles read through the sensors."""
    log = p.log
    sim = RoverSim(stable_config(cfg), log_ground(log), backend="auto", visuals=False)
    sim.reset()
    step_of = np.round(log.t / sim.dt).astype(np.int64)
    phi, theta, pos, quat = [], [], [], []
    for k in range(len(log)):
        s = sim.sensors()
        seg = sim.segment_truth()
        phi.append(s.phi)
        theta.append(s.theta)
        pos.append(seg.pos[2])
        quat.append(seg.quat[2])
        if k + 1 < len(log):
            sim.set_speed_targets(log.cmd[k])
            sim.step(int(step_of[k + 1] - step_of[k]))
    return np.array(phi), np.array(theta), relative_pose(np.array(pos), np.array(quat))


@pytest.fixture(scope="module")
def drives(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A 10 s drive with turns and stops on flat ground and one on regolith."""
    cfg = load_rover("proto_explorer")
    out = {}
    for name, terrain in (("flat", "flat"), ("soil", {"soil": "regolith"})):
        root = tmp_path_factory.mktemp(f"twin_{name}")
        sim = RoverSim(cfg, _ground(terrain), backend="auto")
        sim.reset()
        sched = drive_schedule("test", np.random.default_rng(7), 10.0, cfg.motor.max_wheel_speed)
        rec = run_drive(sim, sched, 10.0)
        out[name] = write_log(
            rec.to_log("proto_explorer", terrain=terrain),  # type: ignore[arg-type]
            root / "drive.csv",
        )
    return out


def _ground(terrain: object) -> TerrainConfig:
    """The ground a log declaring ``terrain`` is replayed on."""
    n = 2
    log = DriveLog(
        t=np.arange(n) / 50.0,
        cmd=np.zeros((n, 4)),
        phi=np.zeros((n, 6)),
        theta=np.zeros((n, 5)),
        pose=np.full((n, 3), np.nan),
        meta=LogMeta(rover="proto_explorer", sample_rate_hz=50.0, terrain=terrain),  # type: ignore[arg-type]
    )
    return log_ground(log)


@pytest.mark.parametrize(
    ("ground", "ext"),
    [
        ("flat", {}),
        ("flat", {"command_delay": {"delay": 0.08}}),
        ("flat", {"rolling_resistance": {"c_rr": 0.05}}),
        ("soil", {}),
    ],
    ids=["flat", "delay", "rolling_resistance", "soil"],
)
def test_the_twin_gives_the_sensed_drives_states_to_the_bit(
    drives: dict[str, Path], ground: str, ext: dict
) -> None:
    log = read_log(drives[ground])
    cfg = RoverConfig(extensions=ext)
    p = prepare(log, cfg, "drive.csv", ReplaySettings())
    got = rs.twin_states(p, cfg)
    want = _sensed_twin(p, cfg)
    assert np.ptp(want[0][:, 4]) > 1.0  # the free wheels turned: the drive moved
    for a, b, what in zip(got, want, ("wheels", "joints", "pose"), strict=True):
        assert a.shape == b.shape, what
        np.testing.assert_array_equal(a, b, err_msg=what)


def test_a_twin_made_again_comes_from_the_memo(drives: dict[str, Path]) -> None:
    """``twins_of`` answers the same log object under the same configuration from memory,
    read-only; an equal log read again, or another configuration, is twinned anew."""
    log = read_log(drives["flat"])
    cfg = RoverConfig()
    p = prepare(log, cfg, "drive.csv", ReplaySettings())
    first = rs.twins_of([p], cfg, {0})[0]
    again = rs.twins_of([p], cfg, {0})[0]
    assert all(a is b for a, b in zip(first, again, strict=True))
    assert not first[0].flags.writeable
    other = prepare(read_log(drives["flat"]), cfg, "drive.csv", ReplaySettings())
    anew = rs.twins_of([other], cfg, {0})[0]
    assert anew[0] is not first[0]
    np.testing.assert_array_equal(anew[0], first[0])
    lag = RoverConfig(extensions={"command_lag": {"tau": 0.2}})
    lagged = rs.twins_of([p], lag, {0})[0]
    assert lagged[0] is not first[0]
    assert not np.array_equal(lagged[0], first[0])
