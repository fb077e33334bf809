"""Command effects computed at once (``CommandEffect.sequence``, ``RoverSim.drive``'s
commanded path, ``loop_commands``, ``CommandLag.prime``) give the numbers the substep-by-substep
definitions give, to the bit: a speed change must not change what ``diagnose`` finds."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from rover_env.calibration.replay import loop_commands
from rover_env.config import RoverConfig
from rover_env.effects import CommandEffect, build_effects, command_rows, command_sequence
from rover_env.logs import DriveLog, LogMeta
from rover_env.sim.simulator import RoverSim

EXTS = [
    {"command_lag": {"tau": 0.05}},
    {"command_delay": {"delay": 0.013}},
    {"command_lag": {"tau": 0.05}, "command_delay": {"delay": 0.013}},
]
IDS = ["lag", "delay", "both"]


def _effects(ext: dict[str, dict[str, float]]) -> list[CommandEffect]:
    out = [e for e in build_effects(ext) if isinstance(e, CommandEffect)]
    for e in out:
        e.reset(np.zeros(4))
    return out


@pytest.mark.parametrize("ext", EXTS, ids=IDS)
def test_sequence_is_step_by_step(ext: dict[str, dict[str, float]]) -> None:
    """Rows that change every substep and runs of held rows, in several calls, then a block:
    the sequence gives what ``step`` gives and leaves the same memory behind."""
    stepped, seq = _effects(ext), _effects(ext)
    rng = np.random.default_rng(5)
    dt = 0.002
    got, want, given = [], [], []
    for n in (3, 1, 17, 0, 40):
        rows = np.repeat(rng.uniform(-3, 3, (n, 4)), rng.integers(1, 4, n), axis=0)
        got.append(command_sequence(seq, rows, dt))
        given.append(rows)
        for u in rows:
            for e in stepped:
                u = e.step(u, dt)
            want.append(np.array(u))
    np.testing.assert_array_equal(np.concatenate(got), np.array(want))
    u = rng.uniform(-3, 3, 4)
    np.testing.assert_array_equal(command_rows(seq, u, dt, 9), command_rows(stepped, u, dt, 9))
    assert np.any(np.concatenate(got) != np.concatenate(given))  # the effect did act


@pytest.mark.parametrize("ext", EXTS, ids=IDS)
def test_drive_through_command_effects_is_row_by_row(ext: dict[str, dict[str, float]]) -> None:
    """``drive`` queues every substep's targets across rows; row by row (set the targets,
    one ``step`` each) moves the rover to the same state, across rows longer than the queue."""
    cfg = dataclasses.replace(RoverConfig(), extensions=ext)
    at_once, by_row = RoverSim(cfg, backend="plugin"), RoverSim(cfg, backend="plugin")
    plain = RoverSim(backend="plugin")
    rng = np.random.default_rng(9)
    targets = rng.uniform(-4, 4, (6, 4))
    steps = np.array([7, 90, 1, 0, 20, 33])
    at_once.drive(targets, steps)
    plain.drive(targets, steps)
    for u, n in zip(targets, steps, strict=True):
        by_row.set_speed_targets(u)
        by_row.step(int(n))
    for a in ("qpos", "qvel", "ctrl"):
        np.testing.assert_array_equal(getattr(at_once.data, a), getattr(by_row.data, a), a)
    np.testing.assert_array_equal(at_once.speed_targets, by_row.speed_targets)
    assert np.max(np.abs(plain.data.qpos[:3] - at_once.data.qpos[:3])) > 1e-4, "no effect"


def _log(t: np.ndarray, cmd: np.ndarray) -> DriveLog:
    n = len(t)
    return DriveLog(
        t=t,
        cmd=cmd,
        phi=np.zeros((n, 6)),
        theta=np.zeros((n, 5)),
        pose=np.full((n, 3), np.nan),
        meta=LogMeta(rover="proto_explorer", sample_rate_hz=50.0, terrain="flat"),
    )


@pytest.mark.parametrize("ext", EXTS, ids=IDS)
def test_loop_commands_average_each_interval_as_before(ext: dict[str, dict[str, float]]) -> None:
    """Each interval's mean of the effects' rows, intervals of uneven length included,
    equals ``command_rows`` interval by interval averaged with ``mean(axis=0)``."""
    rng = np.random.default_rng(2)
    t = np.cumsum(rng.choice([0.02, 0.02, 0.026, 0.014], 400))
    cmd = rng.uniform(-2, 2, (400, 4))
    cfg = dataclasses.replace(RoverConfig(), extensions=ext)
    dt = cfg.sim.timestep
    effects = _effects(ext)
    step_of = np.round(t / dt).astype(np.int64)
    want = cmd.copy()
    for k in range(len(t) - 1):
        n = int(step_of[k + 1] - step_of[k])
        want[k] = command_rows(effects, cmd[k], dt, n).mean(axis=0)
    got = loop_commands(_log(t, cmd), cfg)
    np.testing.assert_array_equal(got, want)
    assert np.any(got != cmd)


def _prime_by_sample(
    tau: float, t: np.ndarray, cmd: np.ndarray, t_now: float, dt: float
) -> np.ndarray:
    """CommandLag.prime's definition: the lag advanced over each sample's hold, in order."""
    x = [0.0] * 4
    for k in range(len(t)):
        if t[k] >= t_now - 1e-12:
            break
        t_end = min(t[k + 1] if k + 1 < len(t) else t_now, t_now)
        n = round((float(t_end) - float(t[k])) / dt)
        f = math.exp(-n * dt / tau)
        x = [float(c) + (xi - float(c)) * f for c, xi in zip(cmd[k], x, strict=True)]
    return np.array(x)


def test_lag_prime_is_sample_by_sample() -> None:
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.choice([0.02, 0.021, 0.0195], 300)) - 0.02
    cmd = rng.uniform(-2, 2, (300, 4))
    (lag,) = _effects({"command_lag": {"tau": 0.3}})
    for t_now in (0.0, 0.01, float(t[57]), float(t[57]) + 0.007, float(t[-1]) + 0.5):
        lag.prime(t, cmd, t_now, 0.002)
        np.testing.assert_array_equal(lag.x, _prime_by_sample(0.3, t, cmd, t_now, 0.002))
    assert np.any(lag.x != 0.0)


def test_the_compiled_lag_is_the_python_loop_to_the_bit(monkeypatch: pytest.MonkeyPatch) -> None:
    """``CommandLag.sequence`` and ``prime`` give the same numbers compiled (recursions.c)
    and on Python floats (``ROVER_ENV_NATIVE=0``), and the compiled path is the one taken
    where a compiler is found, so the tests above check it."""
    from rover_env.effects import native

    if native.library() is None:
        pytest.skip("no C compiler: the Python loops are the only path")
    rng = np.random.default_rng(9)
    rows = np.repeat(rng.uniform(-3, 3, (60, 4)), rng.integers(1, 12, 60), axis=0)
    t = np.cumsum(rng.choice([0.02, 0.021, 0.0195], 200)) - 0.02
    cmd = rng.uniform(-2, 2, (200, 4))
    out = {}
    for flag in ("1", "0"):
        monkeypatch.setenv("ROVER_ENV_NATIVE", flag)
        assert (native.library() is None) == (flag == "0")
        (lag,) = _effects({"command_lag": {"tau": 0.07}})
        lag.x = rng.uniform(-1, 1, 4) if flag == "1" else out["x0"]
        out.setdefault("x0", lag.x.copy())
        seq = [lag.sequence(rows[:100], 0.002), lag.sequence(rows[100:], 0.002), lag.x.copy()]
        lag.prime(t, cmd, float(t[150]) + 0.003, 0.002)
        out[flag] = [*seq, lag.x.copy()]
    for a, b in zip(out["1"], out["0"], strict=True):
        np.testing.assert_array_equal(a, b)
    assert np.any(out["1"][0] != rows[:100])


@pytest.mark.parametrize("ext", EXTS, ids=IDS)
def test_command_effects_beside_a_hinge_effect_are_queued_as_fed(
    ext: dict[str, dict[str, float]],
) -> None:
    """With a hinge effect (rolling resistance) the plugin runs to each hinge update in one
    call, the command effects' targets queued: the same state to the bit as one substep per
    call, across rows whose substeps straddle the updates."""
    both = {**ext, "rolling_resistance": {"c_rr": 0.06}}
    cfg = dataclasses.replace(RoverConfig(), extensions=both)
    at_once, by_substep = RoverSim(cfg, backend="plugin"), RoverSim(cfg, backend="plugin")
    no_hinge = RoverSim(dataclasses.replace(RoverConfig(), extensions=ext), backend="plugin")
    hinge = {"rolling_resistance": {"c_rr": 0.06}}
    no_command = RoverSim(dataclasses.replace(RoverConfig(), extensions=hinge), backend="plugin")
    rng = np.random.default_rng(3)
    targets = rng.uniform(-4, 4, (8, 4))
    steps = np.array([7, 90, 1, 0, 23, 33, 4, 12])
    for sim in (at_once, no_hinge, no_command):
        sim.drive(targets, steps)
    for u, n in zip(targets, steps, strict=True):
        by_substep.set_speed_targets(u)
        for _ in range(int(n)):
            by_substep.step(1)
    for a in ("qpos", "qvel", "ctrl"):
        np.testing.assert_array_equal(getattr(at_once.data, a), getattr(by_substep.data, a), a)
    for other, what in ((no_hinge, "hinge"), (no_command, "command effect")):
        assert np.max(np.abs(other.data.qpos[:3] - at_once.data.qpos[:3])) > 1e-5, what
