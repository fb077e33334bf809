"""A named soil's k_phi read from straight driving (rover_env.calibration.diagnosis.straight)."""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from rover_env.calibration.candidates import SOIL_FORMS, catalogue
from rover_env.calibration.diagnosis import straight as st
from rover_env.calibration.diagnosis.state import STRAIGHT
from rover_env.calibration.fit import Fit
from rover_env.calibration.replay import SIGNALS, Window, WindowResult, straight_windows

REGOLITH = SOIL_FORMS[4][0]


def _soil() -> Any:
    return catalogue(["loose_soil"])[0].with_form(REGOLITH)


def _fit(c: Any = None, x: float = 0.3) -> Fit:
    c = c or _soil()
    xv = np.array([x])
    return Fit(
        candidates=[c],
        x=xv,
        ci_lo=xv * 0.8,
        ci_hi=xv * 1.2,
        se=xv * 0.1,
        cost=1.0,
        nfev=10,
        ext=c.to_ext(xv),
        seconds=0.0,
        which="train",
    )


class FakeEv:
    """An evaluator whose joint residual on every window is ``log(u / u0)`` (its loss a
    parabola in log u with its minimum at ``u0``), its pose residual ``log(u / u_pose)``
    (``u_pose`` None: ``u0``); the wheels' residuals pull elsewhere (toward ``u_other``),
    as the yaw joints do in a turn."""

    def __init__(
        self,
        u0: float,
        u_other: float = 5.0,
        windows: int = 6,
        off: float = 3.0,
        u_pose: float | None = None,
    ):
        self.u0, self.u_other, self.off = u0, u_other, off
        self.u_pose = u0 if u_pose is None else u_pose
        self.sets = {STRAIGHT: [Window(0, 0, 10)] * windows}
        self.scale = {s: 1.0 for s in SIGNALS}
        self.calls: list[tuple[str, str | None]] = []

    def run(self, ext: dict[str, Any], which: str, ref: str | None = None) -> list[WindowResult]:
        self.calls.append((which, ref))
        k = ext["loose_soil"]["k_phi"]
        u = 1e6 / k if k > 0 else 0.0

        def r(at: float) -> float:
            return self.off if u <= 0 else math.log(u / at)

        out = []
        for w in self.sets[which]:
            n = 5
            resid = np.full((n, 11), r(self.u_other))
            resid[:, 6:] = r(self.u0)  # theta_1 .. theta_5
            out.append(
                WindowResult(
                    window=w,
                    idx=np.arange(n),
                    resid=resid,
                    sim=np.zeros((n, 11)),
                    pose_idx=np.arange(n),
                    pose_resid=np.full((n, 3), r(self.u_pose)),
                    pose_sim=np.zeros((n, 3)),
                )
            )
        return out


def _min(ev: FakeEv, group: str = "joints", **kw: Any) -> float | None:
    return st.group_minima(ev, _soil(), kw.pop("fixed", {}), (group,), **kw)[group]  # type: ignore[arg-type]


@pytest.mark.parametrize("u0", [0.05, 0.2, 0.9, 2.5, 7.0])
def test_group_minima_find_each_groups_own_minimum(u0: float) -> None:
    ev = FakeEv(u0, u_pose=min(3 * u0, 9.0))
    soil = _soil()
    got = st.group_minima(ev, soil, soil.to_ext(np.array([1.0])))  # type: ignore[arg-type]
    assert set(got) == {"joints", "pose"}
    assert got["joints"] == pytest.approx(u0, rel=0.05)
    assert got["pose"] == pytest.approx(min(3 * u0, 9.0), rel=0.05)
    # replayed on the straight windows only, profiled over their own windows
    assert {c for c in ev.calls} == {(STRAIGHT, STRAIGHT)}


def test_a_minimum_beyond_the_softest_soil_stops_at_the_range() -> None:
    assert _min(FakeEv(40.0)) == pytest.approx(_soil().hi[0])


def test_a_minimum_at_the_softest_rung_is_no_reading_where_ends_are_refused() -> None:
    """``end=False`` (``--soft-end-unread``): a best rung at the range's soft end reads nothing
    (three spent soil singles read at 0.05-0.15 x the truth there); inside, as before."""
    assert _min(FakeEv(40.0), end=False) is None
    assert _min(FakeEv(8.0), end=False) is None
    assert _min(FakeEv(2.5), end=False) == pytest.approx(2.5, rel=0.05)
    f = _fit(x=0.3)
    read = st.from_straight(FakeEv(40.0), f, end=False)  # type: ignore[arg-type]
    assert read is not None and read.replaced is None and read.reads["joints"] is None
    assert f.x[0] == 0.3


def test_hard_ground_that_fits_the_group_as_well_reads_nothing() -> None:
    assert _min(FakeEv(0.9, off=0.0)) is None
    assert _min(FakeEv(0.9, off=0.0), "pose") is None


@pytest.mark.parametrize("group", ["joints", "pose"])
def test_from_straight_moves_a_named_soil_to_its_groups_minimum(group: str) -> None:
    """The joints by default (``Options.soil_from_joints``), the pose where asked; both
    groups' readings are returned either way, and the interval stretched to hold the new
    value."""
    f = _fit(x=0.3)
    read = st.from_straight(FakeEv(2.0, u_pose=0.9), f, group=group)  # type: ignore[arg-type]
    assert read is not None and read.replaced == pytest.approx(0.3) and read.group == group
    assert read.reads["joints"] == pytest.approx(2.0, rel=0.05)
    assert read.reads["pose"] == pytest.approx(0.9, rel=0.05)
    want = {"joints": 2.0, "pose": 0.9}[group]
    assert f.x[0] == pytest.approx(want, rel=0.05)
    assert f.ext["loose_soil"]["k_phi"] == pytest.approx(1e6 / f.x[0])
    assert f.ext["loose_soil"]["preset"] == 1.0  # the soil's form stays
    assert f.ci_lo[0] == pytest.approx(0.24) and f.ci_hi[0] == pytest.approx(f.x[0])


@pytest.mark.parametrize("case", ["few windows", "other effect", "one-sided"])
def test_from_straight_leaves_alone(case: str) -> None:
    f = _fit()
    ev = FakeEv(2.0, windows=st.MIN_WINDOWS - 1 if case == "few windows" else 6)
    if case == "other effect":
        rr = catalogue(["rolling_resistance"])[0]
        f = _fit(rr, 0.02)
    if case == "one-sided":
        f.sided = ("upper",)
    x = float(f.x[0])
    assert st.from_straight(ev, f) is None  # type: ignore[arg-type]
    assert f.x[0] == x and ev.calls == []


def test_a_soil_the_joints_do_not_read_keeps_its_fit_and_records_the_reads() -> None:
    """Hard ground fits the joints as well: the fit over every signal stands, and
    ``read_from`` still records each group's reading (the pose's here) with no rule."""
    from rover_env.calibration.diagnosis import select as sel

    f = _fit(x=0.3)
    ev = FakeEv(2.0, u_pose=0.9)
    ev.off = 0.0  # "off" fits both groups perfectly ...
    d = SimpleNamespace(
        opts=SimpleNamespace(
            soil_from_straight=True,
            soil_from_joints=True,
            soil_from_motion=False,
            soft_end_unread=False,
        ),
        ev=ev,
    )
    s = SimpleNamespace(fit=f, fit_scale=None, read_from=None)
    sel.read_soil(d, s)  # type: ignore[arg-type]
    assert f.x[0] == 0.3
    assert s.read_from == {"rule": None, "group": "joints", "reads": {"joints": None, "pose": None}}
    ev.off, ev.u0 = 3.0, 1e-6  # ... or the joints' minimum lies off the range's stiff end
    sel.read_soil(d, s)  # type: ignore[arg-type]
    assert f.x[0] == 0.3 and s.read_from["rule"] is None
    assert s.read_from["reads"]["pose"] == pytest.approx(1e6 / 0.9, rel=0.05)


def test_straight_windows_drop_every_window_with_a_turning_sample() -> None:
    n = 30
    left, right = np.zeros(n, bool), np.zeros(n, bool)
    left[12] = True  # one sample of a left turn
    right[25] = True
    log = SimpleNamespace(regimes={"left_turn": left, "right_turn": right})
    ws = [Window(0, 0, 9), Window(0, 10, 19), Window(0, 20, 29), Window(0, 13, 24)]
    assert straight_windows([log], ws) == [ws[0], ws[3]]  # type: ignore[list-item]


@pytest.mark.parametrize("rule", ["straight", "straight-pose", "motion", None])
def test_diagnose_reads_a_named_soil_only_where_asked(rule: str | None) -> None:
    """``finish_chosen`` reads a named soil from straight driving
    (``Options.soil_from_straight``; the joints' minimum by default, the pose's with
    ``soil_from_joints`` off) or from the pose over every window
    (``Options.soil_from_motion``), says so and records it; with neither the fit over every
    signal stands."""
    from rover_env.calibration.diagnosis import select as sel
    from rover_env.calibration.diagnosis.state import Options

    assert Options().soil_from_straight and Options().soil_from_joints
    f = _fit(x=0.3)
    f.groups = {"joints": 0.3, "pose": 1.2}  # the pose group's own minimum over every window
    said: list[str] = []
    straight = rule in ("straight", "straight-pose")
    d = SimpleNamespace(
        opts=SimpleNamespace(
            soil_from_straight=straight,
            soil_from_joints=rule == "straight",
            soil_from_motion=rule == "motion",
            soft_end_unread=False,
            noise_draws=0,
            polish=0,
            name_beyond_allowance=False,
        ),
        ev=FakeEv(2.0, u_pose=0.9),  # the groups' minima over the straight windows
        chosen=[SimpleNamespace(fit=f, fit_scale=None, test="")],
        allowance=None,
        say=said.append,
    )
    sel.finish_chosen(d)  # type: ignore[arg-type]
    want = {"straight": 2.0, "straight-pose": 0.9, "motion": 1.2, None: 0.3}[rule]
    assert f.x[0] == pytest.approx(want, rel=0.05)
    words = {"straight": "straight driving", "motion": "rover's motion"}
    said_rule = "straight" if straight else rule
    assert [w for w in words.values() if any(w in m for m in said)] == (
        [words[said_rule]] if said_rule else []
    )
    read = getattr(d.chosen[0], "read_from", None)  # recorded in result.json's fit
    assert (read["rule"] if read else None) == said_rule
    if read:
        k, lo, hi = read["replaced"]["loose_soil"]["k_phi"]
        assert k == pytest.approx(1e6 / 0.3) and lo < k < hi  # the fit before the move
    if straight:
        assert read is not None
        assert read["group"] == ("joints" if rule == "straight" else "pose")
        assert any(f"the {read['group']} signals" in m for m in said)
        reads = read["reads"]  # each group's reading, as k_phi
        assert reads["joints"] == pytest.approx(1e6 / 2.0, rel=0.05)
        assert reads["pose"] == pytest.approx(1e6 / 0.9, rel=0.05)
