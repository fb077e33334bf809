"""benchmarks/effect_twin.py's comparison of an effect's change in the generator (measured on a
clean twin) with the model's change at the truth: the vectors, their labels, the tally. No
replay runs here: the window results are built by hand."""

from __future__ import annotations

from types import ModuleType
from typing import Any

import numpy as np
import pytest
from _bench import load_bench

from rover_env.calibration.replay import Window, WindowResult
from rover_env.calibration.residuals import SIGNALS

SCALE = {s: 1.0 for s in SIGNALS}


@pytest.fixture(scope="module")
def et() -> ModuleType:
    return load_bench("effect_twin")


def result(log: int, resid: np.ndarray, pose: np.ndarray) -> WindowResult:
    n, m = resid.shape[0], pose.shape[0]
    idx = np.arange(n, dtype=np.intp)
    return WindowResult(
        Window(log, 0, n), idx, resid, np.zeros_like(resid), idx[:m], pose, np.zeros_like(pose)
    )


def test_a_model_effect_equal_to_the_generators_has_cosine_one_and_size_ratio_one(
    et: ModuleType,
) -> None:
    rng = np.random.default_rng(1)
    base = [rng.normal(size=(4, 11)), rng.normal(size=(4, 11)), rng.normal(size=(2, 3))]
    effect = [rng.normal(size=(4, 11)), rng.normal(size=(4, 11)), rng.normal(size=(2, 3))]
    nominal = [result(0, base[0], base[2]), result(1, base[1], base[2])]
    # The twin lacks the effect; a perfect model at the truth moves the replay the same way.
    twin = [
        result(0, base[0] + effect[0], base[2] + effect[2]),
        result(1, base[1] + effect[1], base[2] + effect[2]),
    ]
    c = et.changes(nominal, twin, twin, SCALE, ["steps", "turns"])
    assert c["all"]["cos"] == pytest.approx(1.0)
    assert c["all"]["model"] == pytest.approx(c["all"]["gen"])
    assert set(c["drives"]) == {"0:steps", "1:turns"}
    # The opposite change: cosine -1, the same size.
    opposite = [
        result(0, base[0] - effect[0], base[2] - effect[2]),
        result(1, base[1] - effect[1], base[2] - effect[2]),
    ]
    c = et.changes(nominal, twin, opposite, SCALE, ["steps", "turns"])
    assert c["all"]["cos"] == pytest.approx(-1.0)
    assert c["all"]["model"] == pytest.approx(c["all"]["gen"])


def test_a_change_in_one_signal_group_shows_in_that_group_only(et: ModuleType) -> None:
    z = np.zeros((4, 11))
    nominal = [result(0, z, np.zeros((2, 3)))]
    moved = z.copy()
    moved[:, SIGNALS.index("wheel_3L")] = 2.0  # a free wheel only
    twin = [result(0, moved, np.zeros((2, 3)))]
    truth = [result(0, z, np.zeros((2, 3)) + 0.5)]  # the model moves the pose only
    c = et.changes(nominal, twin, truth, SCALE, ["pivots"])
    assert c["groups"]["free wheels"]["gen"] == pytest.approx(4.0)  # sqrt(4 rows x 2^2)
    assert c["groups"]["free wheels"]["model"] == 0.0
    assert c["groups"]["pose"]["gen"] == 0.0
    assert c["groups"]["pose"]["model"] == pytest.approx(np.sqrt(6 * 0.25))
    assert c["all"]["cos"] == 0.0  # orthogonal changes
    assert c["twin_left"] == pytest.approx(4.0)


def test_replays_of_different_windows_are_refused(et: ModuleType) -> None:
    a = [result(0, np.zeros((4, 11)), np.zeros((2, 3)))]
    b = [result(0, np.zeros((3, 11)), np.zeros((2, 3)))]
    with pytest.raises(ValueError, match="same windows"):
        et.changes(a, b, a, SCALE, ["steps"])


def test_the_summary_orders_effects_by_their_cosine_and_skips_failed_cases(
    et: ModuleType,
) -> None:
    def row(effect: str, gen: float, model: float, cos: float) -> dict[str, Any]:
        return {
            "effect": effect,
            "all": {"gen": gen, "model": model, "cos": cos},
            "twin_left": 10.0,
        }

    rows = [
        row("torque_limit", 20.0, 5.0, 0.1),
        row("command_delay", 30.0, 30.0, 0.99),
        row("command_delay", 10.0, 12.0, 0.95),
        {**row("command_delay", 1.0, 1.0, -1.0), "error": "boom"},
    ]
    lines = et.summary(rows)
    assert lines[2] == "| torque_limit | 1 | 2.00 | 0.25 | +0.10 | 0 |"
    assert lines[3] == "| command_delay | 2 | 2.00 | 1.10 | +0.97 | 2 |"


def test_motor_fields_are_scaled_by_numbers_and_set_by_words() -> None:
    """benchmarks/_motor.py: the ``--motor`` option of effect_twin, truth_ceiling and
    group_reads."""
    import argparse

    from rover_env.config import load_rover

    mo = load_bench("_motor")
    assert mo.parse_motor("speed_gain=2.1") == ("speed_gain", 2.1)
    assert mo.parse_motor("anti_windup=conditional") == ("anti_windup", "conditional")
    with pytest.raises(SystemExit, match="speed_gian"):
        mo.parse_motor("speed_gian=2")
    with pytest.raises(SystemExit, match="FIELD=FACTOR"):
        mo.parse_motor("speed_gain")
    ap = argparse.ArgumentParser()
    mo.add_motor_argument(ap)
    args = ap.parse_args(["--motor", "armature=2", "--motor", "anti_windup=conditional"])
    assert mo.motors(args) == {"armature": 2.0, "anti_windup": "conditional"}
    assert mo.motors(ap.parse_args([])) == {}
    cfg = load_rover()
    m = mo.with_motor(cfg, {"speed_gain": 2.0, "anti_windup": "conditional"}).motor
    assert m.speed_gain == pytest.approx(2 * cfg.motor.speed_gain)
    assert m.anti_windup == "conditional"
    assert m.integral_gain == cfg.motor.integral_gain


def test_visibility_splits_at_the_naming_tests_gain(et: ModuleType) -> None:
    # 10 % of the held-out loss for an orthogonal change: Δ / R = sqrt(0.1 / 0.9).
    assert et.VISIBLE == pytest.approx(1 / 3)

    def row(gen: float, named: bool) -> dict[str, Any]:
        return {
            "all": {"gen": gen, "model": 1.0, "cos": 1.0},
            "twin_left": 30.0,
            "named_right": named,
        }

    rows = [row(10.5, True), row(9.5, True), row(2.0, False), {**row(50.0, True), "error": "x"}]
    lines = et.visibility(rows)
    assert lines[2] == "| >= 0.33 | 1 | 1 |"
    assert lines[3] == "| < 0.33 | 2 | 1 |"
