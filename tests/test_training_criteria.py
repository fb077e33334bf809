"""The training BIC diagnose names by (stop 67): windows as observations, each signal in
units of its replay floor, the held-out test's units. Built on stand-in replays whose
losses are known in closed form."""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np

from rover_env.calibration.diagnosis.judge import score, training_criteria
from rover_env.calibration.replay import SIGNALS

N = 32  # training windows
T = 20  # scored rows per window
FREE = (4, 5)  # wheel_3L, wheel_3R
FLOOR = dict.fromkeys(SIGNALS, 0.002)


def replays(free: float, rest: float, seed: int = 0) -> list[Any]:
    """Windows whose free wheels are off by ``free`` and every other signal by ``rest``
    (times a draw of unit spread), pose at its floor."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(N):
        resid = rest * rng.standard_normal((T, 11))
        resid[:, FREE] = free * (1.0 + 0.1 * rng.standard_normal((T, 2)))
        pose = 0.002 * rng.standard_normal((3, 3))
        out.append(SimpleNamespace(resid=resid, pose_resid=pose))
    return out


def test_an_effect_seen_in_two_signals_pays_its_price_in_floor_units() -> None:
    # The model leaves the free wheels 50 x their floor (a slope it lacks) and the other
    # signals 5 x (its form); the slope takes the free wheels to their floor.
    before, after = replays(0.1, 0.01), replays(0.002, 0.01)
    _, bic_floor = training_criteria(before, after, FLOOR, N, 2)
    # Per window about 2 T 50^2 + 9 T 5^2 before, 2 T + 9 T 5^2 after.
    want = N * math.log((2 * T + 9 * T * 25) / (2 * T * 2500 + 9 * T * 25)) + 2 * math.log(N)
    assert abs(bic_floor - want) < 0.05 * abs(want)
    # Scaled by each signal's RMS before the effect, every signal weighs about one in each
    # window: fixing 2 of 14 gains at most their share of each window, short of 2 ln 32.
    scale = {s: _rms(before, s) for s in SIGNALS}
    _, bic_rms = training_criteria(before, after, scale, N, 2)
    assert bic_rms > 0


def test_a_few_per_cent_off_the_largest_signal_does_not_pay() -> None:
    # A candidate that takes 3 % off the free wheels' residual in every window (what a
    # wrong effect can absorb of a form the model lacks) does not lower the BIC.
    before, after = replays(0.1, 0.01), replays(0.097, 0.01)
    _, bic = training_criteria(before, after, FLOOR, N, 1)
    assert bic > 0


def test_the_same_replays_score_nothing_but_the_price() -> None:
    before = replays(0.1, 0.01)
    aic, bic = training_criteria(before, before, FLOOR, N, 2)
    assert (aic, bic) == (4.0, 2 * math.log(N))


def _rms(results: list[Any], signal: str) -> float:
    j = SIGNALS.index(signal)
    if j < 11:
        col = np.concatenate([r.resid[:, j] for r in results])
    else:
        col = np.concatenate([r.pose_resid[:, j - 11] for r in results])
    return max(float(np.sqrt(np.mean(col**2))), FLOOR[signal])


def test_score_judges_the_training_windows_in_floor_units() -> None:
    # diagnose's score: the stage's fit scale (each signal's RMS before any effect) is
    # for the least squares; the BIC that names is in floor units.
    runs = {"{}": replays(0.1, 0.01), '{"slope": 1}': replays(0.002, 0.01, seed=1)}

    class Ev:
        def run(self, ext: dict[str, Any], which: str, ref: str | None = None) -> list[Any]:
            return runs["{}" if not ext else '{"slope": 1}']

        def reference(self, ext: dict[str, Any], which: str) -> str:
            return "train"

    d = SimpleNamespace(
        ev=Ev(),
        noise=FLOOR,
        scale={s: _rms(runs["{}"], s) for s in SIGNALS},
        sets={"train": list(range(N))},
    )
    f = SimpleNamespace(ext={"slope": 1}, which="train", k=2)
    held0 = np.array([1e9] * N)  # the held-out losses are not what is tested here
    s = score(d, f, held0, {})  # type: ignore[arg-type]
    assert s.d_bic < -50
