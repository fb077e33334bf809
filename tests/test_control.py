"""Controllers (rover_env.control): slip PI behaviour on synthetic slip, open-loop kinematics,
configuration, the bare-simulator runner and the environment's controller adapter."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from rover_env.benchmark.metrics import trace_metrics
from rover_env.config import ConfigError, TerrainConfig, load_rover
from rover_env.control import (
    CommandSchedule,
    ControllerInput,
    DriveCase,
    OpenLoop,
    SlipPI,
    SlipPIConfig,
    load_slip_pi_config,
    run_on_sim,
    skid_steer_targets,
)
from rover_env.estimation.estimator import (
    FLAG_FREE_WHEELS,
    FLAG_STANDSTILL,
    SlipEstimate,
    static_rolling_radius,
)

ROVER = load_rover()
# The estimate as given (no per-axle re-basing), so the loop sees exactly the synthetic slip.
PLAIN = SlipPIConfig(slip_radius="estimator", kp=0.3, ki=2.0, deadband=0.0)
V, W = 0.15, 0.0


def estimate(slip: list[float], flags: int | list[int] = 0, t: float = 0.0) -> SlipEstimate:
    z3, z4 = np.zeros((3, 3)), np.zeros(4)
    return SlipEstimate(
        t=np.array(t),
        phi_rate=np.full(6, 2.5),
        theta_rate=np.zeros(5),
        nominal_rate=np.full(4, 2.5),
        actual_rate=np.full(4, 2.5),
        slippage=z4,
        slip_ratio=np.asarray(slip, dtype=float),
        seg_velocity=z3,
        seg_omega=z3,
        seg_yaw_rate=np.zeros(3),
        pose=np.zeros(3),
        flags=np.broadcast_to(np.asarray(flags, dtype=np.int64), (4,)).copy(),
    )


def obs(slip: list[float], t: float, flags: int | list[int] = 0, v: float = V, w: float = W):
    return ControllerInput(
        t=t, estimate=estimate(slip, flags, t), theta=np.zeros(5), speed_command=v,
        yaw_rate_command=w,
    )  # fmt: skip


def ff(v: float = V, w: float = W) -> np.ndarray:
    return skid_steer_targets(v, w, ROVER.geometry.half_track, static_rolling_radius(ROVER))


def test_open_loop_is_skid_steer_kinematics() -> None:
    r_e, b = static_rolling_radius(ROVER), ROVER.geometry.half_track
    ol = OpenLoop(ROVER)
    out = ol.act(obs([0, 0, 0, 0], 0.0, v=0.1, w=0.2))
    left, right = (0.1 - b * 0.2) / r_e, (0.1 + b * 0.2) / r_e
    np.testing.assert_allclose(out, [left, right, left, right], rtol=1e-12)
    # Reverse and spot turns; the motor limit clips.
    np.testing.assert_allclose(ol.act(obs([0] * 4, 0.0, v=-0.1, w=0.0)), np.full(4, -0.1 / r_e))
    np.testing.assert_allclose(
        ol.act(obs([0] * 4, 0.0, v=0.0, w=0.4))[:2], [-b * 0.4 / r_e, b * 0.4 / r_e]
    )
    assert np.all(ol.act(obs([0] * 4, 0.0, v=5.0)) == ROVER.motor.max_wheel_speed)


def test_pi_sign_spinning_wheel_slowed_dragged_wheel_sped_up() -> None:
    pi = SlipPI(ROVER, PLAIN)
    base = ff()
    out = np.zeros(4)
    for k in range(5):
        out = pi.act(obs([-0.3, 0.0, 0.0, 0.3], 0.1 * k))
    assert out[0] < base[0], "a spinning wheel (S<0) must be slowed"
    assert out[3] > base[3], "a dragged wheel (S>0) must be sped up"
    np.testing.assert_allclose(out[1:3], base[1:3])  # untouched wheels keep their target
    # The integrator keeps pushing while the slip persists.
    later = pi.act(obs([-0.3, 0.0, 0.0, 0.3], 0.5))
    assert later[0] < out[0] and later[3] > out[3]


def test_pi_step_response_and_anti_windup_recovery() -> None:
    cfg = dataclasses.replace(PLAIN, min_correction=-0.8, retry_interval=0.0)
    pi = SlipPI(ROVER, cfg)
    base = ff()[0]
    t = 0.0
    for _ in range(200):  # 20 s of a fully spinning wheel: the output saturates
        t += 0.1
        out = pi.act(obs([-1.0, 0, 0, 0], t))
    assert out[0] == pytest.approx(base * 0.2)
    assert pi.integral[0] >= cfg.min_correction - 1e-12  # clamped, not wound beyond the limit
    # The slip reverses: the output must leave the limit at once, not after unwinding 20 s.
    t += 0.1
    out = pi.act(obs([0.2, 0, 0, 0], t))
    assert out[0] > base * 0.2 + 0.1 * base * cfg.kp * 0.2
    for _ in range(10):
        t += 0.1
        out = pi.act(obs([0.2, 0, 0, 0], t))
    assert out[0] > base * (1 - 0.8 + 0.3)


def test_pi_output_limits() -> None:
    cfg = dataclasses.replace(PLAIN, min_correction=-0.5, max_correction=0.25)
    pi = SlipPI(ROVER, cfg)
    base = ff()
    for k in range(100):
        out = pi.act(obs([-1.0, 1.0, -1.0, 1.0], 0.1 * k))
        assert np.all(out[[0, 2]] >= base[[0, 2]] * 0.5 - 1e-12)
        assert np.all(out[[1, 3]] <= base[[1, 3]] * 1.25 + 1e-12)
    # Near the motor's limit the cap is the motor's, and the integrator stops there.
    pi = SlipPI(ROVER, cfg)
    v_fast = 0.95 * ROVER.motor.max_wheel_speed * static_rolling_radius(ROVER)
    for k in range(100):
        out = pi.act(obs([1.0, 1.0, 1.0, 1.0], 0.1 * k, v=v_fast))
        assert np.all(np.abs(out) <= ROVER.motor.max_wheel_speed + 1e-12)


def test_pi_unreliable_estimate_freezes_integrator() -> None:
    pi = SlipPI(ROVER, PLAIN)
    for k in range(5):
        pi.act(obs([-0.3, 0, 0, 0], 0.1 * k))
    frozen = pi.integral.copy()
    assert frozen[0] < 0
    for k in range(5, 30):
        out = pi.act(obs([-0.9, 0.5, 0, 0], 0.1 * k, flags=FLAG_FREE_WHEELS))
    np.testing.assert_array_equal(pi.integral, frozen)
    np.testing.assert_allclose(out, ff() * (1 + frozen))  # no proportional action either


def _stuck_drive(cfg: SlipPIConfig) -> tuple[np.ndarray, float]:
    """Outputs over 10 s of a rover standing while driven, and how long its wheels stayed
    stopped before the first retry."""
    pi = SlipPI(ROVER, cfg)
    # The rover stands (segment 3 still) while the wheels are driven.
    outs = np.array([pi.act(obs([0.0] * 4, 0.1 * k, flags=FLAG_STANDSTILL)) for k in range(100)])
    stopped = np.flatnonzero(np.all(outs == 0.0, axis=1))
    assert stopped.size > 0, "a stuck rover's wheels are stopped"
    moving_again = np.flatnonzero(np.all(outs[stopped[0] :] > 0, axis=1))
    assert moving_again.size > 0, "and retried after the retry interval"
    return outs, 0.1 * moving_again[0]


def test_pi_stuck_detector_and_retry() -> None:
    cfg = dataclasses.replace(PLAIN, stuck_time=1.0, retry_interval=3.0)
    outs, held = _stuck_drive(cfg)
    np.testing.assert_allclose(outs[5], ff())  # not stuck yet: frozen, feed-forward only
    assert held == pytest.approx(3.0, abs=0.11)
    # A stuck wheel's own interval: twice as long.
    _, held2 = _stuck_drive(dataclasses.replace(cfg, stuck_retry_scale=2.0))
    assert held2 == pytest.approx(6.0, abs=0.11)


def test_pi_traction_allowance_leaves_shared_slip_alone() -> None:
    cfg = dataclasses.replace(PLAIN, traction_allowance=0.25)
    pi = SlipPI(ROVER, cfg)
    for k in range(30):  # a slope: every wheel spins by 15 %
        out = pi.act(obs([-0.15] * 4, 0.1 * k))
    np.testing.assert_allclose(out, ff())
    pi0 = SlipPI(ROVER, dataclasses.replace(cfg, traction_allowance=0.0))  # the paper's loop
    for k in range(30):
        out0 = pi0.act(obs([-0.15] * 4, 0.1 * k))
    assert np.all(out0 < ff())


def test_pi_turn_schedule_widens_the_deadband() -> None:
    cfg = dataclasses.replace(PLAIN, deadband=0.01, turn_deadband_gain=0.5)
    pi = SlipPI(ROVER, cfg)
    turn = obs([0.1, -0.1, 0.1, -0.1], 0.0, v=0.15, w=0.2)
    assert pi.deadband(turn) == pytest.approx(0.01 + 0.5 * 0.225 * 0.2 / 0.15)
    np.testing.assert_allclose(pi.act(turn), ff(0.15, 0.2))


def test_pi_axle_fight_mode_has_its_own_deadband() -> None:
    """Only the front-against-middle mode is measured against the narrower deadband."""
    cfg = dataclasses.replace(PLAIN, deadband=0.01, axle_fight_scale=0.25)
    pi, plain = SlipPI(ROVER, cfg), SlipPI(ROVER, dataclasses.replace(cfg, axle_fight_scale=1.0))
    o, ok = obs([0.0] * 4, 0.0), np.ones(4, dtype=bool)
    fight = np.array([-0.005, -0.005, 0.005, 0.005])  # front spins, middle dragged
    np.testing.assert_allclose(pi.slip_error(fight, o, ok, True), [-0.0025] * 2 + [0.0025] * 2)
    for steer in ([0.005, -0.005, 0.005, -0.005], [0.005, -0.005, -0.005, 0.005]):
        # Left-right and diagonal modes keep the wide deadband: nothing to correct.
        np.testing.assert_array_equal(pi.slip_error(np.array(steer), o, ok, True), 0.0)
    x = np.array([0.03, -0.004, 0.012, -0.02])
    np.testing.assert_array_equal(pi.slip_error(x, o, ok, False), plain.slip_error(x, o, ok, True))
    e = pi.slip_error(x, o, ok, True) - plain.slip_error(x, o, ok, True)
    np.testing.assert_allclose(e, e[0] * np.array([1, 1, -1, -1]), atol=1e-15)
    # Through the loop: the plain PI leaves the fight alone, the axle-fight PI slows the
    # spinning front axle and speeds up the dragged middle one.
    out_plain = plain.act(obs(fight.tolist(), 0.0))
    out = pi.act(obs(fight.tolist(), 0.0))
    np.testing.assert_allclose(out_plain, ff())
    assert np.all(out[:2] < ff()[:2]) and np.all(out[2:] > ff()[2:])
    with pytest.raises(ConfigError, match="axle_fight_scale"):
        SlipPIConfig(axle_fight_scale=-0.5)


def test_slip_pi_config_validation_and_shipped_file(tmp_path: Path) -> None:
    cfg = load_slip_pi_config()
    assert cfg.kp >= 0 and cfg.ki >= 0
    with pytest.raises(ConfigError, match="kp"):
        SlipPIConfig(kp=-1.0)
    with pytest.raises(ConfigError, match="min_correction"):
        SlipPIConfig(min_correction=0.5)
    with pytest.raises(ConfigError, match="slip_radius"):
        SlipPIConfig(slip_radius="wrong")
    bad = tmp_path / "bad.yaml"
    bad.write_text("kp: 0.3\nkq: 1.0\n")
    with pytest.raises(ConfigError, match="kq"):
        load_slip_pi_config(bad)
    with pytest.raises(ConfigError, match="not found"):
        load_slip_pi_config(tmp_path / "missing.yaml")


def test_controller_input_and_schedule_validation() -> None:
    with pytest.raises(ValueError, match="theta"):
        ControllerInput(t=0.0, estimate=estimate([0] * 4), theta=np.zeros(4), speed_command=0.1,
                        yaw_rate_command=0.0)  # fmt: skip
    with pytest.raises(ValueError, match="finite"):
        obs([0] * 4, float("nan"))
    s = CommandSchedule.from_rows([[0.0, 0.1, 0.0], [2.0, 0.2, 0.1]])
    assert s.at(1.99) == (0.1, 0.0) and s.at(2.0) == (0.2, 0.1)
    assert s.path_length(3.0) == pytest.approx(0.1 * 2 + 0.2 * 1)
    with pytest.raises(ConfigError):
        CommandSchedule.from_rows([[1.0, 0.1, 0.0], [1.0, 0.2, 0.0]])


def test_run_on_bare_simulator() -> None:
    """Controllers live below the env: they drive RoverSim directly."""
    case = DriveCase(
        terrain=TerrainConfig(name="flat", size=(20.0, 20.0)),
        schedule=CommandSchedule.from_rows([[0.0, 0.15, 0.0]]),
        duration=3.0,
        seed=0,
    )
    ol = run_on_sim(OpenLoop(ROVER), case)
    pi = run_on_sim(SlipPI(ROVER, load_slip_pi_config()), case)
    for tr in (ol, pi):
        m = trace_metrics(tr, case.schedule.path_length(case.duration))
        assert 0.35 < m["distance_made_good"] < 0.5
        assert m["rms_speed_error"] < 0.05 and not tr.flipped
        assert len(tr.t) == 30


def test_env_controller_input_matches_observation() -> None:
    from rover_env.envs.proto_explorer import OBS_NAMES, ProtoExplorerEnv

    env = ProtoExplorerEnv()
    o, _ = env.reset(seed=1)
    for _ in range(3):
        o, *_ = env.step(np.full(4, 0.5, dtype=np.float32))
    ci = env.controller_input(o)
    assert isinstance(ci, ControllerInput)
    i = OBS_NAMES.index
    np.testing.assert_allclose(
        ci.slip_ratio, o[i("slip_estimate_1L") : i("slip_estimate_2R") + 1], rtol=1e-6
    )
    np.testing.assert_allclose(ci.theta, o[i("theta_1") : i("theta_5") + 1], rtol=1e-6)
    assert (ci.speed_command, ci.yaw_rate_command) == pytest.approx(
        tuple(o[i("command_speed") :][:2])
    )
    assert ci.t == pytest.approx(env.sim.time)
    assert ci.imu_gyro is not None and ci.imu_gyro.shape == (3, 3)
    assert env.controller_input().imu_gyro is None
    env.close()


def test_speed_hold_gives_back_lost_speed_bounded_held_in_turns_cleared_when_stuck() -> None:
    cfg = dataclasses.replace(PLAIN, speed_hold_gain=1.0, speed_hold_limit=0.05)
    pi = SlipPI(ROVER, cfg, dt=0.1)

    def at(t: float, v_hat: float, w: float = W, flags: int = 0) -> ControllerInput:
        est = dataclasses.replace(estimate([0.0] * 4, flags, t), seg_velocity=np.zeros((3, 3)))
        est.seg_velocity[1, 0] = v_hat
        return ControllerInput(
            t=t, estimate=est, theta=np.zeros(5), speed_command=V, yaw_rate_command=w
        )

    pi.act(at(0.0, 0.98 * V))  # the first call integrates over the nominal dt = 0.1 s
    out = pi.act(at(0.1, 0.98 * V))  # 2 % slow for 2 x 0.1 s at gain 1/s: +0.4 % everywhere
    np.testing.assert_allclose(out, ff() * (1 + 0.004), rtol=1e-9)
    for k in range(2, 10):  # 50 % slow: outside speed_hold_window (an obstacle), held
        out = pi.act(at(0.1 * k, 0.5 * V))
    assert pi.speed_hold == pytest.approx(0.004)
    for k in range(10, 40):
        out = pi.act(at(0.1 * k, 0.85 * V))
    np.testing.assert_allclose(out, ff() * 1.05, rtol=1e-9)  # bounded by speed_hold_limit
    pi.act(at(4.0, 0.85 * V, w=0.2))  # a turn: held, not integrated
    assert pi.speed_hold == pytest.approx(0.05)
    pi.act(at(4.1, 1.15 * V))
    assert pi.speed_hold == pytest.approx(0.05 - 0.15 * 0.1)  # too fast: wound back
    for k in range(42, 70):  # standing still while driven: stuck after stuck_time
        pi.act(at(0.1 * k, 0.0, flags=FLAG_STANDSTILL))
    assert pi.last_stuck.any() and pi.speed_hold == 0.0
