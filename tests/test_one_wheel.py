"""A rolling resistance only one free wheel feels is not named (stage 5c, :mod:`.one_wheel`)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis.one_wheel import free_wheel_difference, withdraw_one_wheel
from rover_env.calibration.diagnosis.state import ODOMETRY_BAND, Options
from rover_env.calibration.fit import Fit


def _scored(name: str, value: float) -> SimpleNamespace:
    (c,) = catalogue([name])
    x = np.array([value])
    fit = Fit([c], x, x - 0.01, x + 0.01, x * 0 + 0.005, 0.0, 0, c.to_ext(x), 0.0, "train")
    return SimpleNamespace(fit=fit, test="")


def _diagnosis(chosen: list[Any], left: float, right: float, **opts: Any) -> Any:
    both = (left + right) / 2
    return SimpleNamespace(
        opts=Options(progress=False, **opts),
        chosen=list(chosen),
        demoted=[],
        odometry={"difference": {"both": both, "3L": left, "3R": right, "driven": 0.0}},
        noise={"wheel_3L": 1.0},
        final_floor={},
        one_wheel=None,
        say=lambda *_: None,
    )


def test_a_rolling_resistance_one_free_wheel_feels_is_withdrawn() -> None:
    """Spent case 52463 (a 0.19 N m brake on wheel 3L named c_rr 0.081): 3L +3.0 %, 3R -3.3 %
    against the named model's twins, 6.3 % apart, beyond the 5 % split limit."""
    rr = _scored("rolling_resistance", 0.08)
    d = _diagnosis([rr], 0.0304, -0.0330)
    withdraw_one_wheel(d)
    assert d.chosen == [] and d.demoted == [rr]
    assert d.final_floor == d.noise
    rec = d.one_wheel
    assert rec["withdrawn"] and rec["effects"] == ["rolling_resistance"]
    assert rec["split"] == pytest.approx(0.0634) and rec["limit"] == ODOMETRY_BAND.split
    assert "rolling_resistance" in rec["params"] and "beside" not in rec
    assert rr.test.startswith("not named: the free wheels disagree (3L +3.04%, 3R -3.30%")


def test_both_free_wheels_agreeing_keep_the_name() -> None:
    """The spent rolling-resistance singles named right (52409, 65018, 66009) had their free
    wheels 2.3, 0.9 and -1.8 % apart: within the limit, the name stands and is recorded."""
    for left, right in ((0.0233, 0.0), (0.004, -0.005), (-0.010, 0.008)):
        rr = _scored("rolling_resistance", 0.04)
        d = _diagnosis([rr], left, right)
        withdraw_one_wheel(d)
        assert d.chosen == [rr] and d.demoted == [] and not d.one_wheel["withdrawn"]
        assert d.one_wheel["split"] == pytest.approx(left - right)


def test_only_a_rolling_resistance_is_judged_and_the_switch_turns_it_off() -> None:
    """Other effects are left alone (a lag acts on the driven wheels' commands; a slope
    across the track parts the free wheels, 4 % on spent case 52310); ``one_wheel=False`` leaves everything as named; an unknown split
    (no straight, moving interval) withdraws nothing."""
    lag = _scored("command_lag", 0.1)
    d = _diagnosis([lag], 0.05, -0.05)
    withdraw_one_wheel(d)
    assert d.chosen == [lag] and d.one_wheel is None
    rr = _scored("rolling_resistance", 0.08)
    off = _diagnosis([rr], 0.05, -0.05, one_wheel=False)
    withdraw_one_wheel(off)
    assert off.chosen == [rr] and off.one_wheel is None
    nan = _diagnosis([rr], float("nan"), 0.0)
    withdraw_one_wheel(nan)
    assert nan.chosen == [rr] and not nan.one_wheel["withdrawn"]


def test_what_stays_named_keeps_its_name(monkeypatch) -> None:
    """A withdrawn rolling resistance beside another named fit: the other stays (its floor
    is the kept model's)."""
    import rover_env.calibration.diagnosis.select as select

    rr, delay = _scored("rolling_resistance", 0.08), _scored("command_delay", 0.05)
    d = _diagnosis([delay, rr], 0.04, -0.03)
    floors: list[Any] = []
    monkeypatch.setattr(select, "chosen_floor", lambda d_, ch: floors.append(ch) or {"kept": 1.0})
    withdraw_one_wheel(d)
    assert d.chosen == [delay] and d.demoted == [rr] and floors == [[delay]]
    assert d.final_floor == {"kept": 1.0}


def test_the_report_says_which_wheel_to_inspect() -> None:
    from rover_env.calibration.report import _headline

    rec = {
        "3L": 0.0304,
        "3R": -0.0330,
        "split": 0.0634,
        "limit": 0.05,
        "withdrawn": True,
        "effects": ["rolling_resistance"],
        "params": {"rolling_resistance": "c_rr=0.08052 [0.0391, 0.0885]"},
    }
    base = {"unexplained": [], "above_floor": [], "named": []}
    text = "\n".join(_headline({**base, "one_wheel": rec}, [], [], None))
    assert text.startswith(
        "**Nothing named.** Fitted but not named: rolling_resistance c_rr=0.08052"
    )
    assert "6.3 % apart, beyond the 5 %" in text and "Free wheel 3L turns the less" in text
    kept = "\n".join(_headline({**base, "one_wheel": {**rec, "withdrawn": False}}, [], [], None))
    assert "free wheels" not in kept


@pytest.mark.parametrize(
    ("effects", "apart"),
    [
        ({"brake_drag": {"torque": 0.3, "wheel": 4}}, True),
        ({"brake_drag": {"torque": 0.3, "wheel": 5}}, True),
        ({"rolling_resistance": {"c_rr": 0.06}}, False),
    ],
)
def test_another_implementation_s_dragging_brake_parts_the_free_wheels(
    tmp_path, effects: dict[str, dict[str, float]], apart: bool
) -> None:
    """A physics check of the statistic on the independent generator's logs (its own rover,
    brake and soil code; built to drawing): a 0.3 N m brake on one free wheel parts the two
    wheels' travel against the nominal model's twins beyond the limit, that wheel the one
    held back; a rolling resistance of 0.06 drags both alike."""
    from rover_env.calibration.replay import ReplaySettings, prepare
    from rover_env.config import load_rover
    from rover_env.independent import make_independent_logs
    from rover_env.logs import read_log

    paths = make_independent_logs(
        tmp_path, effects, drives=1, seed=11, duration=30.0, nuisance=False
    )
    cfg = load_rover()
    prepared = [prepare(read_log(p), cfg, "drive", ReplaySettings()) for p in paths]
    d = SimpleNamespace(odometry=None, base=cfg, prepared=prepared, chosen=[])
    d.ev = SimpleNamespace(config=lambda ext: cfg)
    diff = free_wheel_difference(d)  # type: ignore[arg-type]
    split = diff["3L"] - diff["3R"]
    assert (abs(split) > ODOMETRY_BAND.split) == apart, diff
    if apart:
        assert (split > 0) == (effects["brake_drag"]["wheel"] == 4)


def test_the_split_benchmark_takes_each_plan_s_cases_round_robin() -> None:
    """``benchmarks/one_wheel_split.py``: every plan's first rolling-resistance single and
    first clean case, then the seconds, ...; each case once, from its own plan's seeds."""
    from _bench import load_bench

    bench = load_bench("one_wheel_split")
    got = bench.planned(60000, 2, ["single_rolling_resistance", "clean"])
    assert len(got) == 2 * (5 + 10) and len({c["seed"] for c in got}) == len(got)
    first = [bench.tag(c) for c in got[:4]]
    assert [t.rsplit("_", 1)[0] for t in first] == [
        "single_rolling_resistance",
        "clean_none",
        "single_rolling_resistance",
        "clean_none",
    ]
    assert [c["seed"] // 100 for c in got[:4]] == [600, 600, 601, 601]
    assert all(c["seed"] // 100 in (600, 601) for c in got)


def test_a_pair_s_other_effect_is_not_named_by_the_pair_s_fit() -> None:
    """A rolling resistance fitted together with a delay and withdrawn: the delay was fitted
    beside it, so it is named only by its own fit; with no single fit of it at hand it is
    listed ``beside``, and only the rolling resistance's value is given as withdrawn."""
    from rover_env.calibration.candidates import merge

    rr, delay = catalogue(["rolling_resistance", "command_delay"])
    x = np.array([0.08, 0.05])
    ext = merge(rr.to_ext(x[:1]), delay.to_ext(x[1:]))
    pair = SimpleNamespace(
        fit=Fit([rr, delay], x, x - 0.01, x + 0.01, x * 0 + 0.005, 0.0, 0, ext, 0.0, "train"),
        test="",
    )
    d = _diagnosis([pair], 0.04, -0.03)
    d.ranked = []
    withdraw_one_wheel(d)
    assert d.chosen == [] and d.demoted == [pair]
    assert d.one_wheel["beside"] == ["command_delay"]
    assert list(d.one_wheel["params"]) == ["rolling_resistance"]
