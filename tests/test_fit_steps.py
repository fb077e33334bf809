"""The multi-parameter fit's finite differences (rover_env.calibration.fit.fit)."""

from __future__ import annotations

import numpy as np

from rover_env.calibration.candidates import catalogue
from rover_env.calibration.fit import fit


class _FakeEvaluator:
    """An Evaluator stand-in whose replay is an analytic residual of the slope's tilt
    vector (two windows of three rows each), recording where it was evaluated."""

    def __init__(self, target: tuple[float, float]) -> None:
        self.target = np.array(target)
        self.points: list[np.ndarray] = []

    @staticmethod
    def _tilt(ext: dict) -> np.ndarray:
        d, h = ext["slope"]["deg"], np.radians(ext["slope"]["heading_deg"])
        return np.array([d * np.cos(h), d * np.sin(h)])

    def vector(self, ext: dict, which: str) -> np.ndarray:
        x = self._tilt(ext)
        self.points.append(x)
        e = x - self.target
        # Curved in the tilt, as a tilt's response is (sines of it): a forward difference
        # as wide as the value puts the iteration's fixed point off the minimum.
        return np.array([e[0], e[1], 0.3 * e[0] ** 2, 0.3 * e[1] ** 2, 0.2 * e[0] * e[1], 0.0])

    def run(self, ext: dict, which: str) -> list:
        class _W:
            resid = np.zeros((3, 1))
            pose_resid = np.zeros((0, 3))

        return [_W(), _W()]

    def log(self, msg: str) -> None:
        pass


def test_a_slope_is_differenced_over_a_tenth_of_its_value_and_converges() -> None:
    """Stop 38: ``least_squares``' ``diff_step`` is relative (``h = diff_step * max(1,
    |x|)``), and the fit passed its absolute steps: a tilt of 6.7 deg was differenced over
    4.4 deg and the search stopped short (own slope 7.19 deg fitted 6.57)."""
    (c,) = [c for c in catalogue(["slope"])]
    ev = _FakeEvaluator((-1.5, 7.0))
    f = fit(ev, [c], "train", x_start=np.array([-1.37, 6.66]), max_nfev=4, probe=False)  # type: ignore[arg-type]
    steps = [np.abs(p - q).max() for p, q in zip(ev.points[1:], ev.points[:-1], strict=False)]
    assert min(s for s in steps if s > 0) < 0.11 * 7.0
    np.testing.assert_allclose(f.x, [-1.5, 7.0], atol=0.01)
