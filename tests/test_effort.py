"""The torque limit read from the reported motor torque (rover_env.calibration.effort).

The logs here come from a small wheel model of this file's own (a PI speed loop into a
current-limited motor, a load torque, 1 ms steps, 50 Hz samples), not from the simulator.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration.diagnosis.effort_stage import action
from rover_env.calibration.effort import read_limit
from rover_env.calibration.report_notes import effort_lines
from rover_env.cli import main
from rover_env.generators.make_logs import EFFORT_NOISE, make_logs
from rover_env.logs import EFFORT_COLUMNS, DriveLog, LogError, LogMeta, read_log, write_log

CONFIGURED = 3.0


def wheel_log(
    targets: list[float],
    limit: float,
    *,
    load: float = 0.2,
    seed: int = 0,
    kp: float = 4.0,
    ki: float = 20.0,
    hold_s: float = 2.0,
    noise: float = 0.015,
    inertia: float = 0.06,
    lag_s: float = 0.0,
    scale: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0),
    stagger_s: float = 0.0,
) -> DriveLog:
    """Four wheels stepping through ``targets`` (rad/s, times ``scale`` per wheel), each held
    ``hold_s``, wheel j's steps ``j * stagger_s`` late; the loops see the logged targets
    through a first-order lag of ``lag_s`` (0: none)."""
    rng = np.random.default_rng(seed)
    dt, every = 0.001, 20
    n_steps = round(len(targets) * hold_s / dt)
    omega, integ, phi, seen = np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4)
    ts, cmds, phis, taus = [], [], [], []
    late = stagger_s * np.arange(4)
    for k in range(n_steps + 1):
        step = np.clip(((k * dt - late) // hold_s).astype(int), 0, len(targets) - 1)
        target = np.array(targets)[step] * np.array(scale)
        seen = seen + (dt / lag_s) * (target - seen) if lag_s > 0 else target
        err = seen - omega
        raw = kp * err + integ
        tau = np.clip(raw, -limit, limit)
        integ += dt * ki * err * (raw == tau)  # conditional integration
        if k % every == 0:
            ts.append(k * dt)
            cmds.append(target.copy())
            phis.append(np.concatenate([phi, phi[:2]]))
            taus.append(tau.copy())
        drag = load * np.tanh(omega / 0.05)
        omega = omega + dt * (tau - drag) / inertia
        phi = phi + dt * omega
    phi_arr = np.round(np.array(phis) / 2e-4) * 2e-4  # an encoder's count
    return DriveLog(
        t=np.array(ts),
        cmd=np.array(cmds),
        phi=phi_arr,
        theta=np.zeros((len(ts), 5)),
        pose=np.full((len(ts), 3), np.nan),
        meta=LogMeta(rover="proto_explorer", sample_rate_hz=50.0),
        effort=np.array(taus) + rng.normal(0.0, noise, (len(ts), 4)),
    )


STEPS = [0.0, 1.0, 2.5, 0.5, -1.5, 3.0, 0.0, 2.0, -0.5, 1.2]
"""Steps of many sizes: the motors saturate on the large ones, each at its own demand."""


@pytest.mark.parametrize("limit", [2.1, 2.9, 1.0])
def test_a_ceiling_is_read_within_its_noise(limit: float) -> None:
    r = read_limit([wheel_log(STEPS, limit)], CONFIGURED, 0.10)
    assert r is not None and r.plateau
    assert r.level == pytest.approx(limit, abs=0.02)
    cut = r.cut()
    assert cut is not None
    x, lo, hi = cut
    truth = limit / CONFIGURED - 1.0
    assert lo <= truth <= hi
    assert x == pytest.approx(truth, abs=0.01)
    named = not lo <= 0.0 <= hi
    assert named == (limit < 2.6)  # a 30 % cut is named, 3 % is within the tolerance


def test_a_repeated_manoeuvres_own_peak_is_not_a_ceiling() -> None:
    """The same step again and again peaks at the same torque at the same demand."""
    same = [0.0, 1.0] * 5
    r = read_limit([wheel_log(same, 10.0)], CONFIGURED, 0.10)
    assert r is not None and not r.plateau
    assert r.largest > 1.0  # the motor was asked, and gave, a real torque
    ruled = r.deepest_ruled_out()
    assert ruled is not None and ruled == pytest.approx(r.largest / (CONFIGURED * 1.1) - 1)


def test_a_steady_load_while_tracking_is_not_a_ceiling() -> None:
    """A climb's level torque (the loop tracks, no lag) is not taken for the limit."""
    r = read_limit([wheel_log([1.0] * 6, CONFIGURED, load=1.5)], CONFIGURED, 0.10)
    assert r is not None and not r.plateau


def test_a_level_the_torque_exceeds_elsewhere_is_no_ceiling() -> None:
    log = wheel_log(STEPS, 2.0)
    log.effort[40:44, 2] = 2.6  # at rest, not asked: the motor gave more for 80 ms
    r = read_limit([log], CONFIGURED, 0.10)
    assert r is not None and not r.plateau


def test_one_manoeuvre_tests_the_ceiling_once() -> None:
    """Four wheels clipped in one step, at demands 3 x apart, are one event, not a ceiling
    (behind an unnamed lag one reversal's wheels made a false one, exploratory seed 74091);
    the same four clips a second apart are four, and read the limit."""
    one = [0.0, 2.5, 2.5, 2.5, 2.5]
    scale = (1.0, 1.6, 2.2, 3.0)
    together = read_limit([wheel_log(one, 1.0, scale=scale)], CONFIGURED, 0.10)
    assert together is not None and together.events == 1 and not together.plateau
    apart = read_limit([wheel_log(one, 1.0, scale=scale, stagger_s=1.0)], CONFIGURED, 0.10)
    assert apart is not None and apart.events == 4 and apart.spread > 2.5
    assert apart.level == pytest.approx(1.0, abs=0.02)


def test_the_loops_targets_decide_what_was_asked() -> None:
    """Behind a command lag the logged target runs ahead; given the loop's own (here: the
    wheel's rate itself, nothing asked), no plateau is read."""
    log = wheel_log(STEPS, 2.0)
    assert read_limit([log], CONFIGURED, 0.10).plateau  # type: ignore[union-attr]
    rates = np.gradient(log.phi[:, :4], log.t, axis=0)
    r = read_limit([log], CONFIGURED, 0.10, [rates])
    assert r is not None and not r.plateau and r.asked == 0


def test_behind_a_long_lag_only_the_loops_targets_tell_a_load_from_a_limit() -> None:
    """Behind a 0.8 s command lag the wheel lags the logged target while its motor meets a
    steady 1.2 N m load: against the logged targets that load reads as a ceiling (why the
    stage gives the loops' targets after a named lag); against the loop's own, nothing."""
    log = wheel_log(STEPS, CONFIGURED, load=1.2, inertia=0.005, lag_s=0.8)
    logged = read_limit([log], CONFIGURED, 0.10)
    assert logged is not None and logged.level == pytest.approx(1.2, abs=0.03)
    seen = np.zeros_like(log.cmd)
    for k in range(1, len(log.t)):
        seen[k] = seen[k - 1] + (1.0 - math.exp(-(log.t[k] - log.t[k - 1]) / 0.8)) * (
            log.cmd[k - 1] - seen[k - 1]
        )
    loop = read_limit([log], CONFIGURED, 0.10, [seen])
    assert loop is not None and not loop.plateau


def test_logs_without_effort_give_no_reading() -> None:
    log = wheel_log([0.0, 1.0], 2.0)
    bare = DriveLog(log.t, log.cmd, log.phi, log.theta, log.pose, log.meta)
    assert not bare.has_effort
    assert read_limit([bare], CONFIGURED, 0.10) is None


def test_the_report_says_what_was_read() -> None:
    r = read_limit([wheel_log(STEPS, 2.1)], CONFIGURED, 0.10)
    assert r is not None
    text = " ".join(effort_lines({**r.as_json(), "named": True}))
    assert "held at 2.1" in text and "named `torque_limit`" in text
    never = read_limit([wheel_log([0.0, 0.5] * 3, 10.0)], CONFIGURED, 0.10)
    assert never is not None
    text = " ".join(effort_lines({**never.as_json(), "named": False}))
    assert "never held at a ceiling" in text and "rules out cuts deeper than" in text


def test_effort_columns_round_trip_and_bad_ones_are_named(tmp_path: Path) -> None:
    log = wheel_log([0.0, 1.0], 2.0)
    log.effort[3, 1] = math.nan  # not measured there
    back = read_log(write_log(log, tmp_path / "d.csv"))
    assert np.array_equal(back.effort, log.effort, equal_nan=True)
    header = (tmp_path / "d.csv").read_text().splitlines()[0].split(",")
    assert header[-4:] == list(EFFORT_COLUMNS)
    # Three of the four columns: refused, naming what is missing.
    text = (tmp_path / "d.csv").read_text().replace(",effort_2R", ",other")
    (tmp_path / "e.csv").write_text(text)
    (tmp_path / "e.yaml").write_text((tmp_path / "d.yaml").read_text())
    with pytest.raises(LogError, match="effort_2R"):
        read_log(tmp_path / "e.csv")
    bad = wheel_log([0.0, 1.0], 2.0)
    bad.effort[5, 0] = math.inf
    with pytest.raises(LogError, match="effort is infinite"):
        write_log(bad, tmp_path / "f.csv")


@pytest.mark.parametrize(
    "cut, windows, inside, expected",
    [
        (None, None, False, "no ceiling"),
        (None, (-0.3, -0.1), False, "no ceiling"),  # no ceiling: the windows' name stands
        ((-0.07, -0.15, 0.04), None, False, "within"),
        ((-0.07, -0.15, 0.04), (-0.5, -0.3), False, "withdraw"),  # the motors gave it
        ((-0.07, -0.15, 0.04), None, True, "within"),
        ((-0.3, -0.37, -0.22), None, True, "inside"),
        ((-0.3, -0.37, -0.22), None, False, "name"),
        ((-0.3, -0.37, -0.22), (-0.25, -0.18), False, "agree"),
        ((-0.3, -0.37, -0.22), (-0.6, -0.45), False, "replace"),
    ],
)
def test_what_a_reading_does_beside_the_windows(
    cut: tuple[float, float, float] | None,
    windows: tuple[float, float] | None,
    inside: bool,
    expected: str,
) -> None:
    assert action(cut, windows, inside) == expected


def test_make_logs_effort_is_the_motor_torque_on_its_own_stream(tmp_path: Path) -> None:
    """``make-logs --effort``: the simulator's motor torque with noise of its own stream,
    clipped at the cut limit; every other column the same as without it."""
    kw: dict = {"drives": 1, "seed": 3, "duration": 8.0, "progress": False}
    cut = {"torque_limit": {"fraction": -0.3}}
    (p,) = make_logs(tmp_path / "e", cut, effort=True, **kw)
    (q,) = make_logs(tmp_path / "n", cut, **kw)
    a, b = read_log(p), read_log(q)
    assert a.has_effort and not b.has_effort
    for name in ("cmd", "phi", "theta", "pose"):
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True)
    top = np.abs(a.effort).max()
    assert 2.1 - 0.1 < top < 2.1 + 5 * EFFORT_NOISE  # the steps ask for more than the limit


@pytest.mark.parametrize("bad", ["1", "1.5", "-0.1", "nan", "ten"])
def test_a_bad_effort_tolerance_is_refused_naming_the_flag(
    bad: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(
            ["diagnose", str(tmp_path / "x.csv"), "--out", str(tmp_path), "--effort-tolerance", bad]
        )
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "--effort-tolerance" in err and bad in err, err


def test_the_foreign_generator_refuses_effort(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["make-logs", "--generator", "foreign", "--effort", "--out", str(tmp_path), "--quiet"]
    assert main(argv) == 2
    assert "logs no motor torque (--effort)" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.csv"))
