"""The torch slip estimator (rover_env.warp.estimator) against the numpy BatchSlipEstimator,
and WarpRoverEnv's observation that carries it.

Both estimators get the same sensor streams: three rovers driven by the CPU simulator (C
plugin) for 5 s, read at 50 Hz through the default sensor model (quantised encoders, noisy
potentiometers) and rounded to float32 (what the device holds), with a standstill, a
start, straight runs, left and right turns, turning on the spot and reversing.

Tolerances of the float32 estimator (float32 unit roundoff u = 6e-8):

* rates: a least-squares slope sums M = 26 products (a 0.5 s window at 50 Hz); the
  classic bound for such a sum is M u |rate| = 26 x 6e-8 x 5 rad/s = 8e-6 rad/s. Bound
  1e-5 rad/s; measured 3.1e-6 (nominal rates), 2.4e-6 (wheel rates).
* slip ratio: (hub - tread speed) / max(|hub|, |tread|, v_eps), so a rate error e gives at
  most 2 d e / den: the bound is that, per entry, from the numpy run's speeds (measured
  1.5e-6 at most).
* segment velocities: the rates' bound times the chain's lengths (< 0.5 m): 1e-5.
* pose: 250 increments of dead reckoning, each rounded to u |pose|: 250 u (1 + |pose|), about
  4e-5 m; measured 5.7e-7 m.
* flags: equal (thresholds the float32 rounding moves across would show here).

The float64 estimator is the numpy one to 1e-12. A 1e-4 change of the rolling radius
breaks the float32 bounds, so they see a model change of that size.
"""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("warp")

from rover_env.config import load_rover  # noqa: E402
from rover_env.estimation.batch import BatchSlipEstimator  # noqa: E402
from rover_env.estimation.estimator import EstimatorConfig, static_rolling_radius  # noqa: E402
from rover_env.estimation.sensors import SensorConfig, SensorModel  # noqa: E402
from rover_env.sim.simulator import RoverSim  # noqa: E402
from rover_env.warp.estimator import TorchSlipEstimator  # noqa: E402

CFG = load_rover("proto_explorer")
PLANS = [  # (from s, targets 1L 1R 2L 2R rad/s)
    [(0.0, (0, 0, 0, 0)), (0.3, (3, 3, 3, 3)), (2.0, (2, 4, 2, 4)), (4.0, (4, 4, 4, 4))],
    [(0.0, (2, 2, 2, 2)), (1.5, (-2, 2, -2, 2)), (3.0, (-3, -3, -3, -3))],
    [(0.0, (4, 3, 4, 3)), (2.5, (0, 0, 0, 0)), (3.5, (3, 3, 3, 3))],
]
SAMPLES = 250
FIELDS = ("phi_rate", "theta_rate", "nominal_rate", "slippage", "seg_velocity", "seg_omega")


@pytest.fixture(scope="module")
def streams() -> np.ndarray:
    """(3, SAMPLES, 12): t, wheel angles (6), joint angles (5), float32 values."""
    out = []
    for j, plan in enumerate(PLANS):
        sim = RoverSim(CFG, "flat", backend="plugin")
        sim.reset()
        sensors = SensorModel(SensorConfig(), np.random.default_rng(j))
        rows = []
        for k in range(SAMPLES):
            t = k * 0.02
            sim.set_speed_targets(np.array([p[1] for p in plan if p[0] <= t + 1e-9][-1], float))
            if k:
                sim.step(20)
            s = sim.sensors()
            phi, theta = sensors.read(s.phi, s.theta)
            rows.append(np.concatenate([[t], phi, theta]))
        out.append(np.array(rows))
    return np.stack(out).astype(np.float32).astype(np.float64)


def _run(streams: np.ndarray, dev: TorchSlipEstimator) -> tuple[dict, dict]:
    """Feed both estimators the streams (rover 1 restarts at sample 120 and is fed alone,
    by index, then rover 2 by mask); stack every estimate of both."""
    ref = BatchSlipEstimator(CFG, 3)
    got: dict[str, list] = {}
    want: dict[str, list] = {}
    for k in range(SAMPLES):
        x = streams[:, k]
        ref.push(None, x[:, 0], x[:, 1:7], x[:, 7:])
        dev.push(None, torch.tensor(x[:, 0]), torch.tensor(x[:, 1:7]), torch.tensor(x[:, 7:]))
        if k == 120:
            ref.reset([1])
            dev.reset(torch.tensor([1]))
            x1 = x[1:2].copy()
            x1[:, 0] += 1e-3
            ref.push([1], x1[:, 0], x1[:, 1:7], x1[:, 7:])
            dev.push(torch.tensor([1]), x1[:, 0], x1[:, 1:7], x1[:, 7:])
        if k == 121:  # one more sample of rover 2 only, as a mask with inputs for all
            x2 = x.copy()
            x2[:, 0] += 1e-3
            ref.push([2], x2[2:, 0], x2[2:, 1:7], x2[2:, 7:])
            mask = torch.tensor([False, False, True])
            dev.push(mask, x2[:, 0], x2[:, 1:7], x2[:, 7:])
        e, d = ref.estimate(), dev.estimate()
        for f in (*FIELDS, "slip_ratio", "pose", "flags", "t"):
            want.setdefault(f, []).append(np.stack([getattr(q, f) for q in e]))
            got.setdefault(f, []).append(getattr(d, f).double().numpy())
    return {k: np.stack(v) for k, v in want.items()}, {k: np.stack(v) for k, v in got.items()}


@pytest.fixture(scope="module")
def numpy_and_float32(streams: np.ndarray) -> tuple[dict, dict]:
    return _run(streams, TorchSlipEstimator(CFG, 3, capacity=27, validate=True))


def _float32_errors(want: dict, got: dict) -> dict[str, float]:
    """Each quantity's largest difference over its bound (> 1 breaks it)."""
    out = {f: np.abs(got[f] - want[f]).max() / 1e-5 for f in FIELDS}
    d = np.array(static_rolling_radius(CFG))
    hub = d * want["nominal_rate"]
    tread = d * (want["nominal_rate"] + want["slippage"])
    den = np.maximum(np.maximum(np.abs(hub), np.abs(tread)), CFG.tire.v_eps)
    out["slip_ratio"] = (
        np.abs(got["slip_ratio"] - want["slip_ratio"]) / (2 * d * 1e-5 / den)
    ).max()
    pose_bound = SAMPLES * 6e-8 * (1 + np.abs(want["pose"]))
    out["pose"] = (np.abs(got["pose"] - want["pose"]) / pose_bound).max()
    return out


def test_streams_exercise_every_flag(numpy_and_float32: tuple[dict, dict]) -> None:
    """The drives set each reliability flag somewhere, so equal flags mean something."""
    flags = numpy_and_float32[0]["flags"]
    for bit in (1, 2, 4, 8):
        assert ((flags & bit) != 0).any(), bit
    assert (flags == 0).mean() > 0.5


def test_float64_equals_numpy(streams: np.ndarray) -> None:
    want, got = _run(streams, TorchSlipEstimator(CFG, 3, dtype=torch.float64, capacity=27))
    for f in (*FIELDS, "slip_ratio", "pose", "t"):
        np.testing.assert_allclose(got[f], want[f], rtol=0, atol=1e-12, err_msg=f)
    np.testing.assert_array_equal(got["flags"], want["flags"])


def test_float32_equals_numpy_to_rounding(numpy_and_float32: tuple[dict, dict]) -> None:
    want, got = numpy_and_float32
    errors = _float32_errors(want, got)
    assert max(errors.values()) <= 1.0, errors
    np.testing.assert_array_equal(got["flags"], want["flags"])
    np.testing.assert_array_equal(got["t"], want["t"])


def test_float32_bounds_see_a_1e4_radius_change(
    streams: np.ndarray, numpy_and_float32: tuple[dict, dict]
) -> None:
    r = static_rolling_radius(CFG) * (1 + 1e-4)
    dev = TorchSlipEstimator(CFG, 3, EstimatorConfig(rolling_radius=r), capacity=27)
    want, got = _run(streams, dev)
    errors = _float32_errors(want, got)
    assert errors["slip_ratio"] > 1 and errors["pose"] > 1 and errors["seg_velocity"] > 1


def test_validate_catches_a_short_ring_and_time_going_back() -> None:
    dev = TorchSlipEstimator(CFG, 1, capacity=3, validate=True)
    with pytest.raises(RuntimeError, match="sample"):
        dev.estimate()
    zero6, zero5 = torch.zeros(1, 6), torch.zeros(1, 5)
    for k in range(3):
        dev.push(None, [0.1 * k], zero6, zero5)
    with pytest.raises(ValueError, match="time must increase"):
        dev.push(None, [0.1], zero6, zero5)
    with pytest.raises(ValueError, match="capacity"):
        dev.push(None, [0.3], zero6, zero5)


# --------------------------------------------------------------------------- the env
