"""The ground's tilt and the rover's resistance read from the reported motor torque
(rover_env.calibration.balance) and what the balance stage does with them.

The logs here come from a rigid rover of this file's own: straight runs and turns at given
wheel speeds, the heading turning with the sides' difference, and each driven wheel's torque
a quarter of what holds the rover against gravity along its heading and its resistance,
times the lever, plus the driver's noise; the free wheels turn slower than the driven ones by
the slip that traction takes at the tires' slip stiffness (times ``stiff``), plus a slip the
same both ways (``slip_offset``: a radius off). Not the simulator.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration.balance import (
    CLEAN_SLIP_TILT,
    CLEAN_TILT,
    HOLD,
    TURN_SETTLE,
    BalanceReading,
    Run,
    lever,
    read_balance,
    runs,
)
from rover_env.calibration.diagnosis.balance_stage import (
    PLAN,
    UNDECIDED,
    action,
    record,
    wide_at,
)
from rover_env.calibration.drive_plan import DrivePlanError, proposals_from_report
from rover_env.calibration.evidence import PLAN_DURATION, PLAN_SEED
from rover_env.calibration.heading import free_wheels, headings
from rover_env.calibration.plans_held import ask
from rover_env.calibration.report_notes import balance_lines
from rover_env.cli import main
from rover_env.config import RoverConfig
from rover_env.estimation.estimator import static_rolling_radius
from rover_env.logs import DriveLog, LogMeta

CFG = RoverConfig()
WHY_NOT_NONE = "fewer steady straight runs with the torque and the heading than it needs"
WEIGHT = CFG.masses.total * 9.81

# (seconds, left, right) wheel targets: straight runs both ways joined by turns of about 90°.
DRIVE = [
    (4.0, 2.0, 2.0),
    (1.5, -1.5, 1.5),
    (4.0, 2.5, 2.5),
    (4.0, -2.0, -2.0),
    (1.5, -1.5, 1.5),
    (4.0, 1.5, 1.5),
    (4.0, -2.5, -2.5),
    (1.5, -1.5, 1.5),
    (4.0, 3.0, 3.0),
    (4.0, -1.5, -1.5),
]


def rover_log(
    tilt_deg: float,
    heading_deg: float,
    c_rr: float,
    *,
    plan: list[tuple[float, float, float]] = DRIVE,
    seed: int = 0,
    noise: float = 0.02,
    scale: float = 1.0,
    fix_every: int = 50,
    stiff: float = 1.0,
    slip_offset: float = 0.0,
    over: float = 1.0,
    drift: float = 0.0,
) -> DriveLog:
    """One drive of ``plan`` on ground rising ``tilt_deg`` toward ``heading_deg``, the rover
    losing ``c_rr`` of its weight rolling; the driver reports ``scale`` x the torque; the
    tires' slip stiffness is ``stiff`` x the configured one; the free wheels turn apart by
    ``over`` x the rover's yaw (a skid-steered rover's scrub) plus ``drift`` rad a metre of
    travel (free wheels of unequal size)."""
    rng = np.random.default_rng(seed)
    dt = 0.02
    t = np.arange(0.0, sum(p[0] for p in plan) + 1.0, dt)
    cmd = np.zeros((len(t), 4))
    edges = np.cumsum([1.0] + [p[0] for p in plan])
    for (dur, left, right), t0 in zip(plan, edges[:-1], strict=True):
        on = (t >= t0) & (t < t0 + dur)
        cmd[on] = [left, right, left, right]
    r = CFG.geometry.wheel_radius
    yaw = np.cumsum((cmd[:, 1] - cmd[:, 0]) * r / (2 * CFG.geometry.half_track)) * dt
    v = 0.5 * (cmd[:, 0] + cmd[:, 1])
    g = WEIGHT * math.sin(math.radians(tilt_deg))
    force = g * np.cos(yaw - math.radians(heading_deg)) + c_rr * WEIGHT * np.sign(v)
    effort = scale * np.repeat((force * lever(CFG) / 4)[:, None], 4, axis=1)
    effort += rng.normal(0.0, noise, effort.shape)
    slip = np.sign(v) * force / (4 * CFG.tire.C_s * stiff) + np.where(v != 0, slip_offset, 0.0)
    phi = np.cumsum(np.c_[cmd, cmd[:, :2] * (1.0 - slip)[:, None]], axis=0) * dt
    # The free wheels apart by the yaw times the track over the radius, here ``over`` x that.
    travel = np.cumsum(v) * dt * r
    apart = (over - 1.0) * yaw + drift * travel
    apart = apart * CFG.geometry.half_track / static_rolling_radius(CFG)
    phi[:, 4] -= apart
    phi[:, 5] += apart
    pose = np.full((len(t), 3), np.nan)
    fix = np.arange(0, len(t), fix_every)  # 1 Hz by default
    pose[fix, 2] = yaw[fix] + rng.normal(0.0, 0.005, len(fix))
    return DriveLog(
        t=t,
        cmd=cmd,
        phi=phi,
        theta=np.zeros((len(t), 5)),
        pose=pose,
        meta=LogMeta(rover="proto_explorer", sample_rate_hz=50.0),
        effort=effort,
    )


@pytest.mark.parametrize(
    ("tilt", "heading", "c_rr"), [(0.0, 0.0, 0.01), (1.0, 40.0, 0.01), (3.0, -120.0, 0.05)]
)
def test_tilt_heading_and_resistance_are_read_within_their_intervals(
    tilt: float, heading: float, c_rr: float
) -> None:
    logs = [rover_log(tilt, heading, c_rr, seed=s) for s in range(3)]
    r, runs = read_balance(logs, CFG, 0.1)
    assert r is not None and len(runs) == 3 * 7  # DRIVE's seven straight runs a log
    lo, hi = r.tilt_interval()
    assert lo <= tilt <= hi
    assert hi - lo < 0.3 + 2 * 0.1 * tilt  # the noise, and the 10 % scale tolerance
    if tilt > 0:
        assert abs(math.remainder(r.heading - heading, 360.0)) < 5.0
    clo, chi = r.c_rr_interval()
    assert clo <= c_rr <= chi
    assert r.inflation < 3.0


@pytest.mark.parametrize("heading", [10.0, 45.0, -135.0])
def test_a_torque_scale_off_is_inside_the_tolerance(heading: float) -> None:
    logs = [rover_log(2.0, heading, 0.02, seed=s, scale=1.18) for s in range(3)]
    r, _ = read_balance(logs, CFG, 0.2)
    assert r is not None
    lo, hi = r.tilt_interval()
    assert lo <= 2.0 <= hi  # at any heading: the scale moves the whole vector
    assert r.tilt == pytest.approx(2.36, abs=0.05)  # the scale moves the read by its own part
    narrow, _ = read_balance(logs, CFG, 0.0)
    assert narrow is not None and not narrow.tilt_interval()[0] <= 2.0 <= narrow.tilt_interval()[1]


def test_runs_one_way_in_one_heading_cannot_tell_a_tilt_from_a_resistance() -> None:
    plan = [(4.0, 2.0, 2.0), (0.5, 0.0, 0.0)] * 4
    logs = [rover_log(2.0, 0.0, 0.02, plan=plan, seed=s) for s in range(2)]
    r, runs = read_balance(logs, CFG, 0.1)
    assert r is not None and len(runs) == 8
    assert not r.separated  # the tilt along the track and the resistance are one unknown
    assert action(r.tilt_interval(), CLEAN_TILT, 3.0, False, r.separated) == "unseparated"


def test_logs_without_torque_give_no_torque_reading() -> None:
    log = rover_log(1.0, 0.0, 0.01)
    bare = DriveLog(log.t, log.cmd, log.phi, log.theta, log.pose, log.meta)
    assert read_balance([bare], CFG, 0.1) == (None, [])


def _end_only(log: DriveLog, keep_end: bool = True) -> DriveLog:
    """``log`` with the pose's fixes gone but its last (SPEC §6's log), or all gone."""
    pose = np.full_like(log.pose, np.nan)
    if keep_end:
        last = np.flatnonzero(np.isfinite(log.pose[:, 2]))[-1]
        pose[last] = log.pose[last]
    return DriveLog(log.t, log.cmd, log.phi, log.theta, pose, log.meta, effort=log.effort)


def _pose_yaw(logs: list[DriveLog]) -> list[np.ndarray | None]:
    return [None] * len(logs)


@pytest.mark.parametrize("what", ["effort", "slip"])
def test_without_the_pose_the_free_wheels_give_the_heading(what: str) -> None:
    """Free wheels that over-read the turns by 15 % and drift 0.03 rad a metre (DRIVE turns
    90° at a time): fitted to each drive's last fix the heading is the pose's, and
    the tilt reads within its interval (three fixes for four unknowns: within 3°, where the
    free wheels alone are off by 9°); with no fix at all the priors alone leave it wider,
    the truth still inside."""
    truth = [rover_log(1.5, 60.0, 0.02, seed=s, over=1.15, drift=0.03) for s in range(3)]
    ends = [_end_only(lg) for lg in truth]
    hd = headings(ends, CFG, _pose_yaw(ends))
    assert hd.source == ["end fix"] * 3
    for lg, end, yaw in zip(truth, ends, hd.yaw(), strict=True):
        have = np.isfinite(lg.pose[:, 2])
        assert yaw is not None
        assert np.degrees(np.abs(yaw[have] - lg.pose[have, 2])).max() < 3.0
        kin, _ = free_wheels(end, CFG)  # the free wheels' own turn, unfitted
        assert np.degrees(np.abs(kin[have] - lg.pose[have, 2])).max() > 5.0
    widths = {}
    for name, logs in (("end fix", ends), ("free wheels", [_end_only(lg, False) for lg in truth])):
        r, rs = read_balance(logs, CFG, 0.1, what)
        assert r is not None and r.heading_from == name and len(rs) == 3 * 7
        lo, hi = r.tilt_interval()
        assert lo <= 1.5 <= hi
        widths[name] = hi - lo
    with_pose, _ = read_balance(truth, CFG, 0.1, what)
    assert with_pose is not None and with_pose.heading_from == "pose"
    pose_width = with_pose.tilt_interval()[1] - with_pose.tilt_interval()[0]
    assert pose_width <= widths["end fix"] < widths["free wheels"]


def test_the_fix_is_read_on_the_branch_nearest_the_free_wheels() -> None:
    end = _end_only(rover_log(0.0, 0.0, 0.01, over=1.15))
    last = np.flatnonzero(np.isfinite(end.pose[:, 2]))[-1]
    (yaw,) = headings([end], CFG, [None]).yaw()
    assert yaw is not None and yaw[last] == pytest.approx(end.pose[last, 2], abs=0.01)
    for turns in (-1, 1):  # the fix as a pose reports it, whole turns off: the same heading
        pose = end.pose.copy()
        pose[last, 2] += 2 * math.pi * turns
        moved = DriveLog(end.t, end.cmd, end.phi, end.theta, pose, end.meta)
        (again,) = headings([moved], CFG, [None]).yaw()
        assert again is not None and np.allclose(again, yaw)


def test_a_rover_left_bent_is_not_a_straight_run() -> None:
    logs = [rover_log(0.0, 0.0, 0.01, seed=s) for s in range(3)]
    _, straight = read_balance(logs, CFG, 0.1)
    bent = logs[0].theta.copy()
    bent[logs[0].t > 20.0, 1] = math.radians(5.0)  # theta_2 held off after 20 s
    logs[0] = DriveLog(
        logs[0].t, logs[0].cmd, logs[0].phi, bent, logs[0].pose, logs[0].meta, effort=logs[0].effort
    )
    _, kept = read_balance(logs, CFG, 0.1)
    assert len(kept) < len(straight)
    assert all(r.t1 <= 20.0 for r in kept if r.log == 0)


@pytest.mark.parametrize(
    ("tilt", "windows_low", "inside", "expected"),
    [
        ((0.9, 1.3), None, False, "name"),
        ((0.9, 1.3), 2.6, False, "name"),
        ((0.9, 1.3), None, True, "inside"),
        ((0.2, 0.6), 2.5, True, "inside"),
        ((0.2, 0.6), None, False, "level"),
        ((0.2, 0.6), 2.5, False, "withdraw"),
        ((0.2, 0.6), 0.4, False, "level"),
    ],
)
def test_what_a_reading_does_beside_the_windows(
    tilt: tuple[float, float], windows_low: float | None, inside: bool, expected: str
) -> None:
    assert action(tilt, 0.5, windows_low, inside) == expected
    assert action(tilt, 0.5, windows_low, inside, separated=False) == "unseparated"


def test_the_report_says_what_was_read() -> None:
    logs = [rover_log(1.5, 30.0, 0.02, seed=s) for s in range(3)]
    r, runs = read_balance(logs, CFG, 0.1)
    assert r is not None
    rec = {"runs": len(runs), "read": True, "named": True, "allowance": 0.5, **r.as_json()}
    text = "\n".join(balance_lines(rec))
    assert abs(math.remainder(r.heading - 30.0, 360.0)) < 2.0
    assert "named `slope` from it" in text and f"toward {r.heading:.0f}°" in text
    assert "headed by" not in text  # the pose's fixes: nothing to say
    none = "\n".join(balance_lines({"runs": 2, "read": False, "why_not": "too few"}))
    assert "2 steady straight runs" in none and "too few" in none
    ends = [_end_only(lg) for lg in logs]
    e, _ = read_balance(ends, CFG, 0.1, "slip")
    assert e is not None
    rec = {"runs": e.runs, "read": True, "named": True, "allowance": 0.3, **e.as_json()}
    assert "headed by the free wheels' turn fitted to each drive's one pose fix" in "\n".join(
        balance_lines(rec)
    )


def test_unseparated_runs_print_no_tilt() -> None:
    """Runs that do not tell a tilt from a resistance give a degenerate solve (block 54900's
    54917: 90° [0, 17783]); the report says they were not read and proposes the drive."""
    logs = [rover_log(1.5, 30.0, 0.02, seed=s) for s in range(3)]
    r, runs = read_balance(logs, CFG, 0.1)
    assert r is not None
    rec = {"runs": len(runs), "read": True, "named": False, "allowance": 0.5, **r.as_json()}
    rec |= {"tilt": 90.0, "tilt_interval": [0.0, 17783.4], "separated": False}
    rec |= {"why_not": "the runs do not tell a tilt from a resistance", "plan": "reversals"}
    rec |= {"seed": 0, "duration": 50.0}
    text = "\n".join(balance_lines(rec))
    assert "not read: the runs do not tell a tilt from a resistance" in text
    assert "90.00°" not in text and "17783" not in text
    assert "Proposed drive `reversals`" in text
    rec["separated"] = True
    assert "90.00°" in "\n".join(balance_lines(rec))


@pytest.mark.parametrize("flag", ["--balance-allowance", "--slip-allowance"])
@pytest.mark.parametrize("bad", ["-0.1", "25", "nan", "level"])
def test_a_bad_balance_allowance_is_refused_naming_the_flag(
    flag: str, bad: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(
            [
                "diagnose",
                str(tmp_path / "x.csv"),
                "--out",
                str(tmp_path),
                flag,
                bad,
            ]
        )
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert flag in err and bad in err, err


def test_an_unseparated_reading_asks_for_the_drive_both_ways(tmp_path: Path) -> None:
    logs = [
        rover_log(1.0, 0.0, 0.02, plan=[(4.0, 2.0, 2.0), (0.5, 0.0, 0.0)] * 4, seed=s)
        for s in range(2)
    ]
    reading, runs = read_balance(logs, CFG, 0.2)
    act, rec = record(reading, len(runs), 0.5, 3.0, False)
    assert act == "unseparated" and not rec["named"] and rec["plan"] == PLAN
    text = "\n".join(balance_lines(rec))
    assert f"drive-plan --plan {PLAN} --seed {PLAN_SEED} --duration {PLAN_DURATION:g}" in text
    (tmp_path / "result.json").write_text(json.dumps({"balance": rec}))
    (prop,) = proposals_from_report(tmp_path)
    assert (prop.plan, prop.seed, prop.duration) == (PLAN, PLAN_SEED, PLAN_DURATION)
    assert prop.effects == {"slope"} and "force balance" in prop.why[0]
    sloped, runs = read_balance([rover_log(1.5, 0.0, 0.02, seed=s) for s in range(3)], CFG, 0.2)
    act, rec = record(sloped, len(runs), 0.5, None, False)
    assert act == "name" and "plan" not in rec
    (tmp_path / "result.json").write_text(json.dumps({"balance": rec}))
    with pytest.raises(DrivePlanError, match="proposes no drive"):
        proposals_from_report(tmp_path)


def test_a_named_reading_whose_size_is_not_known_asks_for_the_drive(tmp_path: Path) -> None:
    """Named, and its interval's ends more than SPREAD apart (a flat valley: block 54100 read
    2.48° as 8.00°): the slope is named and the crossing drive asked for; a narrow one asks
    for nothing."""
    from dataclasses import replace

    from rover_env.calibration.diagnosis.balance_stage import SPREAD

    sloped, runs = read_balance([rover_log(1.5, 0.0, 0.02, seed=s) for s in range(3)], CFG, 0.2)
    assert sloped is not None
    lo, hi = sloped.tilt_interval()
    assert hi < SPREAD * lo  # runs that cross: the size known
    for bounds, asks in (((1.0, 8.0), True), ((1.2, 1.9), False)):
        r = replace(sloped, size_bounds=bounds)
        act, rec = record(r, len(runs), 0.5, None, False)
        lo, hi = r.tilt_interval()
        assert act == "name" and (hi > SPREAD * lo) == asks
        assert ("plan" in rec) == asks and ("why_drive" in rec) == asks
    act, rec = record(replace(sloped, size_bounds=(1.0, 8.0)), len(runs), 0.5, None, False)
    rec["named"] = True  # as name_by_balance records it
    text = "\n".join(balance_lines(rec))
    assert "named `slope` from it, but its size is not known" in text
    assert f"drive-plan --plan {PLAN}" in text
    (tmp_path / "result.json").write_text(json.dumps({"balance": rec}))
    (prop,) = proposals_from_report(tmp_path)
    assert prop.plan == PLAN and "size is not known" in prop.why[0]
    from rover_env.calibration.diagnosis.write import rover_header

    lo, hi = rec["truth_interval"]
    head = rover_header([], rec)  # rover.yaml's comment: the value is one of those allowed
    assert "slope.deg is not known" in head and f"{lo:.2f}-{hi:.2f}" in head
    assert f"--plan {PLAN} --seed {PLAN_SEED}" in head
    assert "not known" not in rover_header([], {**rec, "why_drive": None})
    assert "not known" not in rover_header([], {**rec, "named": False})
    again = ask(dict(rec), {PLAN: [{"seed": PLAN_SEED, "log": "drive_03.csv"}]})  # driven once
    text = "\n".join(balance_lines(again))
    assert f"--plan {PLAN} --seed {PLAN_SEED + 1} " in text and "(drive_03.csv)" in text
    assert f"--plan {PLAN} --seed {PLAN_SEED + 1} " in rover_header([], again)


def test_runs_that_determine_nothing_are_read_unseparated_with_open_bounds() -> None:
    plan = [(4.0, 2.0, 2.0), (0.5, 0.0, 0.0)] * 4  # forwards in one heading, every run alike
    logs = [rover_log(1.0, 0.0, 0.02, plan=plan, seed=s, noise=0.0) for s in range(2)]
    for log in logs:
        log.pose[:, 2] = np.where(np.isfinite(log.pose[:, 2]), 0.0, np.nan)  # exactly straight
    r, runs = read_balance(logs, CFG, 0.2)
    assert r is not None and len(runs) == 8 and not r.separated
    assert r.tilt_interval()[1] == math.inf
    rec = r.as_json()
    assert rec["tilt_interval"][1] is None and rec["inflation"] is None
    json.dumps(rec, allow_nan=False)  # no infinity in result.json
    act, out = record(r, len(runs), 0.5, None, False)
    text = "\n".join(balance_lines(out))  # no degenerate numbers printed (stop 133)
    assert act == "unseparated" and "not read" in text and "rises" not in text


def test_a_heading_far_from_every_fix_is_not_known() -> None:
    sparse = [rover_log(1.0, 40.0, 0.02, seed=s, fix_every=10**6) for s in range(3)]  # t = 0 only
    alone = read_balance(sparse, CFG, 0.2)[0]  # one fix: the free wheels give every row's
    assert alone is not None and alone.heading_from == "free wheels"

    def seconds(runs: list[Run]) -> float:
        return sum(r.t1 - r.t0 for r in runs)

    every_1s = read_balance([rover_log(1.0, 40.0, 0.02, seed=s) for s in range(3)], CFG, 0.2)[1]
    every_6s = [rover_log(1.0, 40.0, 0.02, seed=s, fix_every=300) for s in range(3)]
    kept = read_balance(every_6s, CFG, 0.2)[1]
    assert seconds(kept) < 0.8 * seconds(every_1s)  # the rows over 2 s from a fix are dropped
    for r in kept:  # and no run is read where no fix lies within 2 s
        assert (
            min(abs(r.t0 - 6.0 * round(r.t0 / 6.0)), abs(r.t1 - 6.0 * round(r.t1 / 6.0)))
            <= 2.0 + 0.02
        )


def test_the_resistance_interval_widens_by_the_scale_on_both_sides() -> None:
    logs = [rover_log(0.0, 0.0, -0.001, seed=s) for s in range(3)]  # a push, as a bad zero reads
    r, _ = read_balance(logs, CFG, 0.2)
    assert r is not None
    lo, hi = r.c_rr_interval()
    plain, _ = read_balance(logs, CFG, 0.0)
    assert plain is not None
    plo, phi = plain.c_rr_interval()
    assert lo < plo < 0.0 and hi > phi
    assert lo <= -0.001 <= hi


def test_a_level_reading_withdraws_a_slope_the_windows_named_alone_only() -> None:
    level, runs = read_balance([rover_log(0.0, 0.0, 0.02, seed=s) for s in range(3)], CFG, 0.2)
    assert level is not None and level.separated
    assert record(level, len(runs), 0.5, 2.6, False)[0] == "withdraw"
    assert record(level, len(runs), 0.5, 2.6, True)[0] == "inside"  # a pair's: reported
    assert record(level, len(runs), 0.5, None, False)[0] == "level"
    assert record(None, 3, 0.5, None, False) == (
        "none",
        {
            "runs": 3,
            "read": False,
            "named": False,
            "source": "effort",
            "action": "none",
            "why_not": WHY_NOT_NONE,
        },
    )


def bare(log: DriveLog) -> DriveLog:
    """The log without its torque columns (SPEC §6's)."""
    return DriveLog(log.t, log.cmd, log.phi, log.theta, log.pose, log.meta)


@pytest.mark.parametrize(("tilt", "heading"), [(0.0, 0.0), (1.0, 40.0), (2.5, -120.0)])
def test_the_slip_balance_reads_the_tilt_without_torque(tilt: float, heading: float) -> None:
    logs = [bare(rover_log(tilt, heading, 0.02, seed=s, slip_offset=0.012)) for s in range(3)]
    assert read_balance(logs, CFG, 0.2)[0] is None  # no torque: the torque's balance is blind
    r, runs = read_balance(logs, CFG, 0.2, "slip")
    assert r is not None and len(runs) == 3 * 7 and r.source == "slip"
    lo, hi = r.tilt_interval()
    assert lo <= tilt <= hi
    assert r.tilt == pytest.approx(
        tilt, abs=0.02
    )  # the radius's slip, the same both ways, is not a tilt
    hlo, hhi = r.heading_interval()
    if tilt > 0:
        assert abs(math.remainder(r.heading - heading, 360.0)) < 2.0
        assert hlo <= r.heading + math.remainder(heading - r.heading, 360.0) <= hhi
        assert 0.0 < hhi - hlo < 30.0  # seven runs in three headings a drive: a few degrees
    else:
        assert hhi - hlo == 360.0  # level: no direction
    drag = 0.02 * WEIGHT / (4 * CFG.tire.C_s)
    assert r.offset_slip == pytest.approx(0.012 + drag, rel=0.05)


def test_a_tire_stiffer_or_softer_than_configured_is_inside_the_slip_tolerance() -> None:
    for stiff in (0.85, 1.18):
        logs = [bare(rover_log(2.0, 70.0, 0.02, seed=s, stiff=stiff)) for s in range(3)]
        r, _ = read_balance(logs, CFG, 0.2, "slip")
        assert r is not None
        lo, hi = r.tilt_interval()
        assert lo <= 2.0 <= hi
        assert r.tilt == pytest.approx(2.0 / stiff, rel=0.02)


def test_the_stage_reads_the_torque_where_logged_and_the_slip_elsewhere() -> None:
    from rover_env.calibration.balance import CLEAN_SLIP_TILT, SCALE, SLIP_SCALE
    from rover_env.calibration.diagnosis.balance_stage import source
    from rover_env.calibration.diagnosis.state import Options

    assert source(Options(), True) == ("effort", CLEAN_TILT, SCALE)
    assert source(Options(), False) == ("slip", CLEAN_SLIP_TILT, SLIP_SCALE)
    assert source(Options(effort_tolerance=None), True)[0] == "slip"  # torque not read
    assert source(Options(balance_allowance=None), True)[0] == "slip"  # each switch its own
    assert source(Options(slip_allowance=None), False) is None
    assert source(Options(slip_allowance=0.2), False) == ("slip", 0.2, SLIP_SCALE)


def test_the_slip_balance_is_reported_and_proposes_its_drive(tmp_path: Path) -> None:
    logs = [bare(rover_log(1.5, 30.0, 0.02, seed=s)) for s in range(3)]
    r, runs = read_balance(logs, CFG, 0.2, "slip")
    act, rec = record(r, len(runs), 0.3, None, False, "slip")
    assert act == "name" and rec["source"] == "slip"
    text = "\n".join(balance_lines(json.loads(json.dumps(rec))))
    assert "slip against the free wheels'" in text and "toward 30°" in text
    plan = [(4.0, 2.0, 2.0), (0.5, 0.0, 0.0)] * 4
    one_way = [bare(rover_log(1.0, 0.0, 0.02, plan=plan, seed=s)) for s in range(2)]
    r, runs = read_balance(one_way, CFG, 0.2, "slip")
    act, rec = record(r, len(runs), 0.3, None, False, "slip")
    assert act == "unseparated" and rec["plan"] == PLAN
    (tmp_path / "result.json").write_text(json.dumps({"balance": rec}))
    (prop,) = proposals_from_report(tmp_path)
    assert "the wheels' slip" in prop.why[0]
    soil_act, _ = record(r, len(runs), 0.3, None, False, "slip", soil=True)
    assert soil_act == "unseparated"  # the drive is still asked for
    sloped, sruns = read_balance(logs, CFG, 0.2, "slip")
    assert record(sloped, len(sruns), 0.3, None, False, "slip", soil=True)[0] == "soil"
    assert record(sloped, len(sruns), 0.3, None, False, "effort", soil=True)[0] == "name"
    none = record(None, 2, 0.3, None, False, "slip")[1]
    assert "torque" not in none["why_not"]
    from rover_env.calibration.report_notes import balance_method

    assert "free wheels" in balance_method(0.3, True, "slip")[0]
    assert "torque" in balance_method(0.5, True)[0] and balance_method(None, True, "slip") == []
    with pytest.raises(ValueError, match="source"):
        read_balance(logs, CFG, 0.2, "pose")


def test_the_slip_balance_weighs_runs_by_the_encoders_step_and_its_floor(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import rover_env.calibration.balance as balance

    logs = [bare(rover_log(1.0, 40.0, 0.02, seed=s)) for s in range(3)]
    r, runs = read_balance(logs, CFG, 0.2, "slip")
    assert r is not None and balance.resolution(logs[0].phi) == 0.0  # not quantised
    assert all(x.noise == pytest.approx(balance.SLIP_FLOOR * 400.0) for x in runs)
    lo, hi = r.tilt_interval()
    assert hi - lo < 0.1 + 2 * 0.2 * 1.0  # the floor over 21 runs, and the 20 % stiffness
    step = 2 * math.pi / 1024  # a 1024-count encoder
    coarse = [
        DriveLog(x.t, x.cmd, np.round(x.phi / step) * step, x.theta, x.pose, x.meta) for x in logs
    ]
    rq, runs_q = read_balance(coarse, CFG, 0.2, "slip")
    assert rq is not None and balance.resolution(coarse[0].phi) == pytest.approx(step)
    assert min(x.noise for x in runs_q) > balance.SLIP_FLOOR * 400.0
    assert rq.tilt_interval()[0] <= 1.0 <= rq.tilt_interval()[1]
    bare_width = np.diff(read_balance(logs, CFG, 0.0, "slip")[0].tilt_interval())[0]  # type: ignore[union-attr]
    monkeypatch.setattr(balance, "SLIP_FLOOR", 10 * balance.SLIP_FLOOR)
    wide, _ = read_balance(logs, CFG, 0.0, "slip")
    assert wide is not None  # the runs agree better than the floor: it sets the width
    assert np.diff(wide.tilt_interval())[0] > 5 * bare_width


def test_runs_beyond_the_critical_slip_are_left_out() -> None:
    from rover_env.calibration.balance import critical_slip

    assert critical_slip(CFG) == pytest.approx(3 * 0.4 * WEIGHT / 6 / 100.0)
    logs = [bare(rover_log(1.0, 40.0, 0.02, seed=s)) for s in range(3)]
    stalled = logs[0].phi.copy()
    stalled[:, 4:] = 0.0  # the free wheels' encoders dead: every run "slips" 100 %
    logs[0] = DriveLog(logs[0].t, logs[0].cmd, stalled, logs[0].theta, logs[0].pose, logs[0].meta)
    r, runs = read_balance(logs, CFG, 0.2, "slip")
    assert r is not None and {x.log for x in runs} == {1, 2} and len(runs) == 14
    assert r.tilt_interval()[0] <= 1.0 <= r.tilt_interval()[1]


def test_a_wide_separated_reading_leaves_the_windows_their_slope_drive() -> None:
    from types import SimpleNamespace

    from rover_env.calibration.diagnosis.evidence_stage import balance_settled

    edge = SimpleNamespace(edge=lambda effect, side: 2.4)

    def settled(**bal: object) -> bool:
        d = SimpleNamespace(balance={"separated": True, **bal}, allowance=edge)
        return balance_settled(d)  # type: ignore[arg-type]

    assert settled(named=True, tilt_interval=[0.8, 9.0])
    assert settled(withdrew=[{"deg": 3.0}], tilt_interval=[0.0, 0.4])
    assert settled(tilt_interval=[0.0, 1.2])  # level, narrower than the windows can name
    assert not settled(tilt_interval=[0.0, 8.99])  # level inside, but it says little
    assert not settled(tilt_interval=[0.0, None])
    assert not balance_settled(SimpleNamespace(balance=None, allowance=edge))  # type: ignore[arg-type]
    unsep = SimpleNamespace(balance={"separated": False, "named": False}, allowance=edge)
    assert not balance_settled(unsep)  # type: ignore[arg-type]


def test_a_straight_run_counts_only_once_the_chain_settles_after_a_turn() -> None:
    log = rover_log(0.0, 0.0, 0.01)  # DRIVE: a 1.5 s pivot before every other straight run
    pivots = np.abs(log.cmd[:, 0] - log.cmd[:, 1]) > 0
    ends = log.t[np.flatnonzero(pivots[:-1] & ~pivots[1:])]
    settled = runs(log, 0, lever(CFG))
    early = runs(log, 0, lever(CFG), settle=0.0)
    for e in ends:
        after = [r for r in settled if e < r.t0 < e + 5.0]
        assert after and all(r.t0 >= e + TURN_SETTLE - 0.03 for r in after)
        assert any(e < r.t0 < e + HOLD + 0.05 for r in early)
    assert len(settled) == len(early)  # the runs stay; their first seconds go


def _reading(sd: float, tilt: float = 0.4) -> BalanceReading:
    return BalanceReading(
        runs=12, tilt_x=tilt, tilt_y=0.0, sd_x=sd, sd_y=sd, corr=0.0, resistance=0.0,
        sd_resistance=1.0, dof=9, weight=WEIGHT, lever=lever(CFG), tolerance=0.2,
        inflation=10.0, scatter=1.0, source="slip", stiffness=4 * CFG.tire.C_s,
    )  # fmt: skip


def test_a_wide_level_reading_asks_for_the_drive_and_a_narrow_one_does_not() -> None:
    wide, narrow = _reading(sd=0.8), _reading(sd=0.15)
    assert wide.tilt_interval()[0] == 0.0 and wide.tilt_interval()[1] > UNDECIDED
    assert narrow.tilt_interval()[1] < UNDECIDED
    act, rec = record(wide, 12, 0.3, None, False, "slip")
    assert act == "wide" and rec["plan"] == PLAN and f"{UNDECIDED:g}°" in rec["why_not"]
    act, rec = record(narrow, 12, 0.3, None, False, "slip")
    assert act == "level" and "plan" not in rec
    act, rec = record(wide, 12, 0.3, 3.0, True, "slip")  # beside a pair: reported, no drive
    assert act == "inside" and "plan" not in rec
    act, rec = record(wide, 12, 0.3, None, False, "slip", soil=True)  # beside a named soil
    assert act == "soil" and "plan" not in rec
    act, _ = record(wide, 12, 0.3, wide.tilt_interval()[1] + 0.5, False, "slip")
    assert act == "withdraw"  # a windows' slope above its whole interval: withdrawn, no drive
    act, rec = record(wide, 12, 0.3, 1.0, False, "slip")  # one it cannot withdraw: the drive
    assert act == "wide" and rec["plan"] == PLAN


def test_a_larger_allowance_moves_where_a_reading_is_wide() -> None:
    """A narrow reading at 1.2° [1.0, 1.4] reaches 1°, but under a 1.5° allowance it is what
    clean builds read: no drive narrows that. A wide one still asks for the drive."""
    narrow, wide = _reading(sd=0.1, tilt=1.2), _reading(sd=1.2, tilt=1.2)
    assert record(narrow, 12, 0.3, None, False, "slip")[0] == "name"
    assert narrow.tilt_interval()[1] > UNDECIDED
    act, rec = record(narrow, 12, 1.5, None, False, "slip")
    assert act == "level" and "plan" not in rec
    assert record(wide, 12, 1.5, None, False, "slip")[0] == "wide"
    assert wide_at(CLEAN_SLIP_TILT, "slip") == wide_at(CLEAN_TILT, "effort") == UNDECIDED


def test_a_wide_reading_proposes_its_drive_in_the_report(tmp_path: Path) -> None:
    _, rec = record(_reading(sd=0.8), 12, 0.3, None, False, "slip")
    text = "\n".join(balance_lines(rec))
    assert f"drive-plan --plan {PLAN} --seed {PLAN_SEED}" in text and "crossing line" in text
    (tmp_path / "result.json").write_text(json.dumps({"balance": rec}))
    (prop,) = proposals_from_report(tmp_path)
    assert prop.plan == PLAN and prop.effects == {"slope"}


def test_the_reversals_drive_crosses_its_first_line(tmp_path: Path) -> None:
    """The drive the balance asks for reads the slope across the first line: its pivot turns
    the rover well off it (the model's own drive; its pose at 1 Hz)."""
    from rover_env.generators.make_logs import make_logs
    from rover_env.logs import read_log

    (path,) = make_logs(tmp_path, {}, drives=1, seed=3, plan=PLAN, progress=False)
    log = read_log(path)
    rs = runs(log, 0, 4 * CFG.tire.C_s, "slip")
    yaws = [math.degrees(math.atan2(r.sin_yaw, r.cos_yaw)) for r in rs]
    turned = abs(math.remainder(yaws[-1] - yaws[0], 180.0))  # between the lines, either way
    assert len(rs) >= 5 and {r.direction for r in rs} == {-1.0, 1.0}
    assert turned >= 45.0, yaws
