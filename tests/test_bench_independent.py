"""The plan of issue 47's matrix on the independent generator (benchmarks/bench_independent.py):
what it draws and how the truth is stated in the catalogue's terms. No diagnosis runs here."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
import yaml
from _bench import load_bench

from rover_env.calibration.drive_plan import Proposal
from rover_env.effects import CATALOGUE, effect_class
from rover_env.independent import effects as ind_effects

_load = load_bench


@pytest.fixture(scope="module")
def b() -> ModuleType:
    _load("bench_diagnose")
    return _load("bench_independent")


@pytest.fixture(scope="module")
def plan() -> ModuleType:
    _load("bench_diagnose")
    return _load("_independent_plan")


@pytest.fixture(scope="module")
def tables() -> ModuleType:
    return _load("_independent_tables")


def test_the_plan_is_deterministic_and_its_seeds_are_its_own(
    b: ModuleType, plan: ModuleType
) -> None:
    a = json.dumps(b.cases(), sort_keys=True)
    assert a == json.dumps(b.cases(), sort_keys=True)
    assert a != json.dumps(b.cases(False, b.SEED0 + 1000), sort_keys=True)
    seeds = [c["seed"] for c in b.cases()]
    assert len(set(seeds)) == len(seeds) and min(seeds) == b.SEED0 == 47500 != plan.DEV_SEED0
    planned = b.planned(False)
    assert sorted(map(b.tag, planned)) == sorted(map(b.tag, b.cases()))  # all, once
    assert [b.tag(c) for c in planned[:5]] == [b.tag(c) for c in b.cases(True)]


def test_a_plan_stopped_early_has_every_clean_pair_and_outside_case(b: ModuleType) -> None:
    """Blocks stop at a registered time: the first 45 planned cases must complete the clean,
    pair and outside lines, and hold every effect's singles at least twice."""
    planned = b.planned(False, 52900)
    head = planned[:45]
    kinds = [c["kind"] for c in head]
    assert (kinds.count("clean"), kinds.count("pair"), kinds.count("outside")) == (10, 6, 4)
    singles = [next(iter(c["effects"])) for c in head if c["kind"] == "single"]
    assert min(singles.count(e) for e in b.EFFECTS) >= 2
    tail = [c["kind"] for c in planned[45:]]
    assert set(tail) == {"single"} and len(tail) == 20


def test_the_plan_has_every_kind_and_every_implemented_effect(
    b: ModuleType, plan: ModuleType
) -> None:
    cs = b.cases()
    kinds = [c["kind"] for c in cs]
    assert kinds.count("clean") == 10 and kinds.count("pair") == 6
    assert kinds.count("outside") == 4 and kinds.count("single") >= 40
    implemented = {n for n in ind_effects.MAIN if n in CATALOGUE}
    assert set(b.EFFECTS) == implemented and len(implemented) == 9
    singles = [next(iter(c["effects"])) for c in cs if c["kind"] == "single"]
    assert set(singles) == implemented
    outside = {next(iter(c["effects"])) for c in cs if c["kind"] == "outside"}
    assert outside == set(ind_effects.OUTSIDE) and not outside & set(CATALOGUE)
    sand = [
        c["effects"]["loose_soil"]["sand"]
        for c in cs
        if c["kind"] == "single" and "loose_soil" in c["effects"]
    ]
    assert 0 < sum(sand) < len(sand)  # some on dry sand, the rest on regolith
    for c in cs:
        if c["kind"] == "clean":
            assert c["effects"] == {} and c["truth"] == "none"
        if c["kind"] == "pair":
            names = set(c["effects"])
            assert len(names) == 2 and names <= implemented
            assert not ("loose_soil" in names and names & plan.INERT_ON_SOIL), c


def test_strong_pairs_draw_from_the_named_effects_then_singles_in_turn(
    b: ModuleType, plan: ModuleType
) -> None:
    timing = ["command_lag", "command_delay"]
    todo = b.strong_pairs(72900, 4, timing, 3)
    assert [c["kind"] for c in todo] == ["pair"] * 4 + ["single"] * 3
    assert all(set(c["effects"]) == set(timing) for c in todo[:4])
    assert [next(iter(c["effects"])) for c in todo[4:]] == [*timing, timing[0]]
    assert [c["seed"] for c in todo] == list(range(72900, 72907))
    for c in todo:
        for e, p in c["effects"].items():
            param, lo, hi, _ = plan.STRONG[e]
            assert lo <= abs(p[param]) <= hi
    assert todo[:4] == b.strong_pairs(72900, 4, timing)  # singles after, pairs unchanged
    with pytest.raises(ValueError, match="friction"):
        b.strong_pairs(72900, 1, ["command_lag", "friction"])
    soils = b.strong_pairs(53000, 0, ["loose_soil"], 3)  # singles of one effect: no pairs
    assert [(c["kind"], next(iter(c["effects"])), c["seed"]) for c in soils] == [
        ("single", "loose_soil", s) for s in (53000, 53001, 53002)
    ]
    with pytest.raises(ValueError, match="two or more"):
        b.strong_pairs(53000, 1, ["loose_soil"])


def test_the_pairs_never_drawn_are_the_effects_diagnose_does_not_try_beside_soil(
    b: ModuleType, plan: ModuleType
) -> None:
    from rover_env.calibration.candidates import REPLACED_BY_SOIL

    assert plan.INERT_ON_SOIL == REPLACED_BY_SOIL  # the tire's effects, in both generators


def test_effort_cases_are_cuts_clean_builds_and_others_in_turn(
    b: ModuleType, plan: ModuleType
) -> None:
    todo = b.effort_cases(52700, 12)
    kinds = [("clean" if c["kind"] == "clean" else next(iter(c["effects"]))) for c in todo]
    others = [k for i, k in enumerate(kinds) if i % 4 == 3]
    assert kinds[::4] == kinds[1::4] == ["torque_limit"] * 3
    assert kinds[2::4] == ["clean"] * 3
    assert others == list(plan.EFFORT_OTHERS[:3])
    assert [c["seed"] for c in todo] == list(range(52700, 52712))
    for c in todo:
        ind_effects.resolve(c["effects"])  # the generator accepts them
        if "torque_limit" in c["effects"]:
            assert -0.78 <= c["effects"]["torque_limit"]["fraction"] <= -0.05


def test_balance_cases_are_slopes_clean_builds_and_loads_in_turn(plan: ModuleType) -> None:
    todo = plan.balance_cases(53400, 8)
    assert [c["seed"] for c in todo] == list(range(53400, 53408))
    kinds = [next(iter(c["effects"]), "clean") for c in todo]
    first, second = ["slope", "clean", "slope"], ["rolling_resistance", "loose_soil"]
    assert kinds == [*first, second[0], *first, second[1]]
    lo, hi = plan.BALANCE_SLOPE
    for c in todo:
        if "slope" in c["effects"]:
            assert lo <= c["effects"]["slope"]["deg"] <= hi
            assert c["truth"]["slope"]["deg"] == c["effects"]["slope"]["deg"]
    assert todo == plan.balance_cases(53400, 8)  # by seed
    others = ("command_lag", "friction", "payload")
    todo = plan.balance_cases(53400, 12, others)
    assert [next(iter(c["effects"]), "clean") for c in todo][3::4] == list(others)
    with pytest.raises(ValueError, match="unknown effects"):
        plan.balance_cases(53400, 4, ("slope",))
    with pytest.raises(ValueError, match="unknown effects"):
        plan.balance_cases(53400, 4, ("gremlins",))


def test_magnitudes_lie_in_their_ranges_in_both_parameterisations(
    b: ModuleType, plan: ModuleType
) -> None:
    for c in b.cases():
        ind_effects.resolve(c["effects"])  # the generator accepts them
        for name, params in c["effects"].items():
            if name in plan.OUTSIDE_RANGES:
                param, lo, hi = plan.OUTSIDE_RANGES[name]
                signs: tuple[int, ...] = (1,)
            else:
                param, lo, hi, signs = {**b.RANGES, **plan.OWN_RANGES}[name]
            v = params[param]
            assert lo * (1 - 1e-4) <= abs(v) <= hi * (1 + 1e-4), (c["seed"], name, v)
            assert int(math.copysign(1, v)) in signs
            if name == "torque_limit":
                assert -0.8 <= v <= -0.05  # only lowered limits
            if name == "brake_drag":
                assert params["wheel"] in (4.0, 5.0)  # a free wheel
        if isinstance(c["truth"], dict):
            for name, params in c["truth"].items():
                effect_class(name)(params)  # inside the catalogue's bounds


def test_truth_mapping_for_loose_soil_torque_limit_and_rolling_radius(
    b: ModuleType, plan: ModuleType
) -> None:
    """As the module docstring states: k_phi = preset k_phi x factor (regolith 8.14e5, dry
    sand 1.52843e6); torque limit (1 + f) 2.8 / 3.0 - 1 (2.8 N m = 0.7 x 100 x 0.02 x 2 A at
    the wheel here, 3.0 N m in the model); rolling radius f x 0.0761 / 0.085."""
    soil = plan.catalogue_truth("loose_soil", {"k_phi": 1.5, "sand": 0.0})
    assert soil == {"k_phi": pytest.approx(1.5 * 8.14e5)}
    sand = plan.catalogue_truth("loose_soil", {"k_phi": 0.5, "sand": 1.0})
    assert sand == {"k_phi": pytest.approx(0.5 * 1528.43e3)}
    assert plan.catalogue_truth("torque_limit", {"fraction": -0.5}) == {
        "fraction": pytest.approx(0.5 * 2.8 / 3.0 - 1.0)
    }
    assert plan.catalogue_truth("torque_limit", {"fraction": -0.05})["fraction"] == pytest.approx(
        -0.11333, abs=1e-5
    )
    r_e = 0.085 - 16.41 * 9.81 / 6 / 1000.0 / 3
    assert plan.catalogue_truth("rolling_radius", {"fraction": -0.1}) == {
        "fraction": pytest.approx(-0.1 * r_e / 0.085)
    }
    for name in ("friction", "command_delay", "rolling_resistance"):
        p = plan.generator_params(name, 5)
        assert plan.catalogue_truth(name, p) == p
    slope = plan.generator_params("slope", 5)
    assert plan.catalogue_truth("slope", slope) == slope and set(slope) == {"deg", "heading_deg"}
    for c in b.cases():  # every case's truth column is the mapping of its drawn parameters
        if isinstance(c["truth"], dict):
            assert c["truth"] == {n: plan.catalogue_truth(n, p) for n, p in c["effects"].items()}


def test_load_dependent_friction_maps_to_the_same_slope_of_mu_over_load(
    b: ModuleType, plan: ModuleType
) -> None:
    """Numerically: the catalogue's mu(F_z) with the mapped fall has the generator's relative
    slope at the static load; the generator's level there is the recorded friction change."""
    fall = 0.3
    cat = plan.catalogue_truth("load_dependent_friction", {"fall": fall})["fall"]
    f0, h = plan.F0_IND, 1e-3
    ind = lambda f: 1 - fall * math.tanh(f / 60.0)  # noqa: E731
    cat_mu = lambda f: 1 - cat * (f - f0) / (2 * 0.1 * f0)  # noqa: E731
    slope_ind = (ind(f0 + h) - ind(f0 - h)) / (2 * h) / ind(f0)
    slope_cat = (cat_mu(f0 + h) - cat_mu(f0 - h)) / (2 * h)
    assert slope_cat == pytest.approx(slope_ind, rel=1e-6)
    ldf = [c for c in b.cases() if "load_dependent_friction" in c["effects"]]
    assert ldf
    for c in ldf:
        a = c["effects"]["load_dependent_friction"]["fall"]
        level = 1 - a * math.tanh(f0 / 60.0)
        assert c["equivalent"]["friction"]["fraction"] == pytest.approx(level - 1)


def test_a_proposal_becomes_the_rows_drive_plan_writes(b: ModuleType) -> None:
    from rover_env.calibration.drive_plan import command_rows

    prop = Proposal("accel", 0, 20.0)
    s = b.schedule(prop)
    t, cmd, _ = command_rows("accel", 0, 20.0, 4.0, 50.0)
    assert np.array_equal(s.t, t) and np.array_equal(s.cmd, cmd)
    assert s.duration == 20.0 and np.abs(s.cmd).max() <= 4.0 and not s.cmd[-1].any()
    assert np.array_equal(s.at(np.array([0.0, 0.02, 19.99])), cmd[[0, 1, -2]])


@pytest.mark.parametrize("untested", [False, True])
def test_run_case_drives_every_proposal_with_the_same_rover(
    b: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, untested: bool
) -> None:
    """The case's plumbing, with a stand-in for diagnose (the matrix runs the real one): the
    first report proposes a tie's drive and an evidence drive; both are driven by the same
    build (truth.yaml's nuisance) as drives 3 and 4 of 1 s logs, the second diagnosis gets all
    five logs, and the row carries its named effects and the fit against the truth. The
    untested-limit drive is recorded, and driven only with ``untested``: twice, last (drives 5
    and 6, seven logs), so one is a training drive."""
    calls: list[list[str]] = []

    def fake(paths: list[str], out: Path, opts: object) -> dict[str, object]:
        calls.append(paths)
        second = len(calls) == 2
        fit = {"params": {"torque_limit": {"fraction": [-0.4, -0.45, -0.35]}}}
        res = {
            "named": ["torque_limit"] if second else [],
            "tie": None
            if second
            else {
                "effects": ["torque_limit", "friction"],
                "plan": "accel",
                "seed": 0,
                "duration": 1.0,
                "why": "x",
            },
            "evidence": []
            if second
            else [
                {
                    "effect": "slope",
                    "plan": "reversals",
                    "seed": 0,
                    "duration": 1.0,
                    "why": "y",
                    "separates": True,
                }
            ],
            # recorded; driven only with untested=True (--untested)
            "untested": []
            if second
            else [
                {"effect": "torque_limit", "plan": "steps", "seed": 0, "duration": 1.0, "why": "z"}
            ],
            "main_signal": "wheel_1L",
            "main_reduction": 0.5,
            "unexplained": [] if second else ["wheel_1L"],
            "fits": {"torque_limit": {**fit, "threshold": {"-": 0.05}}},
            "final": {"torque_limit": fit} if second else {},
        }
        Path(out).mkdir(parents=True)
        (Path(out) / "result.json").write_text(json.dumps(res))
        return res

    monkeypatch.setattr(b, "diagnose", fake)
    monkeypatch.setattr(b, "DURATION", 1.0)
    case = next(c for c in b.cases() if c["kind"] == "single" and "torque_limit" in c["effects"])
    row = b.run_case(case, tmp_path, untested=untested)
    plans = ["accel", "reversals", *(["steps", "steps"] if untested else [])]
    assert [len(c) for c in calls] == [3, 3 + len(plans)]
    assert [Path(p).name for p in calls[1][3:]] == [
        f"drive_0{3 + j}.csv" for j in range(len(plans))
    ]
    d = tmp_path / b.tag(case)
    builds = [
        json.dumps(yaml.safe_load((d / f).read_text())["nuisance"])
        for f in ("logs/truth.yaml", *(f"followup_{j}/truth.yaml" for j in range(len(plans))))
    ]
    assert len(set(builds)) == 1 and len(builds) == 1 + len(plans)
    assert [p["plan"] for p in row["followup"]] == plans
    assert row["untested_driven"] is untested
    assert [u["plan"] for u in row["untested"]] == ["steps"]
    assert (
        row["named"] == ["torque_limit"]
        and row["first_named"] == []
        and row["gen"] == "independent"
    )
    f = row["fits"]["torque_limit"]
    assert (f["value"], f["threshold"]) == (-0.4, 0.05) and f["truth"] == case["truth"][
        "torque_limit"
    ]["fraction"]


def test_the_registered_rotor_rule_reads_the_stored_comparison() -> None:
    """Stop 57's rule is scored from ``result.json`` alone: withdrawn when the rotor's
    training dBIC is at or below the torque limit's; no verdict where none was named."""
    b = _load("_rules")

    def row(kind: str, named: list[str], rotor: float, torque: float) -> dict:
        alt = {"rotor": {"d_bic": rotor}, "torque_limit": {"d_bic": torque}}
        return {"kind": kind, "named": named, "truth": {}, "rotor_alternative": alt}

    assert b.rotor_rule(row("clean", ["torque_limit"], -3.0, -1.0)) is True
    assert b.rotor_rule(row("clean", ["torque_limit"], -1.0, -1.0)) is True
    assert b.rotor_rule(row("clean", ["torque_limit"], -0.2, -1.2)) is False
    assert b.rotor_rule(row("clean", ["slope"], -3.0, -1.0)) is None
    line = b.rotor_line([row("clean", ["torque_limit"], -3.0, -1.0), row("clean", [], 0, 0)])
    assert "clean 1 of 1 named" in line


def test_the_rotor_test_line_counts_withdrawals_against_the_truth() -> None:
    """Stop 62's applied rotor test, scored from the rows: withdrawn on the first or the
    final diagnosis, true cuts and clean cases told apart; rows of older code not counted."""
    b = _load("_rules")
    w = {"effects": ["torque_limit"], "p_torque_better": 0.4, "armature": 0.05}
    rows = [
        {"kind": "clean", "named": [], "truth": {}, "rotor_withdrawn": [w, None]},
        {"kind": "single", "named": [], "truth": {"slope": {}}, "rotor_withdrawn": [None, w]},
        {
            "kind": "single",
            "named": ["torque_limit"],
            "truth": {"torque_limit": {"fraction": -0.5}},
            "rotor_withdrawn": [None, None],
        },
        {"kind": "single", "named": ["torque_limit"], "truth": {}},  # older code
        {
            "kind": "single",
            "named": ["loose_soil"],
            "truth": {"loose_soil": {"k_phi": 5e5}},
            "rotor_withdrawn": [None, {**w, "kept": "loose_soil"}],
        },
    ]
    line = b.rotor_test_line(rows)
    assert "in 4 cases that stored it" in line
    assert "withdrawn in 3 (true torque cuts 0; clean or outside 1)" in line
    assert "its partner named alone (stop 63) in 1 (1 the truth)" in line
    assert "named in the end in 1 (true torque cuts 1; clean or outside 0)" in line


def test_named_effects_keep_their_fits_for_the_false_alarm_tables(tmp_path: Path) -> None:
    """A named effect that is not the truth (a clean case's false alarm) is listed with its
    fitted value and interval, from the row or, for older rows, the case's result.json."""
    b = _load("bench_independent")
    cells = _load("_cells")
    final = {
        "final": {
            "rolling_resistance + slope": {
                "params": {
                    "rolling_resistance": {"c_rr": [0.013, 0.01, 0.016]},
                    "slope": {"deg": [1.5, 1.2, 1.8], "heading_deg": [30.0, 20.0, 40.0]},
                }
            }
        }
    }
    got = b.named_fits(final)
    assert got["rolling_resistance"] == {"c_rr": [0.013, 0.01, 0.016]}
    assert set(got["slope"]) == {"deg", "heading_deg"}
    old = {"case": "clean_none_1", "named": ["rolling_resistance", "slope"]}
    skip = {"case": "clean_none_2", "named": []}
    gone = {"case": "clean_none_3", "named": ["slope"]}
    (tmp_path / "clean_none_1" / "out").mkdir(parents=True)
    (tmp_path / "clean_none_1" / "out" / "result.json").write_text(json.dumps(final))
    b.backfill([old, skip, gone], tmp_path)
    assert old["named_fits"] == got
    assert "named_fits" not in skip and "named_fits" not in gone
    text = cells.named_cell(old)
    assert "rolling_resistance (c_rr 0.013 [0.01, 0.016])" in text
    assert cells.named_cell(gone) == "slope" and cells.named_cell(skip) == "—"


def test_the_registered_evidence_rule_reads_the_first_diagnosis() -> None:
    """Stop 58's rule: a candidate with strong training evidence (ΔBIC <= -6) that the
    held-out drive favours without confirming, not named and without a drive, gets one."""
    r = _load("_rules")

    def fit(d_bic: float, gain: float, significant: bool = False) -> dict:
        return {"d_bic": d_bic, "held_gain": gain, "significant": significant}

    first = {
        "named": ["slope"],
        "evidence": [{"effect": "command_lag"}],
        "fits": {
            "torque_limit": fit(-6.7, 0.085),
            "slope": fit(-20.0, 0.5, True),
            "command_lag": fit(-9.0, 0.05),
            "friction": fit(-5.9, 0.2),
            "rolling_radius": fit(-8.0, -0.01),
        },
    }
    assert r.strong_unconfirmed(first) == ["torque_limit"]
    rows = [
        {"kind": "single", "truth": {"torque_limit": {}}, "strong_unconfirmed": ["torque_limit"]},
        {"kind": "clean", "truth": "none", "strong_unconfirmed": ["friction"]},
        {"kind": "clean", "truth": "none", "strong_unconfirmed": []},
        {"kind": "clean", "truth": "none"},
    ]
    line = r.evidence_line(rows)
    assert "in 2 of 3 cases" in line and "among them in 1" in line and "clean cases 1" in line


def test_the_torque_line_splits_reached_limits_from_unreached_ones(
    b: ModuleType, tables: ModuleType
) -> None:
    """Issue 47's torque line: a cut at or beyond its threshold must be named with a covering
    interval; one below it needs a torque drive proposed (evidence or untested), not just
    any follow-up."""

    def row(truth: float, thr: float, named: bool, asked: str = "", followup: bool = False) -> dict:
        fit = {"truth": truth, "value": truth, "lo": truth - 0.05, "hi": truth + 0.05}
        return {
            "kind": "single", "effects": {"torque_limit": {}}, "truth": {"torque_limit": {}}, "named": ["torque_limit"] * named,
            "first_named": [], "fits": {"torque_limit": fit | {"threshold": thr}},
            "followup": [{"plan": "reversals"}] * followup, "unexplained": [],
            "evidence": [{"effect": "slope"}],
            "untested": [{"effect": asked}] if asked else [],
            "make_logs_s": 1.0, "diagnose_s": 1.0, "followup_s": 0.0,
        }  # fmt: skip

    rows = [
        row(-0.6, 0.2, True),  # reached, named, covering
        row(-0.6, 0.2, False, "torque_limit"),  # reached, not named: a drive does not excuse it
        row(-0.1, 0.4, False, "torque_limit"),  # not reached, the drive proposed
        row(-0.1, 0.4, False, "", followup=True),  # not reached, only another effect's drive
    ]
    (line,) = [x for x in tables.acceptance(rows) if x.startswith("- Torque")]
    assert "reached (cut ≥ its threshold): named covering 1/2" in line
    assert "not reached: a torque drive proposed 1/2" in line


def test_the_named_from_line_counts_only_truths_twice_the_bar(tables: ModuleType) -> None:
    """Stop 95: the acceptance line against the report's "named from" counts a single whose
    truth is at least twice the bar on its side; rows without a bar (stored before it) and
    truths under twice it are left out, and the effect table shows the bar."""

    def row(truth: float, bar: float | None, named: bool) -> dict:
        fit = {"truth": truth, "value": truth, "lo": truth - 0.01, "hi": truth + 0.01}
        return {
            "kind": "single", "seed": 1, "effects": {"command_lag": {"tau": truth}},
            "truth": {"command_lag": {"tau": truth}}, "named": ["command_lag"] * named,
            "first_named": [], "fits": {"command_lag": fit | {"threshold": 0.002, "nameable": bar}},
            "followup": [], "unexplained": [], "make_logs_s": 1.0, "diagnose_s": 1.0, "followup_s": 0.0,
        }  # fmt: skip

    rows = [
        row(0.2, 0.05, True),
        row(0.11, 0.05, False),
        row(0.09, 0.05, False),
        row(0.3, None, False),
    ]
    (line,) = [x for x in tables.acceptance(rows) if "named from" in x]
    assert line.endswith("named right 1/2 (50 %)"), line
    table = "\n".join(tables._effect_table(rows, "command_lag"))
    assert "| 0.05 |" in table and "named from" in table


def test_the_trade_line_counts_refused_and_excused_namings() -> None:
    """Stop 61's trade share is scored from ``result.json``: a refused naming (``not_named``)
    and an excused one (``trade_excused``), each against the case's truth."""
    r = _load("_rules")
    worse = {"theta_4": {"rms_ratio": 1.15, "p": 0.006, "windows": 16, "share": 0.0007}}
    lag = r.trades({"trade_excused": {"effects": "command_lag", "worse": worse}})
    assert lag["refused"] is None and lag["excused"]["worse"]["theta_4"]["share"] == 0.0007
    soil = r.trades({"not_named": {"effects": ["loose_soil", "command_delay"], "worse": worse}})
    rows = [
        {"kind": "single", "truth": {"command_lag": {}}, "trades": lag},
        {"kind": "single", "truth": {"loose_soil": {}}, "trades": soil},
        {"kind": "clean", "truth": {}, "trades": lag},
        {"kind": "clean", "truth": {}},
    ]
    line = r.trade_line(rows)
    assert "in 3 cases that stored it" in line
    assert "refused in 1 (the truth among its effects in 1; clean or outside 0)" in line
    assert "excused (named) in 2 (the truth among its effects in 1; clean or outside 1)" in line


def test_the_limit_line_counts_what_the_detection_limit_rule_refused(tmp_path: Path) -> None:
    """Stop 73's rule is scored from ``result.json``: a candidate whose test says it is below
    its detection limit, in the first diagnosis or the follow-up, against the case's truth."""
    r = _load("_rules")
    below = "not named: friction 0.244 is below its detection limit 0.261 on these logs"
    first = {"fits": {"friction": {"test": below}, "command_lag": {"test": "windows"}}}
    assert r.below_limit(first) == ["friction"]
    assert r.below_limit({"fits": {"friction": {"test": None}}}) == []
    case = tmp_path / "clean_none_1"
    (case / "out").mkdir(parents=True)
    (case / "out" / "result.json").write_text(json.dumps(first))
    rows = [
        {"case": "clean_none_1", "kind": "clean", "truth": {}, "named": []},
        {"case": "single_friction_2", "kind": "single", "truth": {"friction": {}}, "named": []},
    ]
    r.backfill(rows, tmp_path)  # the first row's files are there, the second's are not
    assert rows[0]["below_limit"] == ["friction"] and "below_limit" not in rows[1]
    rows[1]["below_limit"] = ["friction", "slope"]
    line = r.limit_line(rows)
    assert "in 2 cases that stored it: 3 effects refused in 2 cases" in line
    assert "the case's truth 1, another effect 2" in line


def test_the_odometry_line_counts_radii_named_by_dead_reckoning(tmp_path: Path) -> None:
    """Stop 75's odometry stage is scored from ``result.json``'s ``dead_reckoning``: named
    or not, the truth a radius (its interval holding it) or not."""
    r = _load("_rules")
    diff = {"both": -0.05, "3L": -0.05, "3R": -0.05}
    band = [-0.025, 0.025]
    fraction = [-0.04, -0.06, -0.03]
    named = {
        "dead_reckoning": {"named": True, "difference": diff, "fraction": fraction, "band": band}
    }
    assert r.odometry({"dead_reckoning": None}) is None
    assert r.odometry({"dead_reckoning": {"difference": -0.05}}) is None  # stop 74's form
    soil = r.odometry({"dead_reckoning": {"band": band, "named": False, "why_not": "soil"}})
    assert soil is not None and not soil["named"] and soil["difference"] is None
    case = tmp_path / "single_rolling_radius_1"
    (case / "out").mkdir(parents=True)
    (case / "out" / "result.json").write_text(json.dumps(named))
    rows = [
        {
            "case": "single_rolling_radius_1",
            "kind": "single",
            "truth": {"rolling_radius": {}},
            "named": ["rolling_radius"],
            "fits": {"rolling_radius": {"truth": -0.045}},
        },
        {
            "case": "outside_payload_2",
            "kind": "outside",
            "truth": {},
            "named": ["rolling_radius"],
            "odometry": {"named": True, "difference": -0.03, "fraction": [-0.03, -0.04, -0.01]},
        },
        {"case": "clean_none_3", "kind": "clean", "truth": {}, "named": []},
    ]
    r.backfill(rows, tmp_path)
    assert rows[0]["odometry"]["named"] and "odometry" not in rows[2]
    line = r.odometry_line(rows)
    assert "in 2 cases that stored it: a rolling radius named by dead reckoning in 2" in line
    assert "the truth a radius in 1 (interval holding it 1)" in line
    assert "no radius in the truth 1 (outside_payload_2)" in line
    rows[0]["fits"]["rolling_radius"]["truth"] = -0.08
    assert "(interval holding it 0)" in r.odometry_line(rows)


def test_a_truth_is_measured_against_the_threshold_on_its_side(tables: ModuleType) -> None:
    assert tables.truth_ratio("command_lag", {"truth": 0.2, "threshold": 0.05}) == pytest.approx(
        4.0
    )
    # A cut counts as its size; a slope as its tilt (its fit row's truth is the tilt).
    assert tables.truth_ratio("torque_limit", {"truth": -0.3, "threshold": 0.1}) == pytest.approx(
        3.0
    )
    assert tables.truth_ratio("slope", {"truth": 3.0, "threshold": 1.5}) == pytest.approx(2.0)
    # Loose soil in the variable diagnose fits, 1e6 / k_phi.
    assert tables.truth_ratio("loose_soil", {"truth": 5e5, "threshold": 0.5}) == pytest.approx(4.0)
    f = {"truth": 0.2, "threshold": None, "detectable": 0.1}
    assert tables.truth_ratio("friction", f) is None
    assert tables.truth_ratio("friction", f, "detectable") == pytest.approx(2.0)


def test_the_allowance_line_counts_withdrawn_names_against_the_truth() -> None:
    """Stop 77: each effect the clean-fit allowance withdrew (first diagnosis or follow-up,
    once per case) is the case's truth or another effect; a clean case's truth is a word,
    never a catalogue effect; rows without a withdrawal need nothing else."""
    r = _load("_rules")
    rows = [
        {
            "case": "a",
            "truth": {"command_delay": {"delay": 0.02}},
            "allowance_withdrawn": [
                {"effects": ["command_delay"]},
                {"effects": ["command_delay", "slope"]},
            ],
        },
        {"case": "b", "truth": "none", "allowance_withdrawn": [None, {"effects": ["friction"]}]},
        {"case": "c", "truth": "none", "allowance_withdrawn": [None, None]},
        {"named": []},  # an older row: neither the case nor the field
    ]
    line = r.allowance_line(rows)
    assert "in 3 cases that stored it: 3 names withdrawn in 2 cases" in line, line
    assert "the case's truth 1, another effect 2" in line, line
    assert "pair" not in line, line  # no pair lost one effect here


def test_the_allowance_line_counts_a_pairs_other_effect_kept_or_beside() -> None:
    """Stop 78: when a pair loses one effect, the other is named by its own fit (kept) or
    not named (beside); the line counts each against the truth, final diagnosis only."""
    r = _load("_rules")
    lag = {"command_lag": {"tau": 0.08}}
    rows = [
        {
            "case": "a",
            "truth": lag,
            "allowance_withdrawn": [None, {"effects": ["friction"], "kept": "command_lag"}],
        },
        {
            "case": "b",
            "truth": lag,
            "allowance_withdrawn": [None, {"effects": ["command_lag"], "beside": ["slope"]}],
        },
        {
            "case": "c",
            "truth": "none",
            "allowance_withdrawn": [{"effects": ["slope"], "kept": "friction"}, None],
        },
    ]
    line = r.allowance_line(rows)
    assert "3 names withdrawn in 3 cases" in line, line  # c: its first diagnosis
    assert "a pair's other effect kept 1 (the truth 1), beside 1 (the truth 0)" in line, line


def test_a_missed_strong_single_is_given_its_first_reason() -> None:
    """Stop 79: each single at >= 2 x threshold not named gets the first reason that holds:
    the clean-fit allowance (it withdraws what passed every other rule), then in diagnose's
    order the window test (gain, p, BIC), a tie, another effect; weaker singles and named
    ones are not counted."""
    r = _load("_rules")

    def row(name: str, x: float, test: dict | None, **kw: object) -> dict:
        fit = {"truth": x, "threshold": 1.0, **({"test": test} if test else {})}
        return {"truth": {name: {}}, "fits": {name: fit}, "named": [], **kw}

    def test(sig: bool, gain: float = 0.3, p: float = 0.001, d_bic: float = -5.0) -> dict:
        return {"significant": sig, "held_gain": gain, "p": p, "d_bic": d_bic}

    rows = [
        row("slope", 3.0, test(False, gain=0.05)),
        row("slope", 3.0, test(False, p=0.2)),
        row("slope", 3.0, test(False, d_bic=1.8)),
        row("command_delay", 5.0, test(True), tie=["command_delay", "command_lag"]),
        row("command_delay", 5.0, test(True), named=["command_lag"]),
        row(
            "command_lag", 5.0, test(True), allowance_withdrawn=[None, {"effects": ["command_lag"]}]
        ),
        row("friction", 2.5, test(True)),
        row("friction", 2.5, None),
        row("friction", 1.5, test(False, gain=0.0)),  # under 2 x threshold: not counted
        row("friction", 4.0, test(True), named=["friction"]),  # named: not counted
    ]
    ratio = lambda name, f: f["truth"] / f["threshold"]  # noqa: E731
    line = r.missed_line(rows, ratio)
    for part in (
        "held-out gain under 10% 1",
        "held-out p ≥ 0.01 1",
        "training BIC 1",
        "a tie 1",
        "another effect named 1",
        "the allowance 1",
        "a later rule or a withdrawn winner 1",
        "not stored 1",
    ):
        assert part in line, (part, line)
    assert "none missed" in r.missed_line(rows[-1:], ratio)


def test_a_soil_row_says_where_its_k_phi_was_read(b: ModuleType) -> None:
    """The row's fit carries the diagnosis's ``read_from`` rule (None: the fit itself), the
    value it replaced and, from straight driving, the group read and each group's reading."""
    soil = {"params": {"loose_soil": {"k_phi": [1e6, 5e5, 2e6]}}, "sides": {}}
    read = {
        "rule": "straight",
        "replaced": {"loose_soil": {"k_phi": [3e6, 1e6, 9e6]}},
        "group": "joints",
        "reads": {"joints": 1e6, "pose": 7e6},
    }
    for r, want in ((read, "straight"), (None, None)):
        final = {"final": {"loose_soil": {**soil, "read_from": r}}, "fits": {}}
        row = b.fits(final, {"loose_soil": {"k_phi": 8.14e5}})["loose_soil"]
        assert row["read_from"] == want and row["value"] == 1e6
        assert row.get("replaced") == (3e6 if r else None)
        assert row.get("read_group") == (r and "joints")
        assert row.get("reads") == (r and {"joints": 1e6, "pose": 7e6})
    # read, not moved (the joints had no reading): the rule None, the readings kept
    unmoved = {"rule": None, "group": "joints", "reads": {"joints": None, "pose": 7e6}}
    final = {"final": {"loose_soil": {**soil, "read_from": unmoved}}, "fits": {}}
    row = b.fits(final, {"loose_soil": {"k_phi": 8.14e5}})["loose_soil"]
    assert row["read_from"] is None and row["replaced"] is None
    assert row["reads"] == {"joints": None, "pose": 7e6} and row["value"] == 1e6


def test_the_stage_line_sums_each_case_s_passes_and_counts_the_reruns() -> None:
    """Stop 105's ``stage_seconds``: per stage the median over cases of the seconds summed
    over a case's passes; rows without it (before stop 105) give no line."""
    t = load_bench("_independent_tables")
    one = [{"form": 10.0, "fit": 50.0, "select": 20.0}]
    two = [{"form": 10.0, "fit": 60.0, "again": 5.0}, {"form": 0.0, "fit": 40.0, "select": 30.0}]
    rows = [{"stage_seconds": one}, {"stage_seconds": two}, {"stage_seconds": one}, {}]
    (line,) = t.stage_lines(rows)
    assert "form 10, fit 50, select 20, again 0" in line  # two's fit: 100 s, the median 50
    assert "run again under re-judged forms in 1 of 3" in line
    assert t.stage_lines([{}, {"stage_seconds": None}]) == []


def test_rounds_drive_what_each_diagnosis_asks_until_it_asks_nothing(
    b: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--rounds 3``: the first diagnosis asks for the crossing drive, the second (its
    logs holding that draw) for the plan's next draw, the third for nothing; so two drives
    are driven, each last by file name, and the row records each diagnosis's asks beside
    the draws its logs held."""
    calls: list[list[str]] = []

    def fake(paths: list[str], out: Path, opts: object) -> dict[str, object]:
        calls.append(paths)
        n = len(calls)
        held = {"reversals": [{"seed": s, "log": f"drive_0{3 + s}.csv"} for s in range(n - 1)]}
        bal = {"plan": "reversals", "seed": n - 1, "duration": 1.0, "why_not": "wide"}
        res = {
            "named": [],
            "tie": None,
            "evidence": [],
            "untested": [],
            "balance": bal if n < 3 else {"read": True},
            "plans_held": held if n > 1 else {},
            "evidence_judged": [{"effect": "torque_limit", "why": "allowance"}] if n == 3 else [],
            "main_signal": "wheel_1L",
            "main_reduction": 0.5,
            "unexplained": [],
            "fits": {},
            "final": {},
        }
        Path(out).mkdir(parents=True)
        (Path(out) / "result.json").write_text(json.dumps(res))
        return res

    monkeypatch.setattr(b, "diagnose", fake)
    monkeypatch.setattr(b, "DURATION", 1.0)
    case = next(c for c in b.cases() if c["kind"] == "single")
    row = b.run_case(case, tmp_path, rounds=3)
    assert [len(c) for c in calls] == [3, 4, 5]
    assert [Path(p).name for p in calls[2][3:]] == ["drive_03.csv", "drive_04.csv"]
    asked = [[(a["plan"], a["seed"]) for a in r["asked"]] for r in row["rounds"]]
    assert asked == [[("reversals", 0)], [("reversals", 1)], []]
    assert row["rounds"][1]["plans_held"] == {"reversals": [{"seed": 0, "log": "drive_03.csv"}]}
    judged = [r["judged"] for r in row["rounds"]]  # what each diagnosis judged not worth a drive
    assert judged == [[], [], [{"effect": "torque_limit", "why": "allowance"}]]
    calls.clear()
    b.run_case(case, tmp_path, rounds=1)  # the default: the first diagnosis's asks only
    assert [len(c) for c in calls] == [3, 4]
