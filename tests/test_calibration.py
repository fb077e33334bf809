"""Model extensions, hidden-effect logs and the discrepancy diagnosis (issue 8), fast subset."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from rover_env.calibration.diagnose import Options, diagnose
from rover_env.calibration.diagnosis.judge import noise_test
from rover_env.calibration.replay import ReplaySettings, replay_config
from rover_env.cli import main
from rover_env.config import ConfigError, RoverConfig, load_rover, to_dict
from rover_env.effects import CATALOGUE, CombinedSlip
from rover_env.generators.make_logs import make_logs, parse_effects
from rover_env.logs import LogError, read_log
from rover_env.sim.simulator import RoverSim


def _drive(ext: dict, cmd: tuple[float, ...], seconds: float, backend: str = "auto") -> RoverSim:
    sim = RoverSim(RoverConfig(extensions=ext), backend=backend)
    sim.set_speed_targets(cmd)
    sim.step(round(seconds / sim.dt))
    return sim


def _speed(sim: RoverSim) -> float:
    return float(sim.segment_truth().forward_speed[2])


STRAIGHT = (2.0, 2.0, 2.0, 2.0)
TURN = (1.0, 3.0, 1.0, 3.0)
PIVOT = (-3.0, 3.0, -3.0, 3.0)


@pytest.mark.parametrize(
    ("ext", "cmd", "seconds", "metric", "sign"),
    [
        ({"rolling_resistance": {"c_rr": 0.05}}, STRAIGHT, 2.0, "speed", -1),
        ({"slope": {"deg": 5.0}}, STRAIGHT, 2.0, "speed", -1),  # uphill: the ground rises to +x
        ({"slope": {"deg": 5.0, "heading_deg": 180.0}}, STRAIGHT, 2.0, "speed", +1),
        ({"rolling_radius": {"fraction": -0.08}}, STRAIGHT, 2.0, "speed", -1),
        ({"torque_limit": {"fraction": -0.5}}, (4.0, 4.0, 4.0, 4.0), 0.02, "torque", -1),
        ({"command_lag": {"tau": 0.3}}, STRAIGHT, 0.5, "wheel", -1),
        ({"command_delay": {"delay": 0.2}}, STRAIGHT, 0.5, "wheel", -1),
        ({"friction": {"fraction": -0.3}}, TURN, 2.0, "free_diff", +1),  # skid steer turns easier
        ({"combined_slip": {"on": 1.0}}, TURN, 1.0, "free_diff", +1),
        ({"load_dependent_friction": {"fall": 0.3}}, PIVOT, 1.0, "free_diff", 0),
        ({"loose_soil": {"k_phi": 1.5e6}}, STRAIGHT, 2.0, "torque", +1),  # compaction resists
    ],
)
def test_effects_act_in_the_expected_direction(
    ext: dict, cmd: tuple[float, ...], seconds: float, metric: str, sign: int
) -> None:
    def value(sim: RoverSim) -> float:
        if metric == "speed":
            return _speed(sim)
        if metric == "torque":
            return float(np.abs(sim.motor_torque()).max())
        s = sim.sensors()
        if metric == "wheel":
            return float(s.phi[:4].mean())
        return float(s.phi[5] - s.phi[4])  # free wheels' difference: how much it turned

    off = value(_drive({}, cmd, seconds))
    on = value(_drive(ext, cmd, seconds))
    if sign:  # 0: the direction is not obvious, only that it acts
        assert np.sign(on - off) == sign, (off, on)
    assert abs(on - off) > 1e-3 * max(abs(off), 1e-3)


def test_off_values_change_nothing() -> None:
    ext = {name: {} for name in CATALOGUE}  # every effect at its "off" value
    a = _drive({}, TURN, 0.3, backend="numpy")
    b = _drive(ext, TURN, 0.3, backend="numpy")
    assert np.array_equal(a.data.qpos, b.data.qpos)


def test_plugin_runs_every_catalogue_effect_and_refuses_what_it_cannot(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    sim = RoverSim(RoverConfig(extensions={"friction": {"fraction": -0.3}}), backend="plugin")
    assert sim.backend == "plugin"
    cfg = RoverConfig(extensions={"combined_slip": {"on": 1.0}})
    assert RoverSim(cfg, backend="auto").backend == "plugin"
    # A tire effect without a compiled twin (plugin_ok False) is refused by name.
    monkeypatch.setattr(CombinedSlip, "plugin_ok", False)
    with pytest.raises(NotImplementedError, match="combined_slip"):
        RoverSim(cfg, backend="plugin")
    assert RoverSim(cfg, backend="auto").backend == "numpy"
    # Command effects on the plugin equal the numpy reference (same substep rule).
    lag = {"command_lag": {"tau": 0.2}}
    p = _drive(lag, STRAIGHT, 0.4, backend="plugin").sensors().phi
    n = _drive(lag, STRAIGHT, 0.4, backend="numpy").sensors().phi
    np.testing.assert_allclose(p, n, atol=1e-9)


def test_extensions_config_round_trip(tmp_path: Path) -> None:
    cfg = RoverConfig(
        extensions={"slope": {"deg": 3.0, "heading_deg": 45.0}, "command_lag": {"tau": 0.2}}
    )
    path = tmp_path / "rover.yaml"
    path.write_text(yaml.safe_dump(to_dict(cfg)))
    back = load_rover(path)
    assert back.extensions == cfg.extensions
    assert back == cfg
    for bad, key in [
        ({"slope": {"deg": 90.0}}, "extensions.slope.deg"),
        ({"slope": {"tilt": 1.0}}, "extensions.slope"),
        ({"sand": {"depth": 1.0}}, "sand"),
        ({"combined_slip": {"on": 0.5}}, "extensions.combined_slip.on"),
    ]:
        path.write_text(yaml.safe_dump({"extensions": bad}))
        with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
            load_rover(path)


def test_parse_effects() -> None:
    assert parse_effects(["rolling_resistance=0.05", "slope.heading_deg=90", "slope=5"]) == {
        "rolling_resistance": {"c_rr": 0.05},
        "slope": {"heading_deg": 90.0, "deg": 5.0},
    }
    assert parse_effects(["combined_slip=on"]) == {"combined_slip": {"on": 1.0}}
    with pytest.raises(ConfigError, match="unknown model extension"):
        parse_effects(["sand=1"])


@pytest.fixture(scope="module")
def rr_case(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """A small hidden-effect case diagnosed once: rolling resistance 0.05, 2 drives x 24 s."""
    root = tmp_path_factory.mktemp("rr")
    result = _small_case(root, {"rolling_resistance": {"c_rr": 0.05}}, 5, SMALL_CANDIDATES)
    return root, result


SMALL_CANDIDATES = ["rolling_resistance", "torque_limit", "command_lag"]


def _small_case(root: Path, effects: dict, seed: int, candidates: list[str]) -> dict:
    """``effects`` hidden in 2 drives of 24 s (``root/logs``), diagnosed (``root/out``)."""
    paths = make_logs(root / "logs", effects, drives=2, seed=seed, duration=24.0, progress=False)
    opts = Options(candidates=candidates, progress=False, max_nfev=3)
    return diagnose([str(p) for p in paths], root / "out", opts)


def _window_results(ms: list[float], signal: int, seed: int) -> list:
    """Synthetic held-out windows: white residuals, one signal at the given mean squares
    (each window's within 10 %)."""
    from rover_env.calibration.replay import Window, WindowResult

    rng = np.random.default_rng(seed)
    out = []
    for i, m in enumerate(ms):
        resid = 1e-3 * rng.standard_normal((20, 11))
        resid[:, signal] = (
            np.sqrt(m) * np.resize([1.0, -1.0], 20) * (1 + 0.05 * rng.standard_normal(20))
        )
        w = Window(0, i, i + 150)
        out.append(WindowResult(w, np.arange(20), resid, resid, np.zeros(0, np.intp),
                                np.zeros((0, 3)), np.zeros((0, 3))))  # fmt: skip
    return out


def test_traded_signals_are_those_left_above_the_floor_and_made_worse() -> None:
    """A signal made worse in every window is traded only if it stays above its floor (in
    ``left``); one equal before and after, window by window up to noise, is not."""
    from rover_env.calibration.diagnosis.judge import traded_signals

    before = _window_results([1e-4] * 12, 9, 0)
    worse = _window_results([1.5e-4] * 12, 9, 1)
    same = _window_results([1e-4] * 12, 9, 2)
    got = traded_signals(before, worse, ["theta_4"], 0.01)
    assert list(got) == ["theta_4"] and got["theta_4"]["rms_ratio"] > 1.1, got
    assert traded_signals(before, worse, [], 0.01) == {}  # at its floor: may move
    assert traded_signals(before, same, ["theta_4"], 0.01) == {}
    assert traded_signals(worse, before, ["theta_4"], 0.01) == {}  # better is no trade
    # A consistent but immaterial worsening (0.5 % RMS) is no trade at naming's 10 % bar.
    slight = _window_results([1e-4 * 1.01] * 12, 9, 0)
    assert list(traded_signals(before, slight, ["theta_4"], 0.01)) == ["theta_4"]
    assert traded_signals(before, slight, ["theta_4"], 0.01, 1.1) == {}
    assert list(traded_signals(before, worse, ["theta_4"], 0.01, 1.1)) == ["theta_4"]


def test_a_trade_is_weighed_against_what_the_other_signals_gained() -> None:
    """The trade's share: what the traded signal lost over what the rest gained, each in
    units of its floor. A wheel from 1 to 0.01 (floor 0.1) against a joint from 1e-4 to 2e-4
    (floor 0.01): lost 1 per window, gained 99, share 1/99; gaining nothing is infinite."""
    from rover_env.calibration.diagnosis.judge import trade_share
    from rover_env.calibration.replay import SIGNALS, Window, WindowResult

    def windows(wheel: float, joint: float) -> list:
        resid = np.zeros((20, 11))
        resid[:, 0] = np.sqrt(wheel) * np.resize([1.0, -1.0], 20)
        resid[:, 9] = np.sqrt(joint) * np.resize([1.0, -1.0], 20)
        none, pose = np.zeros(0, np.intp), np.zeros((0, 3))
        return [
            WindowResult(Window(0, i, i + 150), np.arange(20), resid, resid, none, pose, pose)
            for i in range(12)
        ]

    floor = dict.fromkeys(SIGNALS, 1.0) | {"wheel_1L": 0.1, "theta_4": 0.01}
    worse = {"theta_4": {"rms_ratio": 1.41, "p": 1e-4, "windows": 12}}
    share = trade_share(windows(1.0, 1e-4), windows(0.01, 2e-4), worse, floor)
    assert share == pytest.approx(1 / 99, rel=1e-9)
    assert trade_share(windows(1.0, 1e-4), windows(1.0, 2e-4), worse, floor) == math.inf


def test_a_pair_that_trades_keeps_its_winner_if_the_winner_alone_does_not() -> None:
    """The trade test on a named pair: the partner is dropped when the winner alone trades
    nothing; when the winner trades too, the pair is returned as it is (left unnamed by the
    caller); a single winner is never split."""
    from types import SimpleNamespace

    from rover_env.calibration.diagnosis.select import settle_trades

    def sc(name: str) -> Any:
        return SimpleNamespace(fit=SimpleNamespace(name=name))

    win, pair = sc("command_lag"), sc("command_lag + friction")
    bad = {"theta_4": {"rms_ratio": 1.2, "p": 1e-4, "windows": 12}}
    floor = {"theta_4": 1.0}

    def trades_pair_only(ch: list) -> tuple[dict, dict]:
        return (bad if ch == [pair] else {}), floor

    chosen, worse, dropped, _ = settle_trades([pair], win, trades_pair_only)
    assert (
        chosen == [win]
        and worse == {}
        and dropped
        == {
            "effects": "command_lag + friction",
            "worse": bad,
        }
    )
    chosen, worse, dropped, _ = settle_trades([pair], win, lambda ch: (bad, floor))
    assert chosen == [pair] and worse == bad and dropped is None
    chosen, worse, dropped, _ = settle_trades([win], win, lambda ch: (bad, floor))
    assert chosen == [win] and worse == bad and dropped is None
    assert settle_trades([], None, lambda ch: (bad, floor)) == ([], {}, None, None)


def test_parallel_candidate_fits_give_the_same_diagnosis(rr_case: tuple[Path, dict]) -> None:
    root, result = rr_case
    paths = sorted((root / "logs").glob("drive_*.csv"))
    opts = Options(candidates=SMALL_CANDIDATES, progress=False, max_nfev=3, workers=2)
    again = diagnose([str(p) for p in paths], root / "out_parallel", opts)
    assert again["named"] == result["named"]
    for key in ("fits", "final"):
        assert json.dumps(
            {k: v["params"] for k, v in again[key].items()}, sort_keys=True
        ) == json.dumps({k: v["params"] for k, v in result[key].items()}, sort_keys=True)
    assert again["main_reduction"] == result["main_reduction"]


def test_replays_split_over_processes_are_the_same_to_the_bit(
    rr_case: tuple[Path, dict],
) -> None:
    """``parallel_replays``: each window starts from a full reset, so the windows a worker
    replays give the numbers they give in order in one process (a hinge effect's update
    phase and a command effect's memory included), and as with MuJoCo's sensor stage on."""
    from rover_env.calibration.replay import (
        Replayer,
        make_windows,
        parallel_replays,
        prepare,
        replay_arrays,
    )

    root, _ = rr_case
    st = ReplaySettings()
    logs = [read_log(p) for p in sorted((root / "logs").glob("drive_*.csv"))]
    prepared = [prepare(lg, RoverConfig(), f"d{i}", st) for i, lg in enumerate(logs)]
    windows = make_windows(prepared, st)[::2]
    ext = {"rolling_resistance": {"c_rr": 0.02}, "command_lag": {"tau": 0.1}}
    cfg = RoverConfig(extensions=ext)
    serial = replay_arrays(Replayer(cfg, st).run(prepared, windows))
    with parallel_replays(2):
        split = replay_arrays(Replayer(cfg, st).run(prepared, windows))
    assert serial["resid"].shape[0] > 50
    for k in serial:
        np.testing.assert_array_equal(split[k], serial[k], err_msg=k)
    # The replay's simulator runs without MuJoCo's sensor stage; with it, the same to the bit
    # (here with a hinge and a command effect, the substep-by-substep paths).
    with_sensors = replay_arrays(Replayer(cfg, st, sensors=True).run(prepared, windows))
    for k in serial:
        np.testing.assert_array_equal(with_sensors[k], serial[k], err_msg=k)
    # The evaluator replays a set's windows that another set replayed under the same model
    # from there: every other window first, then all of them, the same to the bit.
    from rover_env.calibration.evaluator import Evaluator

    ev = Evaluator(RoverConfig(), st, prepared, {"all": windows, "sub": windows[::2]})
    ev.run(ext, "sub")
    reused = replay_arrays(ev.run(ext, "all"))
    assert ev.replays == 2
    for k in serial:
        np.testing.assert_array_equal(reused[k], serial[k], err_msg=k)


def test_twins_simulated_side_by_side_are_the_same_to_the_bit(
    rr_case: tuple[Path, dict],
) -> None:
    """``residuals.twins_of``: each drive's twin is one simulation from rest, so run in the
    replay pool's other process it gives what it gives here (the replay floor's twins)."""
    from rover_env.calibration import residuals as rs
    from rover_env.calibration.replay import parallel_replays, prepare

    root, _ = rr_case
    st = ReplaySettings()
    logs = [read_log(p) for p in sorted((root / "logs").glob("drive_*.csv"))][:2]
    prepared = [prepare(lg, RoverConfig(), f"d{i}", st) for i, lg in enumerate(logs)]
    cfg = RoverConfig(extensions={"command_lag": {"tau": 0.1}})
    serial = rs.twins_of(prepared, cfg, {0, 1})
    with parallel_replays(2):
        side = rs.twins_of(prepared, cfg, {0, 1})
    assert sorted(side) == [0, 1]
    for i in (0, 1):
        for a, b in zip(side[i], serial[i], strict=True):
            np.testing.assert_array_equal(a, b)


def test_make_logs_writes_readable_logs_and_hidden_truth(rr_case: tuple[Path, dict]) -> None:
    root, _ = rr_case
    truth = yaml.safe_load((root / "logs" / "truth.yaml").read_text())
    assert truth["effects"] == {"rolling_resistance": {"c_rr": 0.05}}
    log = read_log(root / "logs" / "drive_00.csv")
    assert log.meta.rover == "proto_explorer"  # the logs name the nominal rover only
    have = np.isfinite(log.pose[:, 0])
    assert 20 <= have.sum() <= 30  # pose at 1 Hz
    assert np.any(log.cmd < 0) and np.any(log.cmd[:, 0] != log.cmd[:, 1])  # reversals, turns


def test_diagnose_names_a_moderate_effect(rr_case: tuple[Path, dict]) -> None:
    root, result = rr_case
    assert result["named"] == ["rolling_resistance"]
    value, lo, hi = result["final"]["rolling_resistance"]["params"]["rolling_resistance"]["c_rr"]
    assert abs(value - 0.05) < 0.2 * 0.05
    assert lo < hi
    assert result["main_reduction"] > 0.7
    report = (root / "out" / "report.md").read_text()
    assert "rolling_resistance" in report and "Named" in report
    assert "Each candidate is fitted alone" in report  # its interval is not the truth's
    for fig in ("residual_map.png", "candidates.png", "overlay.png"):
        assert (root / "out" / fig).stat().st_size > 1000


def test_updated_config_reproduces_the_held_out_replay_exactly(rr_case: tuple[Path, dict]) -> None:
    root, result = rr_case
    cfg_path = root / "out" / "rover.yaml"
    cfg = load_rover(cfg_path)
    assert cfg.extensions["rolling_resistance"]["c_rr"] > 0
    RoverSim(cfg_path)  # the simulator loads it as is
    saved = np.load(root / "out" / "replay_heldout.npz")
    held = read_log(Path(result["logs"][-1]))
    again = replay_config(cfg_path, [held], ReplaySettings())
    for key, arr in again.items():
        assert np.array_equal(arr, saved[f"after_{key}"]), key


def test_noise_floor_test_needs_a_cleared_signal_and_no_new_one() -> None:
    above = ["wheel_1L", "wheel_2R"]
    assert noise_test(above, ["wheel_2R"]) == ["wheel_1L"]
    assert noise_test(above, []) == above
    assert noise_test(above, above) == []  # nothing cleared
    assert noise_test(above, ["theta_2"]) == []  # clears both but breaks another signal
    assert noise_test([], []) == []  # a clean reference leaves nothing to clear


def test_bad_logs_fail_naming_file_column_and_row(
    rr_case: tuple[Path, dict], tmp_path: Path
) -> None:
    root, _ = rr_case
    src = root / "logs" / "drive_00.csv"
    lines = src.read_text().splitlines()
    header = lines[0].split(",")
    col = header.index("theta_3")
    row = lines[5].split(",")
    row[col] = "abc"
    lines[5] = ",".join(row)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    (tmp_path / "bad.yaml").write_text((root / "logs" / "drive_00.yaml").read_text())
    with pytest.raises(LogError) as err:
        diagnose([str(bad)], tmp_path / "out", Options(progress=False))
    msg = str(err.value)
    assert "bad.csv" in msg and "theta_3" in msg and "line 6" in msg
    # The command line reports it instead of a traceback.
    assert main(["diagnose", str(bad), "--out", str(tmp_path / "o2"), "--quiet"]) == 2


def test_make_logs_cli(tmp_path: Path) -> None:
    out = tmp_path / "logs"
    rc = main(
        [
            "make-logs",
            "--effect",
            "friction=-0.3",
            "--drives",
            "1",
            "--duration",
            "4",
            "--pose-end-only",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert rc == 0
    log = read_log(out / "drive_00.csv")
    assert np.isfinite(log.pose[:, 0]).sum() == 1  # the end only, as in the paper
    assert yaml.safe_load((out / "truth.yaml").read_text())["effects"] == {
        "friction": {"fraction": -0.3}
    }
    with pytest.raises(SystemExit):
        main(["make-logs", "--out", str(out), "--pose-rate", "2", "--pose-end-only"])


def test_environment_runs_with_extensions() -> None:
    import gymnasium as gym

    import rover_env

    gym.register_envs(rover_env)
    for ext, backend in [
        ({"slope": {"deg": 3.0}}, "plugin"),
        ({"combined_slip": {"on": 1.0}, "load_dependent_friction": {"fall": 0.3}}, "plugin"),
        ({"command_lag": {"tau": 0.2}}, "plugin"),  # per-substep targets: the numpy sample loop
    ]:
        env = gym.make("rover_env/ProtoExplorer-v0", rover=RoverConfig(extensions=ext))
        obs, _ = env.reset(seed=0)
        for _ in range(3):
            obs, *_ = env.step(env.action_space.sample())
        assert env.unwrapped.sim.backend == backend  # type: ignore[attr-defined]
        assert np.all(np.isfinite(obs))
        env.close()


def test_result_json_is_strict_json(rr_case: tuple[Path, dict]) -> None:
    root, _ = rr_case
    text = (root / "out" / "result.json").read_text()

    def refuse(name: str) -> None:
        raise AssertionError(f"result.json holds {name}: not JSON")

    data = json.loads(text, parse_constant=refuse)
    assert data["final"]["rolling_resistance"]["interval_method"] == "bootstrap"


def test_result_json_says_where_the_seconds_went(rr_case: tuple[Path, dict]) -> None:
    """Each pass's wall seconds per stage, in pipeline order, within the case's own seconds
    (which count every pass: a second pass carries on the first's clock)."""
    root, result = rr_case
    passes = result["stage_seconds"]
    assert len(passes) >= 1
    for p in passes[:-1]:
        assert list(p)[-1] == "again"  # a pass that ran again stops at the re-judgement
    last = list(passes[-1])
    assert last[:5] == ["split", "form", "floor", "fit", "winner"]
    assert last[-6:] == ["select", "odometry", "effort", "balance", "one_wheel", "evidence"]
    spent = sum(v for p in passes for v in p.values())
    assert all(v >= 0 for p in passes for v in p.values())
    assert 0.5 * result["seconds"] < spent <= result["seconds"]
    assert "by stage" in (root / "out" / "report.md").read_text()


@pytest.mark.parametrize(
    "name, values", [("command_lag", {"tau": 0.05}), ("command_delay", {"delay": 0.007})]
)
def test_command_effect_block_is_n_steps(name: str, values: dict[str, float]) -> None:
    """The replay's fast path for a held command (``command_rows``, the effect's
    ``sequence``) gives exactly what ``step`` gives, substep by substep, across commands
    that change between blocks; so does the generic ``CommandEffect.sequence``."""
    from rover_env.effects import CommandEffect, command_rows, effect_class

    a, b = effect_class(name)(values), effect_class(name)(values)
    assert isinstance(a, CommandEffect) and isinstance(b, CommandEffect)
    a.reset(np.zeros(4))
    b.reset(np.zeros(4))
    rng = np.random.default_rng(3)
    for n in (1, 4, 10, 3, 20):
        u = rng.uniform(-3, 3, 4)
        stepped = np.array([np.array(a.step(u, 0.001)) for _ in range(n)])
        held = np.tile(u, (n, 1))
        blocked = (
            CommandEffect.sequence(b, held, 0.001) if n == 3 else command_rows([b], u, 0.001, n)
        )
        np.testing.assert_array_equal(blocked, stepped, err_msg=f"{name}, block of {n}")
        # loop_commands averages a block's rows: summed in step()'s row order (C order)
        assert blocked.flags.c_contiguous, f"{name}, block of {n}"
        np.testing.assert_array_equal(blocked.mean(axis=0), stepped.mean(axis=0))
    assert np.any(stepped != u)  # the effect did act (not a pass-through that agrees trivially)


def test_tasks_handed_out_longest_first_come_back_in_task_order() -> None:
    """``map_parallel(order=...)`` (the soil's four forms go to a worker first): the order
    the tasks are handed out changes where they run, not which result is whose."""
    from rover_env.calibration.candidates import catalogue
    from rover_env.calibration.diagnosis.parallel import map_parallel
    from rover_env.calibration.diagnosis.state import Scored
    from rover_env.calibration.fit import Evaluator, Fit

    lag = catalogue(["command_lag"])[0]
    ev = Evaluator(RoverConfig(), ReplaySettings(), [], {}, log=lambda m: None)

    def task(i: int) -> Scored:
        z = np.array([float(i)])
        f = Fit([lag], z, z, z, z, float(i), 1, {"command_lag": {"tau": 0.01 * i}}, 0.0, "train")
        return Scored(f, float(i), z, 0.0, 1.0, 0.0, 0.0, 1)

    seen: list[float] = []
    out = map_parallel(
        task,
        lambda s: seen.append(s.fit.cost),
        3,
        lambda i: [lag],
        ev,
        Options(progress=False, workers=2),
        order=[2, 0, 1],
    )
    assert [s.fit.cost for s in out] == [0.0, 1.0, 2.0]
    assert [s.fit.ext["command_lag"]["tau"] for s in out] == [0.0, 0.01, 0.02]
    assert sorted(seen) == [0.0, 1.0, 2.0]


@pytest.mark.parametrize("bad", ["-0.1", "nan", "tenth"])
def test_a_bad_trade_share_is_refused_naming_the_flag(
    bad: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--trade-share`` takes a share of 0 or more; anything else stops before any log is
    read, with the flag and the value named."""
    with pytest.raises(SystemExit) as exit_:
        main(["diagnose", str(tmp_path / "none.csv"), "--out", str(tmp_path), "--trade-share", bad])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "--trade-share" in err and bad in err, err


@pytest.mark.parametrize("bad", ["-1", "1.5", "two"])
def test_a_bad_max_draws_is_refused_naming_the_flag(
    bad: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--max-draws`` takes a whole number of 0 or more (stop 130); anything else stops
    before any log is read, with the flag and the value named."""
    with pytest.raises(SystemExit) as exit_:
        main(["diagnose", str(tmp_path / "none.csv"), "--out", str(tmp_path), "--max-draws", bad])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "--max-draws" in err and bad in err, err


@pytest.mark.parametrize("bad", ["0", "1.5", "nan", "-0.05", "five percent"])
def test_a_bad_rotor_alpha_is_refused_naming_the_flag(
    bad: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--rotor-alpha`` takes a p level above 0 and at most 1; anything else stops before
    any log is read, with the flag and the value named."""
    with pytest.raises(SystemExit) as exit_:
        main(["diagnose", str(tmp_path / "none.csv"), "--out", str(tmp_path), "--rotor-alpha", bad])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "--rotor-alpha" in err and bad in err, err
