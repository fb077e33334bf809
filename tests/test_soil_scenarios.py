"""Loose-soil scenarios, the soil env id, the slip PI's set-point and progress on a slide
(issue 15, items 4 and 5)."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import rover_env  # noqa: F401  (registers the env ids)
from rover_env.benchmark.metrics import episode_metrics
from rover_env.benchmark.mixture import SOIL_MIX, ScenarioMixEnv
from rover_env.benchmark.run import Job, run_jobs
from rover_env.benchmark.scenarios import load_scenario, scenario_names
from rover_env.benchmark.seeds import SPLITS
from rover_env.config import ConfigError, load_rover
from rover_env.control import ControllerInput, SlipPI, SlipPIConfig, load_slip_pi_config
from rover_env.envs.registration import SOIL_ENV_ID
from rover_env.estimation.estimator import SlipEstimate

ROVER = load_rover()
SOIL_SCENARIOS = ("sand-slope", "soft-patch", "sand-turns")


def _input(slip: np.ndarray, t: float, v: float = 0.15, w: float = 0.0) -> ControllerInput:
    z3, z4 = np.zeros((3, 3)), np.zeros(4)
    est = SlipEstimate(
        t=np.array(t), phi_rate=np.full(6, 2.5), theta_rate=np.zeros(5),
        nominal_rate=np.full(4, 2.5), actual_rate=np.full(4, 2.5), slippage=z4,
        slip_ratio=np.asarray(slip, dtype=float), seg_velocity=z3, seg_omega=z3,
        seg_yaw_rate=np.zeros(3), pose=np.zeros(3), flags=np.zeros(4, dtype=np.int64),
    )  # fmt: skip
    return ControllerInput(
        t=t, estimate=est, theta=np.zeros(5), speed_command=v, yaw_rate_command=w
    )


def _drive(cfg: SlipPIConfig, slips: np.ndarray, shift: float = 0.0) -> np.ndarray:
    pi = SlipPI(ROVER, cfg)
    cmds = [(0.15, 0.0)] * 30 + [(0.12, 0.2)] * 20 + [(0.15, -0.1)] * 30
    return np.array([pi.act(_input(s + shift, 0.1 * k, *cmds[k])) for k, s in enumerate(slips)])


def test_setpoint_only_moves_the_band() -> None:
    """The set-point PI is the zero-set-point PI acting on slip measured from the set-point:
    fed slip shifted by s0 it gives bit-identical targets (values exact in binary), so it
    differs from today's PI by the set-point alone; at the default 0 it *is* today's PI."""
    rng = np.random.default_rng(15)
    # Shared slip drifting through and beyond the band, wheels apart by a few per cent;
    # multiples of 1/256 so that adding -0.25 is exact.
    common = np.concatenate([np.linspace(0.0, -0.3, 40), np.linspace(-0.3, 0.2, 40)])
    slips = np.round((common[:, None] + rng.normal(0, 0.03, (80, 4))) * 256) / 256
    base = dataclasses.replace(
        load_slip_pi_config("slip_pi"), slip_radius="estimator", traction_allowance=0.0625
    )
    assert base.slip_setpoint == 0.0
    ref = _drive(base, slips)
    shifted = _drive(dataclasses.replace(base, slip_setpoint=-0.25), slips, shift=-0.25)
    np.testing.assert_array_equal(shifted, ref)
    # Not vacuous: the same set-point on unshifted slip drives differently.
    assert not np.array_equal(_drive(dataclasses.replace(base, slip_setpoint=-0.25), slips), ref)
    # Every shipped hard-ground configuration keeps set-point 0.
    for name in ("slip_pi", "slip_pi_plain", "slip_pi_v1", "slip_pi_axle_fight"):
        assert load_slip_pi_config(name).slip_setpoint == 0.0


def test_setpoint_speeds_up_below_and_slows_beyond() -> None:
    cfg = load_slip_pi_config("slip_pi_soil")
    s0, a = cfg.slip_setpoint, cfg.traction_allowance
    assert s0 < -a  # a spinning set-point, outside the hard-ground band around 0
    ff = SlipPI(ROVER, cfg).feedforward.feedforward(0.15, 0.0)
    for shared, sign in ((s0 + 3 * a, 1.0), (s0, 0.0), (s0 - 3 * a, -1.0)):
        pi = SlipPI(ROVER, dataclasses.replace(cfg, slip_radius="estimator"))
        for k in range(20):
            out = pi.act(_input(np.full(4, shared), 0.1 * k))
        assert np.all(np.sign(np.round(out - ff, 9)) == sign), (shared, out - ff)
    with pytest.raises(ConfigError, match="slip_setpoint"):
        SlipPIConfig(slip_setpoint=0.1)


@pytest.mark.parametrize("name", SOIL_SCENARIOS)
def test_soil_scenario_runs_two_seconds(name: str) -> None:
    assert name in scenario_names()
    cfg = load_scenario(name)
    assert cfg.name == name and cfg.duration <= 30.0
    ep = cfg.episode(SPLITS["tuning"].start)
    assert ep.terrain.soil is not None or any(p.soil for p in ep.terrain.patches)
    (row,) = run_jobs([Job("slip-pi:slip_pi_soil", name, SPLITS["tuning"].start, duration=2.0)])
    for k in ("energy_per_metre", "mean_sinkage", "max_sinkage", "time_stuck"):
        assert np.isfinite(row[k]), k
    assert 0.0 < row["distance_made_good"] < 0.5
    if ep.terrain.soil is not None:  # soil under the wheels from the start
        assert 0.003 < row["mean_sinkage"] <= row["max_sinkage"] < 0.085


def test_soil_env_id_sinks_its_wheels() -> None:
    env = gym.make(SOIL_ENV_ID)
    env.reset(seed=3)
    sink = []
    for _ in range(15):
        _, _, term, trunc, info = env.step(np.full(4, 0.4, dtype=np.float32))
        sink.append(info["wheel_sinkage"])
        assert not (term or trunc)
    env.close()
    sink = np.array(sink)
    assert sink.shape == (15, 6) and np.all(np.isfinite(sink))
    assert np.all(sink[-1] > 0.003)  # every wheel in the regolith, none buried
    assert np.all(sink < 0.085)


def test_soil_scenarios_in_the_mix_env() -> None:
    env = ScenarioMixEnv(scenarios=SOIL_MIX)
    seen = set()
    for seed in range(4):
        _, info = env.reset(seed=seed)
        seen.add(info["scenario"])
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
        assert info["wheel_sinkage"].shape == (6,)
    assert seen <= set(SOIL_SCENARIOS) and seen


def test_sliding_back_is_not_progress() -> None:
    n = 50
    kw = dict(
        slip_abs_step=np.zeros((n, 4)),
        tracking_error_speed=np.zeros(n), tracking_error_yaw_rate=np.zeros(n),
        energy=np.ones(n), distance=np.full(n, 0.015), start=np.zeros(3),
        end=np.array([-0.75, 0.0, 0.0]), flipped=False, commanded_path=0.75,
        command=np.tile([0.15, 0.0], (n, 1)), step_dt=0.1,
    )  # fmt: skip
    forward = episode_metrics(**kw, speed=np.full(n, 0.15))  # type: ignore[arg-type]
    back = episode_metrics(**kw, speed=np.full(n, -0.15))  # type: ignore[arg-type]
    legacy = episode_metrics(**kw)  # type: ignore[arg-type]
    assert forward["success"] == 1.0 and forward["time_stuck"] == 0.0
    assert back["success"] == 0.0 and back["time_stuck"] == pytest.approx(5.0)
    assert legacy == forward
    assert back["energy_per_metre"] == forward["energy_per_metre"]  # over the path travelled


def test_open_loop_gain_scales_every_target() -> None:
    """``open-loop@gain=K``: the no-learning reference of the soil agents, targets x K, clipped
    at the motor limit like the plain feed-forward."""
    from rover_env.control.open_loop import OpenLoop
    from rover_env.policies.specs import controller_settings, parse_specs

    inp = _input(np.zeros(4), 0.0, v=0.15, w=0.2)
    base, fast = OpenLoop(ROVER).act(inp), OpenLoop(ROVER, gain=1.4).act(inp)
    np.testing.assert_allclose(fast, 1.4 * base, rtol=1e-12)
    top = OpenLoop(ROVER, gain=1e3).act(inp)
    assert np.all(np.abs(top) == ROVER.motor.max_wheel_speed)
    assert parse_specs("open-loop@gain=1.4") == ["open-loop@gain=1.4"]
    assert controller_settings("open-loop@gain=1.4")["gain"] == 1.4
    assert controller_settings("open-loop") == {"kind": "open-loop", "variant": ""}
    for bad in ("open-loop@kp=1", "open-loop@gain=0", "open-loop@gain=-1"):
        with pytest.raises(ValueError, match="open-loop"):
            parse_specs(bad)


def test_open_loop_ramp_grows_the_over_speed_from_one_over_its_time() -> None:
    """``open-loop@gain=K@ramp=T``: the soft start. At the drive's start the targets are the
    feed-forward's, half-way through the ramp the over-speed is half grown, after it K."""
    from rover_env.control.open_loop import OpenLoop
    from rover_env.policies.specs import controller_settings, parse_specs

    ff = OpenLoop(ROVER).act(_input(np.zeros(4), 0.0, v=0.1, w=0.1))
    soft = OpenLoop(ROVER, gain=2.0, ramp=4.0)
    for t, g in ((0.0, 1.0), (2.0, 1.5), (4.0, 2.0), (30.0, 2.0)):
        inp = _input(np.zeros(4), t, v=0.1, w=0.1)
        np.testing.assert_allclose(soft.act(inp), g * ff, rtol=1e-12, err_msg=f"t={t}")
    assert parse_specs("open-loop@gain=2.2@ramp=3") == ["open-loop@gain=2.2@ramp=3"]
    assert controller_settings("open-loop@gain=2.2@ramp=3") == {
        "kind": "open-loop",
        "variant": "",
        "gain": 2.2,
        "ramp": 3.0,
    }
    for bad in ("open-loop@ramp=-1", "open-loop@gain=2@lag=1"):
        with pytest.raises(ValueError, match="open-loop"):
            parse_specs(bad)
