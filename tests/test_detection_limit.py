"""The detection limit diagnose reports beside the noise threshold (stop 59): the magnitude
at which an effect, were it in the logs, would pay its training BIC price against the
residual the logs leave. Built on stand-in replays whose answer is known in closed form."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis.fit_stage import crossing, detection_limit
from rover_env.calibration.diagnosis.judge import below_detection_limit, limit_at
from rover_env.calibration.diagnosis.select import first_confident
from rover_env.calibration.diagnosis.state import Scored
from rover_env.calibration.fit import Fit
from rover_env.calibration.replay import SIGNALS

N = 64  # windows
T = 10  # scored rows per window


class FakeEv:
    """Replays whose residual is ``base`` on wheel_1L everywhere plus, for a torque cut of
    fraction f, f * ``gain`` on wheel_2L in the windows ``where``."""

    def __init__(self, base: float, gain: float, where: range) -> None:
        self.scale = dict.fromkeys(SIGNALS, 1.0)
        self.base, self.gain, self.where = base, gain, where

    def run(self, ext: dict, which: str) -> list:
        f = ext.get("torque_limit", {}).get("fraction", 0.0)
        out = []
        for w in range(N):
            resid = np.zeros((T, 11))
            resid[:, 0] = self.base
            if w in self.where:
                resid[:, 2] = f * self.gain
            out.append(SimpleNamespace(resid=resid, pose_resid=np.zeros((1, 3))))
        return out


def limit(base: float, gain: float, where: range) -> float:
    (c,) = catalogue(["torque_limit"])
    ev = FakeEv(base, gain, where)
    return detection_limit(ev, c, "train", ev.scale)["-"]  # type: ignore[arg-type]


def test_the_limit_is_where_the_effect_pays_its_price_against_the_residual_left() -> None:
    # Every window: E = T (g m)^2 against R = T base^2, so N log(1 + (g m / base)^2) = ln N.
    want = math.sqrt(math.expm1(math.log(N) / N))  # base 1, gain 1
    assert limit(1.0, 1.0, range(N)) == pytest.approx(want, rel=1e-6)
    # Four times the residual (a model whose form is further off): twice the limit.
    assert limit(2.0, 1.0, range(N)) == pytest.approx(2 * limit(1.0, 1.0, range(N)), rel=1e-6)
    # Seen in 4 windows of 64 (a limit reached in a few accelerations): far less visible.
    assert limit(1.0, 1.0, range(4)) > 3 * limit(1.0, 1.0, range(N))


def test_no_limit_for_an_effect_that_moves_nothing_or_a_switch() -> None:
    (c,) = catalogue(["torque_limit"])
    ev = FakeEv(1.0, 0.0, range(N))
    assert detection_limit(ev, c, "train", ev.scale) == {}  # type: ignore[arg-type]
    (sw,) = catalogue(["combined_slip"])
    ev = FakeEv(1.0, 1.0, range(N))
    assert detection_limit(ev, sw, "train", ev.scale) == {}  # type: ignore[arg-type]


def test_the_limit_is_in_the_units_it_is_given() -> None:
    # The residual left and the effect both on signals of floor 1: a scale of 2 on every
    # signal divides both alike (no change); on the effect's signal alone, doubles the limit.
    (c,) = catalogue(["torque_limit"])
    ev = FakeEv(1.0, 1.0, range(N))
    one = detection_limit(ev, c, "train", ev.scale)["-"]  # type: ignore[arg-type]
    both = detection_limit(ev, c, "train", dict.fromkeys(SIGNALS, 2.0))["-"]  # type: ignore[arg-type]
    assert both == pytest.approx(one, rel=1e-6)
    wheel = {**ev.scale, "wheel_2L": 2.0}
    assert detection_limit(ev, c, "train", wheel)["-"] == pytest.approx(2 * one, rel=0.05)  # type: ignore[arg-type]


def test_the_noise_threshold_lies_where_the_response_crosses_one_floor() -> None:
    # A response linear in the magnitude: m / S at any rung, the bracket agrees.
    linear = [(m, 40.0 * m) for m in (0.01, 0.03, 0.089, 0.267, 0.8)]
    assert crossing(linear) == pytest.approx(0.025)
    # A torque limit the drives reach only past 0.267 (spent case 51221's rungs): the rung
    # nearest one floor (0.8, S 14.2) would put it at 0.056, below two rungs that moved
    # nothing; it lies between them, log-log interpolated.
    reached_late = [(0.01, 0.0), (0.03, 0.0), (0.089, 0.01), (0.267, 0.03), (0.8, 14.23)]
    t = crossing(reached_late)
    assert 0.267 < t < 0.8
    u = -math.log(0.03) / (math.log(14.23) - math.log(0.03))
    assert t == pytest.approx(0.267 * (0.8 / 0.267) ** u)
    # A rung that moved nothing at all bounds it: m / S (0.05) falls below it, so linearly
    # between the two.
    assert crossing([(0.1, 0.0), (0.3, 6.0)]) == pytest.approx(0.1 + 0.2 / 6.0)
    # An estimate inside its bracket stands (a response steeper than linear near the top).
    assert crossing([(0.1, 0.5), (0.3, 1.2)]) == pytest.approx(0.25)
    # Every rung below one floor: extrapolated from the one nearest it; every rung above:
    # from the smallest.
    assert crossing([(0.1, 0.01), (0.3, 0.5)]) == pytest.approx(0.6)
    assert crossing([(0.1, 4.0), (0.3, 12.0)]) == pytest.approx(0.025)


class DeadZoneEv(FakeEv):
    """A torque cut that acts only past 0.3 (the drives reach the motors' limit there)."""

    def run(self, ext: dict, which: str) -> list:
        f = ext.get("torque_limit", {}).get("fraction", 0.0)
        past = math.copysign(max(0.0, abs(f) - 0.3), f)
        return super().run({"torque_limit": {"fraction": past}}, which)


def test_a_limit_acting_only_past_a_point_is_not_placed_below_rungs_that_moved_nothing() -> None:
    (c,) = catalogue(["torque_limit"])
    ev = DeadZoneEv(1.0, 10.0, range(N))
    rungs = sorted(abs(p[0]) for p in c.ladder or () if p[0] < 0)
    last_quiet = max(m for m in rungs if m <= 0.3)  # a rung the drives never felt
    # The rung nearest the price alone (E ~ m^2 from 0.8) would put it at 0.041.
    assert last_quiet < detection_limit(ev, c, "train", ev.scale)["-"] < 0.8  # type: ignore[arg-type]


class SlopeEv(FakeEv):
    """A tilt whose x component moves wheel_2L by ``gx`` per degree and whose y component
    moves wheel_2R by ``gy``, against ``base`` on wheel_1L everywhere."""

    def __init__(self, gx: float, gy: float) -> None:
        super().__init__(1.0, 0.0, range(0))
        self.gx, self.gy = gx, gy

    def run(self, ext: dict, which: str) -> list:
        s = ext.get("slope", {"deg": 0.0, "heading_deg": 0.0})
        h = math.radians(s["heading_deg"])
        tx, ty = s["deg"] * math.cos(h), s["deg"] * math.sin(h)
        out = super().run({}, which)
        for r in out:
            r.resid[:, 2] = self.gx * tx
            r.resid[:, 3] = self.gy * ty
        return out


def test_a_slopes_limit_is_measured_along_each_axis_and_joined_as_an_ellipse() -> None:
    (c,) = catalogue(["slope"])
    ev = SlopeEv(2.0, 0.5)
    lim = detection_limit(ev, c, "train", ev.scale)  # type: ignore[arg-type]
    want = math.sqrt(math.expm1(2 * math.log(N) / N))  # price: two parameters
    for axis, g in (("x+", 2.0), ("x-", 2.0), ("y+", 0.5), ("y-", 0.5)):
        assert lim[axis] == pytest.approx(want / g, rel=1e-6), axis
    assert lim["x+"] < lim["deg"] < lim["y+"]  # the median over directions, as reported
    # Along the diagonal the change is exactly a quadratic form: the ellipse is exact.
    diag = np.array([1.0, 1.0])
    exact = want * math.sqrt(2.0 / (2.0**2 + 0.5**2))
    assert limit_at(c, diag, lim) == pytest.approx(exact, rel=1e-6)
    assert limit_at(c, np.array([-3.0, 0.0]), lim) == pytest.approx(want / 2.0, rel=1e-6)
    # Without the axes (a report written before them): the median over directions.
    assert limit_at(c, diag, {"deg": 1.5}) == 1.5


def _named(name: str, x: list[float]) -> Scored:
    (c,) = catalogue([name])
    xa = np.array(x)
    f = Fit(
        [c], xa, xa - 1e-3, xa + 1e-3, np.full(len(x), 5e-4), 0.0, 0, c.to_ext(xa), 0.0, "train"
    )
    return Scored(f, 0.0, np.zeros(3), 0.2, 0.001, -5.0, -5.0, 10, significant=True)


def test_an_effect_below_its_detection_limit_is_not_named() -> None:
    # Stop 73's pattern: a clean case's friction of -0.244 where the logs can show only
    # -0.261 or stronger; a delay well above its limit is named.
    limits = {"friction": {"-": 0.261, "+": 0.4}, "command_delay": {"+": 0.03}}
    friction, delay = _named("friction", [-0.244]), _named("command_delay", [0.09])
    assert below_detection_limit(friction.fit, limits) != []
    assert below_detection_limit(delay.fit, limits) == []
    assert below_detection_limit(friction.fit, limits, {"command_delay"}) == []  # not judged
    assert below_detection_limit(friction.fit, {}) == []  # no limit measured: no verdict
    say: list[str] = []
    chosen = first_confident([friction, delay], lambda s: None, lambda s: None, say.append, limits)
    assert chosen is delay
    assert not friction.significant and "below its detection limit 0.261" in friction.test
    # The same without limits (--no-name-above-limit): the friction is named.
    friction.significant = True
    assert (
        first_confident([friction, delay], lambda s: None, lambda s: None, say.append) is friction
    )


def test_loose_soil_has_no_one_detection_limit() -> None:
    # Several forms, the ladder replayed in one: the rule does not judge it.
    soil = _named("loose_soil", [0.1])
    assert below_detection_limit(soil.fit, {"loose_soil": {"+": 1.0}}) == []
    # As fitted: the candidate in the form the fit chose (block 51500 refused two soils
    # this way before the exemption read it).
    (c,) = catalogue(["loose_soil"])
    soil.fit.candidates = [c.with_form(c.forms[1][0])]
    assert below_detection_limit(soil.fit, {"loose_soil": {"+": 1.0}}) == []
