"""Dead reckoning's driven-wheel check beside the leading unnamed fit
(:func:`rover_env.calibration.diagnosis.odometry.beside_lead`): a rolling resistance the
windows fitted but did not name makes the driven wheels slip while the free wheels roll; the
radius is then read against twins that slip so, and only then."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis import judge, odometry
from rover_env.calibration.diagnosis.state import ODOMETRY_BAND, Scored
from rover_env.calibration.fit import Fit, to_ext

LOGS = {"both": -0.030, "3L": -0.031, "3R": -0.029, "driven": -0.077}
"""Study 73100's pair 73100 (a radius of -4.4 % beside a rolling resistance of 0.072):
the free wheels travel 3 % less per turn than the nominal twins, the driven wheels 8 %."""
NOMINAL = {"both": 0.001, "3L": 0.0, "3R": 0.002, "driven": 0.004}
DRAGGED = {"both": 0.009, "3L": 0.008, "3R": 0.010, "driven": -0.045}
"""Twins under the fitted drag: the free wheels dragged (+0.9 %), the driven wheels slip."""


def _scored(name: str, value: float, d_bic: float, gain: float, screened: bool = False) -> Scored:
    c = catalogue([name])[0]
    x = np.array([value])
    fit = Fit(
        candidates=[c],
        x=x,
        ci_lo=x * 0.8,
        ci_hi=x * 1.2,
        se=x * 0.1,
        cost=1.0,
        nfev=1,
        ext=to_ext([c], x),
        seconds=0.0,
        which="train",
    )
    nan = float("nan")
    return Scored(fit, nan, np.zeros(1), gain, 0.001, nan, d_bic, 1, screened=screened)


def _diagnosis(ranked: list[Scored], said: list[str]) -> Any:
    return SimpleNamespace(
        chosen=[],
        winner=None,
        partners=[],
        ranked=ranked,
        prepared=[],
        ev=SimpleNamespace(config=lambda ext: ext),  # the twins below read the extensions
        say=said.append,
    )


@pytest.fixture
def twins(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Twins that slip only under a rolling resistance; each call's model recorded."""
    calls: list[Any] = []

    def fake(cfg: Any, prepared: Any, r_e: float, form: str) -> dict[str, float]:
        calls.append(cfg)
        return DRAGGED if "rolling_resistance" in cfg else NOMINAL

    monkeypatch.setattr(odometry, "twin_scales", fake)
    return calls


def _read(d: Any, logs: dict[str, float] = LOGS) -> tuple[Any, dict[str, Any]]:
    rec: dict[str, Any] = {"logs": logs}
    named = ({}, NOMINAL, {k: logs[k] - NOMINAL[k] for k in logs})
    got = odometry.beside_lead(d, rec, ODOMETRY_BAND, named, set(), 0.076, odometry.INTERVALS)
    return got, rec


def test_the_named_model_refuses_the_radius_as_a_drag() -> None:
    diff = {k: LOGS[k] - NOMINAL[k] for k in LOGS}
    why = odometry.refusal(diff, ODOMETRY_BAND, set())
    assert why is not None and why.startswith("the driven wheels read")
    assert odometry.refusal(diff, ODOMETRY_BAND, set(), ask_driven=False) is None


def test_an_unnamed_drag_s_twins_read_the_radius(twins: list[Any]) -> None:
    said: list[str] = []
    rr = _scored("rolling_resistance", 0.096, d_bic=-20.0, gain=0.48)
    friction = _scored("friction", -0.1, d_bic=-5.0, gain=0.30)
    (ext, on_twins, diff), rec = _read(_diagnosis([friction, rr], said), LOGS)
    assert "rolling_resistance" in ext and on_twins is DRAGGED
    assert diff["both"] == pytest.approx(-0.039) and diff["driven"] == pytest.approx(-0.032)
    assert odometry.refusal(diff, ODOMETRY_BAND, set()) is None
    lead = rec["slip_lead"]
    assert lead["effect"] == "rolling_resistance" and lead["read_beside"]
    assert lead["named_difference"]["driven"] == pytest.approx(-0.081)
    assert "read beside it" in said[0]


def test_a_lead_that_does_not_close_the_slip_leaves_the_refusal(twins: list[Any]) -> None:
    logs = dict(LOGS, driven=-0.20)  # far more slip than the fitted drag makes
    (ext, on_twins, _), rec = _read(
        _diagnosis([_scored("rolling_resistance", 0.09, -20, 0.4)], []), logs
    )
    assert ext == {} and on_twins is NOMINAL
    assert not rec["slip_lead"]["read_beside"]
    assert rec["slip_lead"]["why_not"].startswith("the driven wheels read")


@pytest.mark.parametrize(
    "ranked",
    [
        [],
        [_scored("rolling_resistance", 0.09, d_bic=+3.0, gain=0.05)],  # neither pays nor betters
        [_scored("rolling_resistance", 0.09, d_bic=-20.0, gain=0.5, screened=True)],
        [_scored("rolling_radius", -0.04, d_bic=-20.0, gain=0.5)],  # what is being read
    ],
)
def test_no_lead_no_other_twins(twins: list[Any], ranked: list[Scored]) -> None:
    (ext, on_twins, _), rec = _read(_diagnosis(ranked, []))
    assert ext == {} and on_twins is NOMINAL and "slip_lead" not in rec and not twins


def test_agreeing_wheels_ask_no_lead(twins: list[Any]) -> None:
    logs = dict(LOGS, driven=-0.028)  # a radius alone: the driven wheels read it too
    d = _diagnosis([_scored("rolling_resistance", 0.09, -20.0, 0.4)], [])
    (ext, on_twins, _), rec = _read(d, logs)
    assert ext == {} and on_twins is NOMINAL and "slip_lead" not in rec and not twins


def test_a_read_radius_is_judged_beside_what_it_was_read_against(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The windows replay the radius with the named effects (and a lead) it was read beside,
    while the configuration gets the radius alone."""
    seen: list[Any] = []

    def fake_score(d: Any, f: Fit, ref_held: Any, ref_ext: Any, k: int | None = None) -> Scored:
        seen.append((f.ext, ref_ext))
        return _scored("rolling_radius", -0.05, d_bic=-3.0, gain=-0.1)

    monkeypatch.setattr(judge, "score", fake_score)
    radius = _scored("rolling_radius", -0.05, d_bic=0.0, gain=0.0).fit
    beside = {"rolling_resistance": {"c_rr": 0.096}}
    d = SimpleNamespace(ev=SimpleNamespace(run=lambda ext, which: []), noise={})
    s, _ = judge.scored_beside(d, radius, beside)
    ((ext, ref),) = seen
    assert ext == {**beside, **radius.ext} and ref == beside
    assert s.fit is radius and s.fit.ext == {"rolling_radius": {"fraction": -0.05}}
