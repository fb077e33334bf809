"""A second effect is named only if it reaches its detection limit beside the winner (stop
90, :func:`rover_env.calibration.diagnosis.select.partner_limits`). Built on stand-in
replays whose answer is known in closed form, as tests/test_detection_limit.py."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis.fit_stage import detection_limit
from rover_env.calibration.diagnosis.select import first_confident, partner_limits
from rover_env.calibration.diagnosis.state import Options, Scored
from rover_env.calibration.fit import Fit
from rover_env.calibration.replay import SIGNALS

N = 64  # windows
T = 10  # scored rows per window
TAU = 0.3  # the winner's lag


class FakeEv:
    """Replays whose residual on wheel_1L is 2 without the winner's lag and 1 with it (the
    lag explains three quarters of the squared residual), plus, for a friction fraction f,
    f on wheel_2L in every window."""

    def __init__(self) -> None:
        self.scale = dict.fromkeys(SIGNALS, 1.0)
        self.runs: list[dict] = []

    def run(self, ext: dict, which: str) -> list:
        self.runs.append(ext)
        tau = ext.get("command_lag", {}).get("tau", 0.0)
        f = ext.get("friction", {}).get("fraction", 0.0)
        out = []
        for _ in range(N):
            resid = np.zeros((T, 11))
            resid[:, 0] = 1.0 if tau == TAU else 2.0
            resid[:, 2] = f
            out.append(SimpleNamespace(resid=resid, pose_resid=np.zeros((1, 3))))
        return out


def closed_form(base: float) -> float:
    # E = T m^2 against R = T base^2 in every window: N log(1 + (m / base)^2) = ln N.
    return base * math.sqrt(math.expm1(math.log(N) / N))


def test_the_limit_beside_the_winner_is_against_what_the_winner_leaves() -> None:
    (fr,) = catalogue(["friction"])
    ev = FakeEv()
    alone = detection_limit(ev, fr, "train", ev.scale)["-"]  # type: ignore[arg-type]
    beside = detection_limit(
        ev,  # type: ignore[arg-type]
        fr,
        "train",
        ev.scale,
        hold={"command_lag": {"tau": TAU}},
    )["-"]
    assert alone == pytest.approx(closed_form(2.0), rel=0.05)
    assert beside == pytest.approx(closed_form(1.0), rel=0.05)  # half: the lag took 3/4
    assert all(e.get("command_lag", {}).get("tau") == TAU for e in ev.runs[-3:])


def _diagnosis(partner_limit: bool) -> SimpleNamespace:
    (lag,) = catalogue(["command_lag"])
    (fr,) = catalogue(["friction"])
    winner = SimpleNamespace(
        fit=SimpleNamespace(name="command_lag", candidates=[lag], ext={"command_lag": {"tau": TAU}})
    )
    ev = FakeEv()
    said: list[str] = []
    d = SimpleNamespace(
        winner=winner,
        ev=ev,
        noise=ev.scale,
        opts=Options(partner_limit=partner_limit),
        say=said.append,
        partner_limits=None,
    )
    x = np.array([TAU, -0.1])
    f = Fit(
        [lag, fr],
        x,
        np.array([0.2, -0.15]),
        np.array([0.4, -0.05]),
        np.zeros(2),
        1.0,
        1,
        {"command_lag": {"tau": TAU}, "friction": {"fraction": -0.1}},
        0.0,
        "train",
    )
    pair = Scored(f, 0.0, np.zeros(3), 0.2, 0.001, -5.0, -5.0, 10, significant=True)
    return SimpleNamespace(d=d, pair=pair)


def test_a_partner_below_its_limit_beside_the_winner_is_not_named() -> None:
    case = _diagnosis(partner_limit=True)
    limits = partner_limits(case.d, [case.pair])  # type: ignore[arg-type]
    assert limits is not None and set(limits) == {"friction"}  # the winner's own is not asked
    assert limits["friction"]["-"] == pytest.approx(closed_form(1.0), rel=0.05)
    assert case.d.partner_limits == limits  # reported in result.json
    # A friction of -0.1 (interval clear of off) is below that limit (about 0.26)
    second = first_confident(
        [case.pair],
        lambda s: None,
        lambda s: {"friction"},
        lambda m: None,
        limits,
    )
    assert second is None and "below its detection limit" in case.pair.test
    assert not case.pair.significant
    # The same pair with a friction of -0.5, above the limit, is named
    big = _diagnosis(partner_limit=True).pair
    big.fit.x[1], big.fit.ci_lo[1], big.fit.ci_hi[1] = -0.5, -0.6, -0.4
    assert first_confident([big], lambda s: None, lambda s: {"friction"}, lambda m: None, limits)


def test_off_it_measures_nothing() -> None:
    case = _diagnosis(partner_limit=False)
    assert partner_limits(case.d, [case.pair]) is None  # type: ignore[arg-type]
    assert case.d.ev.runs == [] and case.d.partner_limits is None


def test_the_few_drives_report_counts_what_the_rule_removed(tmp_path: Path) -> None:
    import json

    from _bench import load_bench

    bench = load_bench("few_drives")
    rows = [
        # a right winner and a wrong partner the rule refused
        {
            "case": "a",
            "kind": "single",
            "truth": {"command_lag": {"tau": 0.3}},
            "drives": 2,
            "named": ["command_lag"],
            "named_off": ["command_lag", "friction"],
            "acted": True,
            "partner_limits": {"friction": {"-": 0.69}},
            "diagnose_s": 40.0,
        },
        # a right partner it refused (harm)
        {
            "case": "b",
            "kind": "pair",
            "truth": {"slope": {"deg": 3}, "friction": {"fraction": -0.5}},
            "drives": 2,
            "named": ["slope"],
            "named_off": ["slope", "friction"],
            "acted": True,
            "partner_limits": {"friction": {"-": 0.6}},
            "diagnose_s": 50.0,
        },
        # a clean case naming something either way
        {
            "case": "c",
            "kind": "clean",
            "truth": "none",
            "drives": 2,
            "named": ["slope"],
            "named_off": ["slope"],
            "acted": False,
            "partner_limits": None,
            "diagnose_s": 30.0,
        },
    ]
    path = tmp_path / "rows.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    text = bench.report(path, tmp_path / "few.md")
    assert "| single | 1 | 1 / 1 | 0 / 1 | 0 / 0 |" in text
    assert "| pair | 1 | 1 / 2 | 0 / 0 | 0 / 0 |" in text
    assert "| clean | 1 | 0 / 0 | 1 / 1 | 0 / 0 |" in text
    assert "right names the rule removed (H1): 1 in 1 cases" in text
    assert "wrong names the rule removed: 1 in 1 cases" in text
    assert (tmp_path / "few.md").read_text() == text
