"""Missing evidence: the proposed drive separates the hypotheses in simulation (issue 16)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from rover_env.calibration.evidence import propose, separation, simulate_plan
from rover_env.calibration.replay import SIGNALS, ReplaySettings
from rover_env.config import RoverConfig

# Replay floors of a typical case (make-logs sensors): wheels, joints, pose.
FLOOR = {s: 0.003 for s in SIGNALS[:6]} | {s: 0.002 for s in SIGNALS[6:11]}
FLOOR |= {"pose_x": 0.012, "pose_y": 0.012, "pose_yaw": 0.017}


def _fake_drives(monkeypatch, fit, evidence, plan: str) -> None:
    """Every candidate moves a training signal by 5 floors, and every proposed drive is
    ``plan`` with fixed separations: the asking rules alone decide what is asked."""
    monkeypatch.setattr(fit, "signal_change", lambda *a, **k: {"wheel_2R": 5.0})
    monkeypatch.setattr(
        evidence, "propose", lambda base, name, *a, **kw: {"effect": name, "plan": plan,
        "best_signal": "wheel_2R", "best_per_window": 3.0, "best_floor_units": 9.0,
        "held_out_best_signal": "wheel_2R", "held_out_floor_units": 5.0},
    )  # fmt: skip


def test_hard_accelerations_separate_a_torque_limit() -> None:
    """The proposed drive, replayed as diagnose replays, moves the driven wheels by many
    floors with a lowered torque limit."""
    ext = {"torque_limit": {"fraction": -0.25}}
    p = propose(RoverConfig(), "torque_limit", ext, FLOOR, {"wheel_1L": 0.2}, duration=12.0)
    assert p["plan"] == "accel"
    assert p["best_signal"].startswith("wheel_")
    assert p["separates"] and p["best_floor_units"] >= 3.0


def test_separation_of_a_drive_with_itself_is_zero() -> None:
    log = simulate_plan(RoverConfig(), "accel", duration=6.0)
    assert max(separation(log, log, FLOOR).values()) == 0.0


@pytest.mark.slow
def test_a_measured_straight_separates_a_rolling_radius_the_pose_sees() -> None:
    """Rolling radius -3 % on all wheels: the joints and driven wheels hardly move in the
    replay; over a 50 s measured straight the pose does, by > 3 floors."""
    ext = {"rolling_radius": {"fraction": -0.03}}
    floor = FLOOR | {"wheel_3L": 0.011, "wheel_3R": 0.011}
    p = propose(RoverConfig(), "rolling_radius", ext, floor, {"pose_x": 1.4})
    assert p["plan"] == "straight" and p["separates"]
    assert p["separation"]["pose_x"] >= 3.0
    assert max(p["separation"][s] for s in SIGNALS[6:11]) < 1.0


def test_a_leaning_held_out_drive_asks_for_the_deciding_drive(monkeypatch) -> None:
    """A candidate the held-out drive improves by the window test's margin, at a p its few
    windows cannot bring under alpha, gets the drive that decides proposed; one the
    held-out drive moved but did not improve by that margin does not (it was judged)."""
    import numpy as np

    from rover_env.calibration import evidence, fit
    from rover_env.calibration.candidates import catalogue
    from rover_env.calibration.diagnosis.evidence_stage import missing_evidence
    from rover_env.calibration.diagnosis.state import Options, Scored
    from rover_env.config import RoverConfig

    cand = {c.name: c for c in catalogue()}
    moved = {"wheel_2R": 5.0, "theta_1": 0.1}  # the held-out drive excites both (>= 1 floor)
    monkeypatch.setattr(fit, "signal_change", lambda *a, **k: dict(moved))
    monkeypatch.setattr(
        evidence,
        "propose",
        lambda base, name, ext, noise, held, **kw: {
            "effect": name,
            "plan": "x",
            "best_signal": "wheel_2R",
            "best_per_window": 9.0,
            "best_floor_units": 30.0,
            "held_out_best_signal": "wheel_2R",
            "held_out_floor_units": 5.0,
        },
    )

    def scored(name: str, gain: float, p: float, d_bic: float = -5.0) -> Scored:
        f = fit.Fit(
            [cand[name]], np.array([-0.14]), np.array([-0.2]), np.array([-0.1]),
            np.array([0.02]), 1.0, 3, {name: {}}, 0.0, "train",
        )  # fmt: skip
        return Scored(f, 1.0, np.ones(16), gain, p, d_bic, d_bic, 32)

    opts = Options(progress=False)
    ev = SimpleNamespace(settings=ReplaySettings())  # only its ground is read here
    ranked = [scored("torque_limit", 0.41, 0.018), scored("command_lag", 0.05, 0.3)]
    out = missing_evidence(ev, ranked, [], {}, RoverConfig(), opts, lambda m: None)  # type: ignore[arg-type]
    assert [e["effect"] for e in out] == ["torque_limit"]
    assert "leans towards it (41 % better)" in out[0]["reason"]
    # Confirmed at alpha: the held-out drive judged it, nothing to ask.
    ranked = [scored("torque_limit", 0.41, 0.001)]
    assert missing_evidence(ev, ranked, [], {}, RoverConfig(), opts, lambda m: None) == []  # type: ignore[arg-type]


def test_strong_training_evidence_the_held_out_drive_does_not_contradict_asks_for_a_drive(
    monkeypatch,
) -> None:
    """Stop 58's registered rule, applied since stop 59: a candidate with a training ΔBIC at
    or below Options.strong_bic whose held-out drive is better at all, short of the window
    test, gets the deciding drive; one just above that line, or one the held-out drive
    makes worse, does not."""
    import numpy as np

    from rover_env.calibration import evidence, fit
    from rover_env.calibration.candidates import catalogue
    from rover_env.calibration.diagnosis.evidence_stage import missing_evidence
    from rover_env.calibration.diagnosis.state import Options, Scored
    from rover_env.config import RoverConfig

    cand = {c.name: c for c in catalogue()}
    _fake_drives(monkeypatch, fit, evidence, "accel")

    def scored(name: str, gain: float, d_bic: float) -> Scored:
        f = fit.Fit(
            [cand[name]], np.array([-0.7]), np.array([-0.75]), np.array([-0.65]),
            np.array([0.02]), 1.0, 3, {name: {}}, 0.0, "train",
        )  # fmt: skip
        return Scored(f, 1.0, np.ones(16), gain, 0.3, d_bic, d_bic, 32)

    opts = Options(progress=False)
    ev = SimpleNamespace(settings=ReplaySettings())

    def asked(*ranked: Scored) -> list[str]:
        got = missing_evidence(ev, list(ranked), [], {}, RoverConfig(), opts, lambda m: None)  # type: ignore[arg-type]
        return [e["effect"] for e in got]

    # Case 47603's numbers: ΔBIC -6.7, held-out 8.5 % better at p 0.3.
    assert asked(scored("torque_limit", 0.085, -6.7)) == ["torque_limit"]
    got = missing_evidence(
        ev, [scored("torque_limit", 0.085, -6.7)], [], {}, RoverConfig(), opts, lambda m: None
    )  # type: ignore[arg-type]
    assert "dBIC -6.7" in got[0]["reason"]
    assert asked(scored("torque_limit", 0.085, -5.9)) == []
    assert asked(scored("torque_limit", -0.02, -12.0)) == []
    opts = Options(progress=False, strong_bic=-8.0)  # the line is the option's
    assert asked(scored("torque_limit", 0.085, -6.7)) == []


def test_a_limit_the_drives_never_reach_gets_the_drive_that_asks_for_it(monkeypatch) -> None:
    """Stop 59: when the torque limit's cut threshold on these drives is beyond
    Options.limit_resolution and none is named or asked for, the accel drive is proposed
    with a cut of that resolution; not when the drives reach a 5 % cut, when it is named,
    when an evidence drive asks for it already, or when the resolution is 0."""
    import numpy as np

    from rover_env.calibration import evidence, fit
    from rover_env.calibration.candidates import catalogue
    from rover_env.calibration.diagnosis.evidence_stage import untested_limit
    from rover_env.calibration.diagnosis.state import Options, Scored
    from rover_env.calibration.report import judged_lines
    from rover_env.config import RoverConfig

    asked: list[dict] = []

    def propose(base, name, ext, noise, held, **kw):
        asked.append(ext)
        return {"effect": name, "plan": "accel", "seed": kw["seed"], "best_signal": "wheel_1L",
                "best_floor_units": 7.0}  # fmt: skip

    monkeypatch.setattr(evidence, "propose", propose)
    (c,) = catalogue(["torque_limit"])
    z = np.zeros(1)
    tl = Scored(fit.Fit([c], z, z, z, z, 1.0, 3, {}, 0.0, "train"), 1.0, z, 0.0, 0.5, 2.0, 2.0, 16)

    def d(
        thr: dict, chosen=(), ev_list=(), res: float = 0.05, rotor_range: float = 2.0, held=None,
        allowance=None,
    ) -> SimpleNamespace:  # fmt: skip
        tl.threshold = thr
        opts = Options(progress=False, limit_resolution=res, rotor_range=rotor_range)
        return SimpleNamespace(
            opts=opts, chosen=list(chosen),
            evidence=list(ev_list), ranked=[tl], base=RoverConfig(), noise={},
            ev=SimpleNamespace(settings=ReplaySettings()), say=lambda m: None, effort=None,
            held_plans=held or {}, allowance=allowance, evidence_judged=[],
        )  # fmt: skip

    (p,) = untested_limit(d({"-": 0.30, "+": 2.0}))  # type: ignore[arg-type]
    assert p["plan"] == "accel" and "only cuts beyond 30 %" in p["reason"]
    assert "a cut of 5 %" in p["reason"]
    assert asked == [{"torque_limit": {"fraction": -0.05}}]
    # Above the tires' traction a cut under the rotor floor reads as the rotor's tolerance.
    assert p["rotor_floor"] == pytest.approx(-0.348, abs=1e-3)
    assert "a cut under 35 % acts as a rotor inertia within its tolerance (x2)" in p["reason"]
    assert "0.91 N m a wheel against a limit of 3 N m" in p["reason"]
    (q,) = untested_limit(d({"-": 0.30}, rotor_range=1.0))  # type: ignore[arg-type]
    assert q["rotor_floor"] == 0.0 and "rotor inertia" not in q["reason"]
    assert "no cut moved" in untested_limit(d({}))[0]["reason"]  # type: ignore[arg-type]
    assert untested_limit(d({"-": 0.04})) == []  # type: ignore[arg-type]
    assert untested_limit(d({"-": 0.3}, chosen=[tl])) == []  # type: ignore[arg-type]
    assert untested_limit(d({"-": 0.3}, ev_list=[{"effect": "torque_limit"}])) == []  # type: ignore[arg-type]
    judged = d({"-": 0.3})  # the evidence stage judged no drive worth asking for it
    judged.evidence_judged = [{"effect": "torque_limit", "why": "allowance"}]
    assert untested_limit(judged) == [] and len(judged.evidence_judged) == 1  # type: ignore[arg-type]
    assert untested_limit(d({"-": 0.3}, res=0.0)) == []  # type: ignore[arg-type]
    # The reported torque held at a ceiling: the limit was read, no drive is asked for it.
    read = d({"-": 0.3})
    read.effort = {"level": 2.2}
    assert untested_limit(read) == []  # type: ignore[arg-type]
    read.effort = {"level": None}  # asked and never held: still proposed
    (r,) = untested_limit(read)  # type: ignore[arg-type]
    assert "log the motors' torque" not in r["reason"]  # they were logged
    assert "log the motors' torque (effort_* columns" in p["reason"]  # not logged: say so
    assert p["seed"] == 0 and "held" not in p
    # The logs hold the accel drive's first draw: the limit was asked for, and its
    # threshold on the training drives does not see that drive (stop 129): nothing asked,
    # and the progress line names the log that holds it.
    once = {"accel": [{"seed": 0, "log": "drive_03.csv"}]}
    lines: list[str] = []
    held = d({"-": 0.30}, held=once)
    held.say = lines.append
    assert untested_limit(held) == []  # type: ignore[arg-type]
    assert "'accel': drive_03.csv" in lines[0]
    assert held.evidence_judged == [{"effect": "torque_limit", "plan": "accel",
        "why": "untested_held", "logs": ["drive_03.csv"]}]  # fmt: skip
    text = "\n".join(judged_lines(held.evidence_judged))
    assert "hold the drive that asks the motors for it (`accel`: drive_03.csv)" in text
    # Another plan held asks for nothing: the accel drive is still proposed.
    (other,) = untested_limit(d({"-": 0.30}, held={"steps": once["accel"]}))  # type: ignore[arg-type]
    assert other["seed"] == 0 and "held" not in other
    # The drives reach every cut beyond the clean-fit allowance's edge (62 %): the wheel
    # angles name none under it whatever the drive, so none is asked, and it is recorded;
    # a threshold beyond the edge, or the motors' torque logged, still asks.
    edge = SimpleNamespace(edge=lambda effect, side: 0.62 if side == "-" else 0.16)
    reach = d({"-": 0.30}, allowance=edge)
    assert untested_limit(reach) == []  # type: ignore[arg-type]
    assert reach.evidence_judged == [{"effect": "torque_limit", "plan": "accel",
        "why": "untested_allowance", "threshold": 0.30, "edge": 0.62}]  # fmt: skip
    assert len(untested_limit(d({"-": 0.70}, allowance=edge))) == 1  # type: ignore[arg-type]
    logged = d({"-": 0.30}, allowance=edge)
    logged.effort = {"level": None}
    assert len(untested_limit(logged)) == 1  # type: ignore[arg-type]


def test_the_rotor_floor_is_the_cut_a_heavier_rotor_mimics_where_the_limit_binds() -> None:
    """Stop 93: above the tires' traction a limit binds only while a wheel spins up, at
    (limit - transmitted torque) / J. Measured in the simulator from rest (a 4 rad/s step,
    the loop saturated between 0.5 and 2 rad/s): the nominal spin-up gives the torque the
    tire passes, and that one number predicts the spin-up with the rotor twice as heavy and
    with the limit cut to ``rotor_floor`` (within 5 %). The floor itself takes the tire's
    most (mu_x F_z r): the smallest cut that reads as that rotor."""
    from dataclasses import replace

    import mujoco
    import numpy as np

    from rover_env.calibration.diagnosis.rotor import rotor_floor, traction_torque
    from rover_env.config import RoverConfig
    from rover_env.sim.simulator import RoverSim

    cfg = RoverConfig()
    assert traction_torque(cfg) == pytest.approx(0.4 * cfg.masses.total * 9.81 / 6 * 0.085)
    floor = rotor_floor(cfg, 2.0)
    limit, tf = cfg.motor.torque_limit, traction_torque(cfg)
    assert limit * (1 + floor) - tf == pytest.approx((limit - tf) / 2.0)
    assert rotor_floor(cfg, 1.0) == 0.0
    assert rotor_floor(replace(cfg, motor=replace(cfg.motor, torque_limit=0.8 * tf)), 2.0) == 0.0

    def spin_up(c: RoverConfig) -> tuple[float, float]:
        sim = RoverSim(c)
        sim.reset()
        sim.step(round(0.5 / sim.dt))
        sim.set_speed_targets(np.full(4, 4.0))
        t, w, phi = [], [], sim.sensors().phi[:4].copy()
        for k in range(1, 200):
            sim.step(1)
            now = sim.sensors().phi[:4].copy()
            t.append(k * sim.dt)
            w.append(float(np.mean(now - phi)) / sim.dt)
            phi = now
        tt, ww = np.array(t), np.array(w)
        band = (ww > 0.5) & (ww < 2.0) & (tt < tt[np.argmax(ww > 2.0)])
        body = sim.model.jnt_bodyid[
            mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_JOINT, "wheel_1L")
        ]
        return float(np.polyfit(tt[band], ww[band], 1)[0]), float(sim.model.body_inertia[body][1])

    a0 = cfg.motor.armature
    nominal, iw = spin_up(cfg)
    passed = limit - nominal * (a0 + iw)  # the torque the tire passes while the wheel spins up
    assert 0.0 < passed <= tf
    heavy, _ = spin_up(replace(cfg, motor=replace(cfg.motor, armature=2 * a0)))
    cut, _ = spin_up(replace(cfg, motor=replace(cfg.motor, torque_limit=limit * (1 + floor))))
    assert heavy == pytest.approx((limit - passed) / (2 * a0 + iw), rel=0.05)
    assert cut == pytest.approx((limit * (1 + floor) - passed) / (a0 + iw), rel=0.05)
    assert cut < 0.65 * nominal  # the cut is far from the nominal rotor, near the heavy one


def test_beside_a_named_effect_a_candidate_is_judged_by_what_it_adds(monkeypatch) -> None:
    """Stop 129: with an effect named, each candidate is refitted beside it
    (``beside``); one that adds nothing there (training dBIC >= 0) asks for no drive though
    its fit alone led the held-out drive, and the drive proposed for one that still leads is
    simulated on the named model with the candidate's own effect only."""
    import numpy as np

    from rover_env.calibration import evidence, fit
    from rover_env.calibration.candidates import catalogue
    from rover_env.calibration.diagnosis.evidence_stage import Asking, missing_evidence
    from rover_env.calibration.diagnosis.state import Options, Scored
    from rover_env.config import RoverConfig

    cand = {c.name: c for c in catalogue()}
    changes: list[tuple] = []

    def change(ev, a, b, which, noise):
        changes.append((a, b))
        return {"wheel_2R": 5.0}

    proposed: list[tuple] = []

    def propose(base, name, ext, noise, held, **kw):
        proposed.append((base.extensions, ext))
        return {"effect": name, "plan": "accel", "best_signal": "wheel_2R",
                "best_per_window": 3.0, "best_floor_units": 9.0,
                "held_out_best_signal": "wheel_2R", "held_out_floor_units": 5.0}  # fmt: skip

    monkeypatch.setattr(fit, "signal_change", change)
    monkeypatch.setattr(evidence, "propose", propose)
    slope_ext = {"slope": {"deg": 0.8, "heading_deg": 30.0}}
    torque_ext = {"torque_limit": {"fraction": -0.5}}

    def scored(name: str, ext: dict, gain: float, d_bic: float) -> Scored:
        f = fit.Fit(
            [cand[name]], np.array([-0.5]), np.array([-0.55]), np.array([-0.45]),
            np.array([0.02]), 1.0, 3, ext, 0.0, "train",
        )  # fmt: skip
        return Scored(f, 1.0, np.ones(16), gain, 0.05, d_bic, d_bic, 32)

    named = scored("slope", slope_ext, 0.5, -40.0)
    alone = scored("torque_limit", torque_ext, 0.3, -12.0)  # leans: 30 % better, p 0.05
    opts = Options(progress=False)
    ev = SimpleNamespace(settings=ReplaySettings())
    lines: list[str] = []

    def asked(beside) -> list[str]:
        got = missing_evidence(
            ev, [alone], [named], {}, RoverConfig(), opts, lines.append, ctx=Asking(beside=beside)
        )  # type: ignore[arg-type]
        return [e["effect"] for e in got]

    # Fitted alone it asks (the code before stop 129, and no effect named).
    assert asked(None) == ["torque_limit"]
    # Beside the slope it adds nothing: no drive, and the line says why.
    assert asked(lambda s: scored("torque_limit", {**slope_ext, **torque_ext}, 0.0, 1.5)) == []
    assert "adds nothing beside slope (dBIC +1.5)" in lines[-1]
    # Beside the slope it still leads: asked, judged against the named model.
    changes.clear()
    proposed.clear()
    both = {**slope_ext, **torque_ext}
    assert asked(lambda s: scored("torque_limit", both, 0.3, -9.0)) == ["torque_limit"]
    assert changes[0] == (both, slope_ext)
    assert proposed == [(slope_ext, torque_ext)]


def test_a_candidate_its_own_held_out_drive_judged_is_not_asked_again(monkeypatch) -> None:
    """Stop 129: where the held-out drive is a draw of the candidate's deciding plan, strong
    training evidence with that drive only a few per cent better asks for no other draw
    (spent case 54412's numbers, there with the draw among the training drives); a lean of
    the window test's margin
    still asks for the next draw; so does the same fit where the draw is a training drive."""
    import numpy as np

    from rover_env.calibration import evidence, fit
    from rover_env.calibration.candidates import catalogue
    from rover_env.calibration.diagnosis.evidence_stage import Asking, missing_evidence
    from rover_env.calibration.diagnosis.state import Options, Scored
    from rover_env.calibration.report import judged_lines
    from rover_env.config import RoverConfig

    (c,) = catalogue(["torque_limit"])
    _fake_drives(monkeypatch, fit, evidence, "accel")

    def scored(gain: float, p: float) -> Scored:
        f = fit.Fit(
            [c], np.array([-0.5]), np.array([-0.55]), np.array([-0.45]), np.array([0.02]),
            1.0, 3, {"torque_limit": {"fraction": -0.5}}, 0.0, "train",
        )  # fmt: skip
        return Scored(f, 1.0, np.ones(16), gain, p, -19.4, -19.4, 32)

    held = {"accel": [{"seed": 0, "log": "drive_04.csv"}]}
    ev = SimpleNamespace(settings=ReplaySettings())
    opts = Options(progress=False)

    def run(s: Scored, held_out: str, allowance=None) -> tuple[list[dict], list[dict], list[str]]:
        ctx = Asking(held=held, held_out=("drive_02.csv", held_out), allowance=allowance)
        lines: list[str] = []
        got = missing_evidence(ev, [s], [], {}, RoverConfig(), opts, lines.append, ctx=ctx)  # type: ignore[arg-type]
        return got, ctx.judged, lines

    # 54412's numbers: dBIC -19.4, the held-out accel draw 3.3 % better at p 0.7.
    got, judged, lines = run(scored(0.033, 0.7), "drive_04.csv")
    assert got == [] and judged[0]["log"] == "drive_04.csv" and judged[0]["seed"] == 0
    assert "not asked again" in lines[-1]
    text = "\n".join(judged_lines(judged))
    assert "`accel` seed 0, drive_04.csv" in text and "3.3 % better" in text
    assert "drive (`accel` or another) could make it nameable" in "\n".join(
        judged_lines([{"effect": "torque_limit", "plan": "accel", "why": "allowance",
                       "edge": 0.62, "fit": "fraction=-0.5"}])
    )  # fmt: skip
    assert "cut beyond 30 %" in "\n".join(
        judged_lines([{"effect": "torque_limit", "plan": "accel", "why": "untested_allowance",
                       "edge": 0.62, "threshold": 0.3}])
    )  # fmt: skip
    # A lean of 22 % at p 0.16: more of the same drive could confirm it; its next draw.
    got, judged, _ = run(scored(0.22, 0.16), "drive_04.csv")
    assert [(e["effect"], e["seed"]) for e in got] == [("torque_limit", 1)] and judged == []
    # The draw among the training drives, another drive held out: asked as before.
    got, judged, _ = run(scored(0.033, 0.7), "drive_05.csv")
    assert [(e["effect"], e["seed"]) for e in got] == [("torque_limit", 1)] and judged == []
    # Its whole interval [-0.55, -0.45] within the allowance's 62 %: no drive could make it
    # nameable; one of 50 % leaves room beyond, and is asked.
    for edge, want in ((0.62, []), (0.50, [("torque_limit", 1)])):
        allow = SimpleNamespace(edge=lambda effect, side, e=edge: e if side == "-" else 0.1)
        got, judged, lines = run(scored(0.22, 0.16), "drive_05.csv", allow)
        assert [(e["effect"], e["seed"]) for e in got] == want
        assert [j["why"] for j in judged] == (["allowance"] if not want else [])
        assert ("within the clean-fit allowance (0.62)" in lines[0]) == (not want)


def test_a_candidate_still_unconfirmed_after_max_draws_asks_for_no_other(monkeypatch) -> None:
    """Stop 130: a lean short of alpha asks for the next draw of its plan only while the logs
    hold fewer than ``Options.max_draws`` draws of it (clean case 54509 asked for seeds 0, 1
    and 2 of ``steps``); the report says so, and 0 lifts the cap."""
    import numpy as np

    from rover_env.calibration import evidence, fit
    from rover_env.calibration.candidates import catalogue
    from rover_env.calibration.diagnosis.evidence_stage import Asking, missing_evidence
    from rover_env.calibration.diagnosis.state import Options, Scored
    from rover_env.calibration.report import judged_lines
    from rover_env.config import RoverConfig

    (c,) = catalogue(["command_delay"])
    _fake_drives(monkeypatch, fit, evidence, "steps")
    f = fit.Fit(
        [c], np.array([0.034]), np.array([0.028]), np.array([0.041]), np.array([0.003]),
        1.0, 3, {"command_delay": {"delay": 0.034}}, 0.0, "train",
    )  # fmt: skip
    lean = Scored(f, 1.0, np.ones(16), 0.33, 0.03, -12.0, -12.0, 32)  # 54509's lean
    ev = SimpleNamespace(settings=ReplaySettings())
    two = {"steps": [{"seed": 0, "log": "drive_03.csv"}, {"seed": 1, "log": "drive_05.csv"}]}
    for held, cap, want in ((two, 2, []), (two, 0, [2]), (two, 3, [2]), ({"steps": two["steps"][:1]}, 2, [1])):  # fmt: skip
        ctx = Asking(held=held, held_out=("drive_05.csv",), max_draws=cap)
        lines: list[str] = []
        got = missing_evidence(
            ev,
            [lean],
            [],
            {},
            RoverConfig(),
            Options(progress=False),
            lines.append,
            ctx=ctx,  # type: ignore[arg-type]
        )
        assert [e["seed"] for e in got] == want
        assert [j["why"] for j in ctx.judged] == ([] if want else ["draws"])
    text = "\n".join(judged_lines([{"effect": "command_delay", "plan": "steps", "why": "draws",
                                    "draws": 2, "gain": 0.33, "p": 0.03}]))  # fmt: skip
    assert "holds 2 draws" not in text and "hold 2 draws of its deciding plan (`steps`)" in text
    assert "33.0 % better" in text and "p 0.03" in text
