"""A named soil's k_phi read from the rover's motion (rover_env.calibration.diagnosis.motion)."""

from __future__ import annotations

import numpy as np
import pytest

from rover_env.calibration.candidates import INV_K_PHI_MAX, SOIL_FORMS, catalogue
from rover_env.calibration.diagnosis.motion import from_motion
from rover_env.calibration.fit import Fit

REGOLITH = SOIL_FORMS[4][0]  # SOIL.md's regolith at lambda 0.3, memoryless


def _fit(name: str = "loose_soil", **kw: object) -> Fit:
    c = catalogue([name])[0]
    if name == "loose_soil":
        c = c.with_form(REGOLITH)
    x = np.array([0.3])
    args: dict[str, object] = dict(
        candidates=[c],
        x=x,
        ci_lo=np.array([0.25]),
        ci_hi=np.array([0.35]),
        se=np.array([0.03]),
        cost=1.0,
        nfev=10,
        ext=c.to_ext(x),
        seconds=0.0,
        which="train",
        groups={"free wheels": 0.2, "joints": 0.3, "pose": 1.2},
        between=0.4,
    )
    args.update(kw)
    return Fit(**args)  # type: ignore[arg-type]


def test_soil_moves_to_the_pose_groups_minimum() -> None:
    f = _fit()
    assert from_motion(f) == pytest.approx(0.3)
    assert f.x[0] == pytest.approx(1.2)
    soil = f.ext["loose_soil"]
    assert soil["k_phi"] == pytest.approx(1e6 / 1.2)
    # the soil's form stays (SOIL.md's constants at its lambda, memoryless)
    assert soil["preset"] == 1.0 and soil["memory"] == 0.0 and soil["lam"] == 0.3
    # the interval is stretched to hold the new value, its other end kept
    assert f.ci_lo[0] == pytest.approx(0.25) and f.ci_hi[0] == pytest.approx(1.2)


def test_groups_that_agree_move_it_too() -> None:
    f = _fit(between=0.0, groups={"joints": 0.3, "pose": 0.32})
    assert from_motion(f) is not None and f.x[0] == pytest.approx(0.32)


def test_a_softer_pose_stretches_the_lower_end() -> None:
    f = _fit(groups={"joints": 0.3, "pose": 0.1})
    assert from_motion(f) is not None
    assert f.ci_lo[0] == pytest.approx(0.1) and f.ci_hi[0] == pytest.approx(0.35)


@pytest.mark.parametrize(
    "kw",
    [
        {"groups": {"joints": 0.3}},  # no pose minimum of its own
        {"groups": None},
        {"groups": {"pose": 0.0}},  # hard ground is not a soil's value
        {"groups": {"pose": INV_K_PHI_MAX * 1.5}},  # beyond the softest soil
        {"groups": {"pose": float("nan")}},
        {"sided": ("upper",)},  # a fit at a bound keeps its one-sided interval
    ],
)
def test_left_alone(kw: dict[str, object]) -> None:
    f = _fit(**kw)
    ext = dict(f.ext)
    assert from_motion(f) is None
    assert f.x[0] == pytest.approx(0.3) and f.ext == ext
    assert (f.ci_lo[0], f.ci_hi[0]) == pytest.approx((0.25, 0.35))


def test_other_effects_are_left_alone() -> None:
    f = _fit("rolling_resistance", x=np.array([0.02]), ext={"rolling_resistance": {"c_rr": 0.02}})
    assert from_motion(f) is None
    assert f.x[0] == pytest.approx(0.02)


def test_a_pair_is_left_alone() -> None:
    soil = _fit()
    other = catalogue(["slope"])[0]
    f = _fit(candidates=[soil.candidates[0], other], x=np.array([0.3, 1.0, 0.0]))
    assert from_motion(f) is None
