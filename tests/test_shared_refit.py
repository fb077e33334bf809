"""A command lag and a delay, which move the wheels' response by about their sum, are judged
as a pair fitted together, both free (:mod:`rover_env.calibration.diagnosis.shared`).
Built on stand-in replays whose answer is known in closed form, as
tests/test_partner_limit.py."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from rover_env.calibration import residuals as rs
from rover_env.calibration.candidates import catalogue, shares_response
from rover_env.calibration.diagnosis.shared import shared_partners, shared_refits
from rover_env.calibration.diagnosis.state import Options, Scored
from rover_env.calibration.fit import Fit
from rover_env.calibration.replay import SIGNALS

N = 24  # windows per set
T = 10  # scored rows per window


@dataclass
class FakeEv:
    """Replays of a rover with a lag ``tau`` and a delay ``d``: wheel_1L's residual is the
    error in the sum (tau + d), wheel_2L's the error in the lag alone, ``weak`` times as
    strong (a step's shape, which tells a lag from a delay), wheel_3L a fixed per-window
    floor; wheel_1L also carries a mismatch the pair cannot explain, ``form`` in every
    row, so the signals' scales before and after the pair differ."""

    truth: tuple[float, float]
    weak: float = 0.5
    form: float = 0.0
    scale: dict = field(default_factory=lambda: dict.fromkeys(SIGNALS, 1.0))
    replays: int = 0
    seconds: float = 0.0

    def run(self, ext: dict, which: str, ref: str | None = None) -> list:
        self.replays += 1
        tau = ext.get("command_lag", {}).get("tau", 0.0)
        d = ext.get("command_delay", {}).get("delay", 0.0)
        floor = np.random.default_rng(7).uniform(0.01, 0.02, 2 * N)
        rows = {"train": floor[:N], "train_sub": floor[:N:2], "held": floor[N:]}[which]
        out = []
        for i, fl in enumerate(rows):
            resid = np.zeros((T, 11))
            ramp = np.linspace(0.5, 1.5, T) * (1 + 0.1 * (i % 3))
            resid[:, 0] = ramp * ((tau + d) - sum(self.truth)) + self.form
            resid[:, 1] = self.weak * ramp * (tau - self.truth[0])
            resid[:, 2] = fl
            resid[:, 3] = ramp * ((tau + d) - sum(self.truth))
            out.append(
                SimpleNamespace(
                    resid=resid,
                    pose_resid=np.zeros((1, 3)),
                    window=SimpleNamespace(log_index=0),
                    idx=np.arange(T),
                    pose_idx=np.arange(1),
                )
            )
        return out

    def vector(self, ext: dict, which: str) -> np.ndarray:
        return rs.residual_vector(self.run(ext, which), self.scale)

    def reference(self, ext: dict, which: str) -> str:
        return "train"

    def log(self, msg: str) -> None:
        pass


def _diagnosis(
    tau: float,
    delay: float,
    named: float,
    ev: FakeEv | None = None,
    floor: float = 1.0,
    **opts: Any,
) -> SimpleNamespace:
    """A diagnosis whose winner is a lag alone fitted at ``named`` on drives of ``tau`` and
    ``delay``."""
    (lag,) = catalogue(["command_lag"])
    ev = ev or FakeEv((tau, delay))
    ext = {"command_lag": {"tau": named}}
    z = np.zeros(1)
    f = Fit([lag], np.array([named]), z, z, z, 1.0, 1, ext, 0.0, "train")
    noise = dict.fromkeys(SIGNALS, floor)
    held = rs.window_losses(ev.run(ext, "held"), noise)
    winner = Scored(f, float(held.sum()), held, 0.9, 1e-4, -50.0, -50.0, N, significant=True)
    return SimpleNamespace(
        winner=winner,
        ev=ev,
        noise=noise,
        sets={"train": list(range(N)), "train_sub": list(range(0, N, 2)), "held": list(range(N))},
        opts=Options(**opts),
        prepared=[SimpleNamespace(regimes={r: np.ones(T, dtype=bool) for r in rs.REGIMES})],
        say=lambda msg: None,
    )


def test_a_lag_and_a_delay_share_a_response_and_nothing_else_does() -> None:
    assert shares_response("command_lag", "command_delay")
    assert shares_response("command_delay", "command_lag")
    assert not shares_response("command_lag", "torque_limit")
    pool = catalogue(["command_delay", "torque_limit", "slope"])
    d = _diagnosis(0.3, 0.1, 0.4)
    assert [c.name for c in shared_partners(d, pool)] == ["command_delay"]  # type: ignore[arg-type]
    d_off = _diagnosis(0.3, 0.1, 0.4, shared_refit=False)
    assert shared_partners(d_off, pool) == []  # type: ignore[arg-type]
    (tl,) = catalogue(["torque_limit"])
    d.winner.fit.candidates = [tl]
    assert shared_partners(d, pool) == []  # type: ignore[arg-type]


def test_fitted_together_a_lag_and_a_delay_land_on_both_and_are_judged_as_a_pair() -> None:
    # The lag alone took both shares (0.4 s for 0.3 + 0.1); beside it held there, the delay
    # would fit at "off". Both free, from 0.2 + 0.2, the pair lands on the truth.
    d = _diagnosis(0.3, 0.1, 0.4)
    (delay,) = catalogue(["command_delay"])
    (s,) = shared_refits(d, [delay])  # type: ignore[arg-type]
    assert [c.name for c in s.fit.candidates] == ["command_lag", "command_delay"]
    assert s.fit.x == pytest.approx([0.3, 0.1], abs=0.01)
    assert s.refit and s.significant and s.test == "windows"
    assert s.gain > 0.5  # against the lag alone, on the held-out windows


def test_a_lag_alone_gains_no_delay_from_the_refit() -> None:
    d = _diagnosis(0.3, 0.0, 0.3, screen=False)
    (delay,) = catalogue(["command_delay"])
    (s,) = shared_refits(d, [delay])  # type: ignore[arg-type]
    assert s.fit.x == pytest.approx([0.3, 0.0], abs=0.01)
    assert not s.significant and s.test == ""


def test_the_screen_fits_in_full_only_a_promising_pair() -> None:
    """A lag and a delay both there: the screen on the subset is promising and the pair is
    fitted as without a screen (the same values); a lag alone: the screen is the answer,
    never named, for fewer replays than the full refit."""
    (delay,) = catalogue(["command_delay"])
    both = _diagnosis(0.3, 0.1, 0.4)
    (s,) = shared_refits(both, [delay])  # type: ignore[arg-type]
    (full,) = shared_refits(_diagnosis(0.3, 0.1, 0.4, screen=False), [delay])  # type: ignore[arg-type]
    assert not s.screened and s.significant
    assert np.array_equal(s.fit.x, full.fit.x)
    alone, alone_full = _diagnosis(0.3, 0.0, 0.3), _diagnosis(0.3, 0.0, 0.3, screen=False)
    (s1,) = shared_refits(alone, [delay])  # type: ignore[arg-type]
    shared_refits(alone_full, [delay])  # type: ignore[arg-type]
    assert s1.screened and s1.refit and not s1.significant
    assert s1.fit.which == "train_sub"
    assert alone.ev.replays < alone_full.ev.replays
    (s2,) = shared_refits(_diagnosis(0.3, 0.0, 0.3, screen_shared=False), [delay])  # type: ignore[arg-type]
    assert not s2.screened and s2.fit.which == "train"


def test_the_pair_is_fitted_again_with_the_signals_weighed_by_what_it_leaves() -> None:
    # wheel_1L carries a mismatch no lag or delay explains, wheel_3R reads the sum exactly.
    # Weighed by the residuals before any effect, the two weigh alike and the sum lands
    # between them; weighed again by what the pair leaves, wheel_3R (left at its floor)
    # outweighs wheel_1L (left at the mismatch) and the sum lands where it says.
    (delay,) = catalogue(["command_delay"])

    def refit(reweigh: int) -> Scored:
        ev = FakeEv((0.3, 0.1), form=0.02)
        d = _diagnosis(0.3, 0.1, 0.4, ev=ev, floor=1e-3, reweigh=reweigh)
        (s,) = shared_refits(d, [delay])  # type: ignore[arg-type]
        return s

    once, again = refit(0), refit(2)
    assert once.fit_scale is None
    assert again.fit_scale is not None and again.fit_scale["wheel_1L"] > 0.01  # the mismatch
    assert again.fit_scale["wheel_3R"] < 0.005
    assert once.fit.x[1] < 0.095  # pulled off by the mismatch
    assert again.fit.x[0] == pytest.approx(0.3, abs=0.003)
    assert abs(again.fit.x[1] - 0.1) < 0.6 * abs(once.fit.x[1] - 0.1)  # two passes of IRLS
