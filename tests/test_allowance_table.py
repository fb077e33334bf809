"""The clean-fit allowance diagnose widens named intervals by (stop 74): the shipped table,
its validation, the widening itself and where diagnose applies it."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnose import add_cli
from rover_env.calibration.diagnosis.select import allow_form
from rover_env.calibration.diagnosis.state import Diagnosis, Options
from rover_env.calibration.fit import Fit
from rover_env.calibration.form_allowance import (
    Bias,
    FormAllowance,
    load_allowance,
    reach_floor,
    widen,
)
from rover_env.config import ConfigError


def _fit(name: str, x: list[float], half: float) -> Fit:
    (c,) = catalogue([name])
    xa = np.array(x)
    se = np.full(len(x), half / 1.96)
    return Fit([c], xa, xa - half, xa + half, se, 0.0, 0, c.to_ext(xa), 0.0, "train")


def _finishing(**switches: bool) -> SimpleNamespace:
    """Options for finishing a named fit with no replays: no polish, no noise draws, no
    soil read; ``switches`` beside them."""
    return SimpleNamespace(
        noise_draws=0, polish=0, soil_from_motion=False, soil_from_straight=False, **switches
    )


def test_the_shipped_table_loads_and_every_bias_is_ordered() -> None:
    a = load_allowance()
    assert {"command_delay", "slope", "torque_limit"} <= set(a.effects)
    for name, b in a.effects.items():
        assert b.low <= b.high and b.cases >= 10, name
    # The delay bias measured on clean logs is one-sided (a delay is never negative), so it
    # pads an interval from below only.
    delay = a.effects["command_delay"]
    assert 0.0 <= delay.low < delay.high and a.pad("command_delay") == (delay.high, 0.0)


def test_the_shipped_soil_factor_brackets_one() -> None:
    """Stop 81: a soil's stiffness is fitted a factor off the truth either way."""
    b = load_allowance().effects["loose_soil"]
    assert 0.0 < b.low < 1.0 < b.high and b.cases >= 40


def test_a_soil_fit_is_widened_by_its_factor_and_never_withdrawn() -> None:
    from rover_env.calibration.diagnosis.judge import allowance_reaches_off

    a = FormAllowance({"loose_soil": Bias(0.5, 3.5, 80)})
    assert a.pad("loose_soil") == (3.5, 0.5)  # fit = truth x f, f in [low, high]
    f = _fit("loose_soil", [1.0], 0.05)  # u = 1e6 / k_phi: k_phi 1e6 [0.952e6, 1.053e6]
    _, lo0, hi0 = f.physical()["loose_soil"]["k_phi"]
    f.allowance = {"loose_soil": a.pad("loose_soil")}
    v, lo, hi = f.physical()["loose_soil"]["k_phi"]
    assert (
        v == pytest.approx(1e6)
        and lo == pytest.approx(lo0 / 3.5)
        and hi == pytest.approx(hi0 / 0.5)
    )
    assert allowance_reaches_off(f) == []
    soft = _fit("loose_soil", [0.05], 0.2)  # reaches u = 0 (hard ground): k_phi up to inf
    soft.allowance = {"loose_soil": a.pad("loose_soil")}
    assert math.isinf(soft.physical()["loose_soil"]["k_phi"][2])
    assert allowance_reaches_off(soft) == []  # whether soil is there is the windows' question


def test_pad_turns_the_spread_into_how_far_the_truth_may_sit() -> None:
    a = FormAllowance(
        {
            "command_delay": Bias(0.0, 0.027, 50),
            "friction": Bias(-0.23, 0.06, 50),
            "slope": Bias(0.3, 2.4, 50),
        }
    )
    # fit = truth + b with b in [low, high]: truth in [lo - high, hi - low].
    assert a.pad("command_delay") == (0.027, 0.0)
    assert a.pad("friction") == (0.06, 0.23)
    assert a.pad("slope") == (2.4, 2.4)  # a spurious tilt adds in any direction
    assert a.pad("command_lag") is None


def test_the_truth_beyond_right_names_pads_each_side_by_the_larger() -> None:
    """Stop 99: a lag that is there is fitted a little short (spent case 52505: 0.4455 s
    fitted 0.432 [0.380, 0.443]), where clean drives only add lag; each side takes the
    larger of the clean spread and how far right names missed on that side."""
    a = FormAllowance(
        {
            "command_lag": Bias(0.0, 0.042, 100, below=0.0, above=0.0022, named=57),
            "command_delay": Bias(0.002, 0.032, 100, below=0.022, above=0.0, named=66),
            "slope": Bias(0.27, 2.4, 100, below=0.45, above=3.0, named=32),
            "friction": Bias(-0.23, 0.06, 50),
        }
    )
    assert a.pad("command_lag") == (0.042, 0.0022)
    assert a.pad("command_delay") == (0.032, 0.0)  # the clean spread is the larger below
    assert a.pad("slope") == (2.4, 3.0)
    assert a.pad("friction") == (0.06, 0.23)  # not measured: the clean spread alone
    # the naming bar reads the side toward "off" (below a lag's fit): unchanged by ``above``
    assert a.edge("command_lag", "+") == 0.042
    lo, hi = widen("command_lag", 0.380, 0.443, a.pad("command_lag") or (0, 0), (0.0, 2.0))
    # 52505's own truth stays 0.3 ms outside: a 95 % quantile leaves about 1 in 20 out
    assert lo == pytest.approx(0.338) and hi == pytest.approx(0.4452) and hi < 0.4455
    with pytest.raises(ConfigError, match="above must be"):
        Bias(0.0, 0.04, 10, above=-0.001)


def test_physical_interval_carries_the_allowance_within_the_range() -> None:
    f = _fit("command_delay", [0.05], 0.005)
    f.allowance = {"command_delay": (0.027, 0.0)}
    (v, lo, hi) = f.physical()["command_delay"]["delay"]
    assert (v, lo, hi) == pytest.approx((0.05, 0.018, 0.055))
    assert f.physical(allow=False)["command_delay"]["delay"] == pytest.approx((0.05, 0.045, 0.055))
    f.allowance = {"command_delay": (0.2, 0.0)}
    assert f.physical()["command_delay"]["delay"][1] == 0.0  # not below the range
    # A tilt of 5 degrees: the magnitude's interval, at least level.
    s = _fit("slope", [3.0, 4.0], 0.1)
    base = s.physical()["slope"]["deg"]
    s.allowance = {"slope": (2.4, 2.4)}
    v, lo, hi = s.physical()["slope"]["deg"]
    assert v == pytest.approx(5.0)
    assert lo == pytest.approx(base[1] - 2.4) and hi == pytest.approx(base[2] + 2.4)
    s.allowance = {"slope": (9.0, 9.0)}
    assert s.physical()["slope"]["deg"][1] == 0.0
    assert math.isnan(s.physical()["slope"]["heading_deg"][1])  # the heading is untouched


def test_the_far_end_floor_moves_only_the_end_away_from_off() -> None:
    """Stop 101: a lag fitted 0.1974 [0.1912, 0.2035] for a truth of 0.2084 (case 71923):
    the upper end at least the reach beyond the fit; the end towards off never moves."""
    assert reach_floor(0.1974, 0.1912, 0.2035, 0.0111, 0.0, (0.0, 1.0)) == pytest.approx(
        (0.1912, 0.2085)
    )
    assert reach_floor(0.1974, 0.1912, 0.25, 0.0111, 0.0, (0.0, 1.0)) == (0.1912, 0.25)
    assert reach_floor(0.99, 0.98, 0.995, 0.0111, 0.0, (0.0, 1.0))[1] == 1.0  # the range's end
    # a radius below off reaches down
    assert reach_floor(-0.05, -0.052, -0.048, 0.005, 0.0, (-0.2, 0.2)) == pytest.approx(
        (-0.055, -0.048)
    )
    assert reach_floor(0.1, 0.09, 0.11, 0.0, 0.0, (0.0, 1.0)) == (0.09, 0.11)
    f = _fit("command_lag", [0.1974], 0.0061)
    f.allowance = {"command_lag": (0.0417, 0.0027)}
    f.reach = {"command_lag": 0.0111}
    _v, lo, hi = f.physical()["command_lag"]["tau"]
    assert lo == pytest.approx(0.1974 - 0.0061 - 0.0417) and hi == pytest.approx(0.2085)
    f.allowance = {}
    assert f.physical()["command_lag"]["tau"][1] == pytest.approx(0.1974 - 0.0061)
    s = _fit("slope", [3.0, 4.0], 0.1)
    s.reach = {"slope": 1.74}
    assert s.physical()["slope"]["deg"][2] == pytest.approx(6.74)


def test_the_shipped_reach_is_read_and_carried_by_allow_form() -> None:
    table = load_allowance()
    assert table.reach("command_lag") > 0.0 and table.reach("loose_soil") == 0.0
    lag = SimpleNamespace(fit=_fit("command_lag", [0.2], 0.005))
    d = SimpleNamespace(chosen=[lag], allowance=table, say=[].append)
    allow_form(d)  # type: ignore[arg-type]
    assert lag.fit.reach == {"command_lag": table.reach("command_lag")}
    with pytest.raises(ConfigError, match="reach"):
        Bias(0.0, 0.04, 10, reach=-0.001)


def test_allow_form_widens_named_effects_only_and_says_so() -> None:
    delay = SimpleNamespace(fit=_fit("command_delay", [0.05], 0.005))
    lag = SimpleNamespace(fit=_fit("command_lag", [0.1], 0.01))
    said: list[str] = []
    table = FormAllowance({"command_delay": Bias(0.0, 0.027, 50)})
    d = SimpleNamespace(chosen=[delay, lag], allowance=table, say=said.append)
    allow_form(d)  # type: ignore[arg-type]
    assert delay.fit.allowance == {"command_delay": (0.027, 0.0)} and lag.fit.allowance == {}
    assert len(said) == 1 and "clean-fit allowance" in said[0]
    off = SimpleNamespace(fit=_fit("command_delay", [0.05], 0.005))
    allow_form(SimpleNamespace(chosen=[off], allowance=None, say=said.append))  # type: ignore[arg-type]
    assert off.fit.allowance == {}


def test_a_bad_table_fails_before_any_work_naming_file_and_key(tmp_path: Path) -> None:
    bad = tmp_path / "a.yaml"
    bad.write_text("effects:\n  command_delay: {low: 0.03, high: 0.01, cases: 5}\n")
    with pytest.raises(ConfigError, match=r"a\.yaml.*effects\.command_delay.*low"):
        load_allowance(bad)
    bad.write_text("effects:\n  warp_drive: {low: 0.0, high: 0.01, cases: 5}\n")
    with pytest.raises(ConfigError, match=r"a\.yaml: effects\.warp_drive: not a catalogue"):
        load_allowance(bad)
    bad.write_text("effects:\n  loose_soil: {low: 0.0, high: 3.0, cases: 5}\n")
    with pytest.raises(ConfigError, match=r"a\.yaml: effects\.loose_soil\.low: a factor"):
        load_allowance(bad)
    bad.write_text("effects:\n  command_lag: {low: 0.0, high: 0.04, cases: 5, above: .nan}\n")
    with pytest.raises(ConfigError, match=r"a\.yaml.*effects\.command_lag.*above"):
        load_allowance(bad)
    bad.write_text("effects:\n  command_delay: {low: 0.0, hgh: 0.01, cases: 5}\n")
    with pytest.raises(ConfigError, match=r"unknown key.*hgh"):
        load_allowance(bad)
    with pytest.raises(ConfigError, match="not found"):
        Diagnosis([], tmp_path, Options(form_allowance=str(tmp_path / "none.yaml")))


def test_command_line_switches_the_allowance() -> None:
    import argparse

    ap = argparse.ArgumentParser()
    add_cli(ap.add_subparsers())
    on = ap.parse_args(["diagnose", "x.csv", "--out", "o"])
    off = ap.parse_args(["diagnose", "x.csv", "--out", "o", "--no-form-allowance"])
    assert on.form_allowance == Options.form_allowance and not on.no_form_allowance
    assert off.no_form_allowance


def test_the_bench_counts_coverage_with_and_without_the_allowance() -> None:
    from _bench import load_bench

    rules = load_bench("_rules")
    result = {
        "final": {
            "command_delay": {
                "params": {"command_delay": {"delay": [0.09, 0.054, 0.10]}},
                "params_without_allowance": {"command_delay": {"delay": [0.09, 0.081, 0.10]}},
            }
        }
    }
    assert rules.raw_interval(result, "command_delay") == (0.081, 0.10)
    assert rules.raw_interval(result, "command_lag") is None
    assert rules.raw_interval({"final": {"command_delay": {"params": {}}}}, "command_delay") is None
    row = {"truth": 0.075, "lo": 0.054, "hi": 0.10, "lo_raw": 0.081, "hi_raw": 0.10}
    cov = load_bench("bench_diagnose").covers
    assert cov(row) and not cov(rules.without_allowance(row))
    old = {"truth": 0.075, "lo": 0.054, "hi": 0.10}  # a row before stop 74: as it is
    assert cov(rules.without_allowance(old))


def test_the_allowance_never_decides_whether_an_effect_is_there() -> None:
    from rover_env.calibration.diagnosis.judge import interval_reaches_off

    s = _fit("slope", [3.0, 4.0], 0.1)  # 5 degrees, clear of level
    s.allowance = {"slope": (9.0, 9.0)}  # widened down to level in the report
    assert s.physical()["slope"]["deg"][1] == 0.0
    assert interval_reaches_off(s) == []  # judged on the fit's own interval


def test_an_interval_the_allowance_takes_to_off_is_named_no_more() -> None:
    """Stop 77: a named effect whose interval for the truth, the clean-fit allowance in it,
    reaches "off" is withdrawn; one clear of it stays, and so does everything when the
    option is off or the effect has no allowance."""
    from rover_env.calibration.diagnosis.judge import allowance_reaches_off
    from rover_env.calibration.diagnosis.select import withdraw_within_allowance

    def named(name: str, x: list[float], half: float, pad: tuple[float, float]) -> Any:
        s = SimpleNamespace(fit=_fit(name, x, half), test="")
        s.fit.allowance = {name: pad}
        return s

    strong = named("command_delay", [0.05], 0.005, (0.027, 0.0))  # [0.018, 0.055]
    weak = named("command_delay", [0.02], 0.005, (0.027, 0.0))  # [0, 0.025]
    tilt = named("slope", [1.2, 1.6], 0.1, (2.4, 2.4))  # 2 deg: [0, 4.6]
    steep = named("slope", [3.0, 4.0], 0.1, (2.4, 2.4))  # 5 deg: [2.4, 7.6]
    bare = named("command_lag", [0.01], 0.009, (0.0, 0.0))  # no allowance: not judged here
    assert allowance_reaches_off(weak.fit) == ["command_delay.delay"]
    assert allowance_reaches_off(tilt.fit) == ["slope.deg"]
    assert allowance_reaches_off(strong.fit) == allowance_reaches_off(steep.fit) == []
    assert allowance_reaches_off(bare.fit) == []

    def diag(chosen: list[Any], on: bool = True) -> Any:
        return SimpleNamespace(
            opts=SimpleNamespace(name_beyond_allowance=on, presence_on_windows=False),
            chosen=list(chosen),
            demoted=[],
            allowance_withdrawn=None,
            winner=chosen[0],
            w_floor={"wheel_3L": 2.0},
            noise={"wheel_3L": 1.0},
            final_floor={"wheel_3L": 3.0},
            say=lambda m: None,
        )

    d = diag([strong, tilt])
    d.winner = strong
    withdraw_within_allowance(d)
    assert d.chosen == [strong] and d.demoted == [tilt]
    assert d.allowance_withdrawn["effects"] == ["slope"] and "clean-fit" in tilt.test
    assert d.final_floor == d.w_floor  # the winner alone stays: its own floor
    d = diag([weak])
    withdraw_within_allowance(d)
    assert d.chosen == [] and d.final_floor == d.noise
    d = diag([weak], on=False)
    withdraw_within_allowance(d)
    assert d.chosen == [weak] and d.allowance_withdrawn is None
    d = diag([steep, bare])
    withdraw_within_allowance(d)
    assert d.chosen == [steep, bare] and d.final_floor == {"wheel_3L": 3.0}


def test_each_effect_of_a_pair_is_judged_by_its_own_allowance(monkeypatch: Any) -> None:
    """Stop 78: a pair fit's effects each carry their own allowance; a partner within its
    allowance is withdrawn and the other effect is named only by its own single fit,
    finished and judged the same way (block 52000: a 0.79 deg slope beside a lag stayed
    named because only one-effect fits were judged)."""
    from rover_env.calibration.diagnosis import select as sel
    from rover_env.calibration.diagnosis.judge import allowance_reaches_off
    from rover_env.calibration.fit import stack_fits

    table = FormAllowance({"command_lag": Bias(0.0, 0.04, 50), "slope": Bias(0.3, 2.4, 50)})

    def pair(lag: float, tilt: float) -> Any:
        f = stack_fits(_fit("command_lag", [lag], 0.01), _fit("slope", [tilt, 0.0], 0.1))
        return SimpleNamespace(fit=f, test="")

    def diag(chosen: list[Any]) -> Any:
        return SimpleNamespace(
            opts=_finishing(name_beyond_allowance=True, presence_on_windows=False),
            ev=None,
            chosen=list(chosen),
            demoted=[],
            allowance=table,
            allowance_withdrawn=None,
            noise={"wheel_3L": 1.0},
            final_floor={"wheel_3L": 3.0},
            say=lambda m: None,
        )

    p = pair(0.30, 0.8)  # a strong lag beside a 0.8 deg tilt
    d = diag([p])
    sel.allow_form(d)
    assert p.fit.allowance == {"command_lag": (0.04, 0.0), "slope": (2.4, 2.4)}
    phys = p.fit.physical()
    assert phys["command_lag"]["tau"][1] == pytest.approx(0.30 - 0.01 - 0.04)
    assert phys["slope"]["deg"][1] == 0.0  # 0.8 - 0.1 - 2.4, at least level
    assert allowance_reaches_off(p.fit) == ["slope.deg"]
    strong = pair(0.30, 5.0)
    sel.allow_form(diag([strong]))
    assert allowance_reaches_off(strong.fit) == []

    lag_alone = SimpleNamespace(fit=_fit("command_lag", [0.29], 0.01), test="", fit_scale=None)
    calls: list[list[str]] = []

    def alone(d: Any, partners: list[str]) -> Any:
        calls.append(partners)
        return (lag_alone, {"wheel_3L": 2.0}) if lag_alone is not None else None

    monkeypatch.setattr(sel, "partner_alone", alone)
    sel.withdraw_within_allowance(d)
    assert calls == [["command_lag"]]
    assert d.chosen == [lag_alone] and d.demoted == [p]
    assert d.allowance_withdrawn["effects"] == ["slope"]
    assert d.allowance_withdrawn["kept"] == "command_lag" and "beside" not in d.allowance_withdrawn
    assert set(d.allowance_withdrawn["params"]) == {"slope"}
    assert lag_alone.fit.allowance == {"command_lag": (0.04, 0.0)}  # finished as the pair was
    assert d.final_floor == {"wheel_3L": 2.0}

    # The partner alone fails its own naming: nothing is named, the partner is "beside".
    lag_alone = None  # type: ignore[assignment]
    d = diag([pair(0.30, 0.8)])
    sel.allow_form(d)
    sel.withdraw_within_allowance(d)
    assert d.chosen == [] and d.allowance_withdrawn["beside"] == ["command_lag"]
    assert d.final_floor == d.noise
    # The partner alone lies within its own allowance: withdrawn too.
    lag_alone = SimpleNamespace(fit=_fit("command_lag", [0.02], 0.01), test="", fit_scale=None)
    d = diag([pair(0.30, 0.8)])
    sel.allow_form(d)
    sel.withdraw_within_allowance(d)
    assert d.chosen == [] and d.allowance_withdrawn["beside"] == ["command_lag"]
    # Both effects of the pair within their allowance: both withdrawn, nobody asked alone.
    calls.clear()
    d = diag([pair(0.02, 0.8)])
    sel.allow_form(d)
    sel.withdraw_within_allowance(d)
    assert d.chosen == [] and sorted(d.allowance_withdrawn["effects"]) == ["command_lag", "slope"]
    assert calls == [] and "beside" not in d.allowance_withdrawn


def test_after_a_withdrawal_the_next_candidate_is_tried_alone(monkeypatch: Any) -> None:
    """Stop 88: when the allowance withdraws every name, the next significant candidate in
    the naming order is named by its own fit, judged by its own allowance, as one under its
    detection limit lets the next be tried (study 65000: a 2.9 deg slope withdrawn hid a
    rolling resistance of 0.106 [0.071, 0.114] for 0.076). A torque limit is not tried, and
    nothing is when a name stays or the option is off."""
    from rover_env.calibration.diagnosis import select as sel

    table = FormAllowance(
        {
            "rolling_resistance": Bias(0.0, 0.032, 50),
            "friction": Bias(-0.226, 0.059, 50),
            "slope": Bias(0.3, 2.4, 50),
        }
    )

    def cand(name: str, x: list[float], half: float, d_bic: float) -> Any:
        f = _fit(name, x, half)
        return SimpleNamespace(
            fit=f, test="", fit_scale=None, significant=True, d_bic=d_bic, gain=0.3,
            n_train=40, held_losses=[1.0] * 10,
        )  # fmt: skip

    def diag(ranked: list[Any], on: bool = True) -> Any:
        slope = ranked[0]
        return SimpleNamespace(
            opts=_finishing(next_after_withdrawn=on, pegged_last=False, presence_on_windows=False),
            ev=None,
            ranked=ranked,
            winner=slope,
            chosen=[],
            demoted=[slope],
            allowance=table,
            allowance_withdrawn={"effects": ["slope"], "params": {"slope": "deg=2.9 [0, 5]"}},
            noise={"wheel_3L": 1.0},
            final_floor={"wheel_3L": 1.0},
            say=lambda m: None,
        )

    judged: list[str] = []

    def alone(d: Any, s: Any) -> Any:
        judged.append(s.fit.name)
        return None if s.fit.name == "command_delay" else {"wheel_3L": 2.0}

    monkeypatch.setattr(sel, "named_alone", alone)
    slope = cand("slope", [2.0, 2.1], 0.2, -30.0)
    limit = cand("torque_limit", [-0.5], 0.05, -29.0)
    rr = cand("rolling_resistance", [0.106], 0.02, -20.0)  # [0.086, 0.126]: clear of 0.032
    fr = cand("friction", [-0.42], 0.06, -3.5)
    d = diag([fr, limit, rr, slope][::-1])  # ranked: the winner first, the order by d_bic
    sel.name_next(d)
    assert judged == ["rolling_resistance"]  # the limit is skipped, the friction not reached
    assert d.chosen == [rr] and d.allowance_withdrawn["next"] == "rolling_resistance"
    assert d.final_floor == {"wheel_3L": 2.0} and rr.fit.allowance == {
        "rolling_resistance": (0.032, 0.0)
    }

    # Within its own allowance the next one is withdrawn too, and the one after is tried.
    judged.clear()
    weak = cand("rolling_resistance", [0.04], 0.01, -20.0)  # [0.03, 0.05] - 0.032 reaches 0
    delay = cand("command_delay", [0.05], 0.005, -10.0)  # not named by its own fit
    d = diag([slope, weak, delay, fr])
    sel.name_next(d)
    assert judged == ["rolling_resistance", "command_delay", "friction"]
    assert d.chosen == [fr] and d.allowance_withdrawn["next"] == "friction"
    assert d.allowance_withdrawn["effects"] == ["slope", "rolling_resistance"]
    assert set(d.allowance_withdrawn["params"]) == {"slope", "rolling_resistance"}
    assert d.demoted == [slope, weak] and "clean-fit" in weak.test

    # Nothing left to name: nothing named, the nominal floor.
    judged.clear()
    d = diag([slope, cand("rolling_resistance", [0.04], 0.01, -20.0)])
    sel.name_next(d)
    assert d.chosen == [] and "next" not in d.allowance_withdrawn
    assert d.final_floor == d.noise
    # Off, or a name kept: nothing tried.
    judged.clear()
    for d in (diag([slope, rr], on=False), diag([slope, rr])):
        if d.opts.next_after_withdrawn:
            d.chosen = [slope]
        sel.name_next(d)
    assert judged == []


def test_the_naming_bar_is_where_the_allowance_stops_withdrawing_a_sharp_fit() -> None:
    """The report's "named from": per side, the larger of the detection limit and the
    allowance's edge; a fit just past the edge (a narrow interval) is not withdrawn, one
    just short of it is, on both sides of off and for a tilt."""
    from rover_env.calibration.diagnosis.judge import allowance_reaches_off
    from rover_env.calibration.form_allowance import naming_bar

    a = FormAllowance(
        {
            "friction": Bias(-0.23, 0.06, 50),
            "slope": Bias(0.3, 2.4, 50),
            "loose_soil": Bias(0.57, 3.4, 50),
        }
    )
    assert a.edge("friction", "+") == 0.06 and a.edge("friction", "-") == 0.23
    assert a.edge("slope", "deg") == 2.4
    assert a.edge("loose_soil", "+") == 0.0  # a factor never withdraws a name
    assert a.edge("command_lag", "+") == 0.0  # no entry
    bar = naming_bar("friction", {"+": 0.02, "-": 0.4, "x+": 9.0}, a)
    assert bar == {"+": 0.06, "-": 0.4}  # the larger of the two; a slope's axes left out
    assert naming_bar("friction", {"+": math.inf}, a) == {}  # never paid: not a bar
    assert naming_bar("friction", {"+": 0.02}, None) == {"+": 0.02}
    for name, side, x in (("friction", "+", 0.06), ("friction", "-", -0.23), ("slope", "deg", 2.4)):
        for k, withdrawn in ((1.02, False), (0.98, True)):
            point = [x * k] if name != "slope" else [0.0, x * k]
            f = _fit(name, point, 0.001)
            f.allowance = {name: a.pad(name)}  # type: ignore[dict-item]
            assert bool(allowance_reaches_off(f)) is withdrawn, (name, side, k)
