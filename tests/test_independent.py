"""The independent (SPEC-only) log generator, issue 47 item 1: reproducibility, physical sanity
of the nominal rover, each effect against the nominal, nuisance tolerances, and independence.

Drives are kept short (0.5 s settling, then 3.5 s logged: 1 s at rest and a 2.5 s step) so the file runs well under a minute.
"""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import yaml

from rover_env.independent import effects, model, motor, nuisance
from rover_env.independent.generate import make_independent_logs
from rover_env.independent.simulate import Truth, simulate
from rover_env.logs import read_log

PKG = Path(__file__).resolve().parents[1] / "rover_env" / "independent"
T = np.round(np.arange(0.0, 3.5 + 1e-9, 0.02), 9)
STEADY = T >= 2.5  # the step starts at 1 s; the speed loops settle within ~0.3 s
W = 2.0  # rad/s, about 0.15 m/s: the paper's pace


def _cmd(left: float, right: float) -> np.ndarray:
    c = np.zeros((T.size, 4))
    c[T >= 1.0] = [left, right, left, right]
    return c


@cache
def _run(
    eff_items: tuple[tuple[str, tuple[tuple[str, float], ...]], ...], left: float, right: float
) -> Truth:
    eff = effects.resolve({k: dict(v) for k, v in eff_items})
    return simulate(model.RoverParams(), eff, T, _cmd(left, right), settle=0.5)


def run(eff: dict[str, dict[str, float]] | None = None, left: float = W, right: float = W) -> Truth:
    items = tuple(sorted((k, tuple(sorted(v.items()))) for k, v in (eff or {}).items()))
    return _run(items, left, right)


def _free_over_driven(tr: Truth) -> float:
    om = tr.omega[STEADY].mean(axis=0)
    return float(om[4:].mean() / om[:4].mean())


# --------------------------------------------------------------------------- (a) reproducibility


def test_same_seed_same_logs_to_the_bit_and_another_seed_differs(tmp_path: Path) -> None:
    a = make_independent_logs(tmp_path / "a", {}, drives=1, seed=3, duration=3.0)
    b = make_independent_logs(tmp_path / "b", {}, drives=1, seed=3, duration=3.0)
    c = make_independent_logs(tmp_path / "c", {}, drives=1, seed=4, duration=3.0)
    assert a[0].read_bytes() == b[0].read_bytes()
    assert a[0].with_suffix(".yaml").read_bytes() == b[0].with_suffix(".yaml").read_bytes()
    ta = yaml.safe_load((tmp_path / "a" / "truth.yaml").read_text())
    tc = yaml.safe_load((tmp_path / "c" / "truth.yaml").read_text())
    assert ta["nuisance"] != tc["nuisance"]  # another rover
    la, lc = read_log(a[0]), read_log(c[0])
    assert not np.array_equal(la.cmd, lc.cmd)  # another drive plan
    assert la.meta.rover == "proto_explorer" and la.meta.terrain == "flat"
    assert np.isfinite(la.pose[0]).all() and np.isnan(la.pose[1]).all()  # fixes at 1 Hz


# --------------------------------------------------------------------------- (b) nominal sanity


def test_straight_drive_free_wheels_roll_at_the_driven_wheels_rate() -> None:
    """On flat ground at constant speed nothing resists but bearing drag (mN): with SPEC's
    C_s = 100 N per unit slip, 1 % slip would need 1 N of traction per driven wheel, i.e. a
    4 N (2.5 % of the weight) resistance that flat ground does not supply. So the free wheels
    (3L/3R) turn within 1 % of the driven wheels' rate, and every |S| < 0.01."""
    tr = run()
    assert abs(_free_over_driven(tr) - 1.0) < 0.01
    assert np.abs(tr.slip[STEADY]).max() < 0.01
    assert np.allclose(tr.omega[STEADY, :4], W, atol=0.02)


def test_joint_angles_stay_near_zero_on_flat_ground() -> None:
    tr = run()
    assert np.abs(tr.theta).max() < np.radians(3.0)  # a pitch nod at the step
    assert np.abs(tr.theta[STEADY]).max() < np.radians(0.5)


def test_left_turn_yaws_positive_with_paper_slip_signs() -> None:
    tr = run(left=1.5, right=2.5)
    assert tr.pose[-1, 2] > 0.05
    s = tr.slip[STEADY].mean(axis=0)
    assert (s[[1, 3]] < 0).all() and (s[[0, 2]] > 0).all()  # outer spins, inner skids (SPEC §4)


def test_rover_at_rest_stays_at_rest() -> None:
    tr = run(left=0.0, right=0.0)
    assert np.abs(tr.pose[-1]).max() < 1e-4
    assert np.abs(tr.phi).max() < 1e-3


# --------------------------------------------------------------------------- (c) effects


def test_rolling_resistance_slows_the_free_wheels_against_the_driven() -> None:
    base, rr = (
        _free_over_driven(run()),
        _free_over_driven(run({"rolling_resistance": {"c_rr": 0.1}})),
    )
    assert rr < base - 0.02


def test_torque_limit_caps_acceleration() -> None:
    def peak_acc(tr: Truth) -> float:
        return float(np.max(np.diff(tr.omega[:, 0]) / np.diff(T)))

    base, capped = run(), run({"torque_limit": {"fraction": -0.8}})
    assert peak_acc(capped) < 0.5 * peak_acc(base)


def test_command_lag_delays_the_response() -> None:
    def t63(tr: Truth) -> float:
        return float(T[np.argmax(tr.omega[:, 0] > 0.63 * W)]) - 1.0

    assert t63(run({"command_lag": {"tau": 1.0}})) > t63(run()) + 0.5


def test_uphill_drive_slips_more() -> None:
    base, up = run(), run({"slope": {"deg": 10.0}})
    assert up.slip[STEADY, :4].mean() < base.slip[STEADY, :4].mean() - 0.03  # spinning: S < 0
    assert _free_over_driven(up) < _free_over_driven(base) - 0.03


def test_command_delay_shifts_the_response() -> None:
    def onset(tr: Truth) -> float:
        return float(T[np.argmax(tr.omega[:, 0] > 0.2 * W)])

    assert 0.4 < onset(run({"command_delay": {"delay": 0.5}})) - onset(run()) < 0.6


def test_rolling_radius_shortens_the_travel_per_wheel_turn() -> None:
    def per_rad(tr: Truth) -> float:
        return float(tr.pose[-1, 0] / tr.phi[-1, 4:].mean())

    ratio = per_rad(run({"rolling_radius": {"fraction": -0.1}})) / per_rad(run())
    assert abs(ratio - 0.9) < 0.01


@pytest.mark.parametrize(
    "eff",
    [{"friction": {"fraction": -0.7}}, {"load_dependent_friction": {"fall": 0.8, "range": 10.0}}],
    ids=["friction", "load_dependent_friction"],
)
def test_less_friction_slips_more_in_a_turn(eff: dict[str, dict[str, float]]) -> None:
    base, low = run(left=1.5, right=2.5), run(eff, left=1.5, right=2.5)
    slip = lambda tr: float(np.abs(tr.slip[STEADY, :4]).mean())  # noqa: E731
    assert slip(low) > slip(base) + 0.05


def test_loose_soil_sinks_slips_and_drags_the_free_wheels() -> None:
    base, sand = run(), run({"loose_soil": {"k_phi": 1.0}})
    assert 0.010 < sand.sink[0].mean() < 0.020  # SOIL.md: 14-17 mm static at 27 N (lambda 0.9-0.3)
    assert sand.slip[STEADY, :4].mean() < -0.05  # driven wheels spin
    assert sand.slip[STEADY, 4:].mean() > 0.02  # free wheels are dragged (skid)
    assert _free_over_driven(sand) < _free_over_driven(base) - 0.05


def test_sustained_spin_buries_a_wheel_in_loose_soil() -> None:
    tr = run({"loose_soil": {"k_phi": 1.0}}, left=-3.0, right=3.0)  # a pivot: all spin, no travel
    assert tr.sink[-1, :4].min() > 1.5 * tr.sink[0, :4].max()


# --------------------------------------------------------------------------- outside the catalogue


def test_payload_on_segment_2_loads_its_wheels_and_bends_the_pitch_joint() -> None:
    """A load of 30 % of the rover's mass on segment 2's deck: the tires carry the new weight
    (sum of C_z delta = (1.3 m) g at rest, within 1 %), segment 2's wheels most of it, and
    the pitch spring to segment 3 takes the moment (it sat at ~0 without)."""
    base, loaded = run(left=0.0, right=0.0), run({"payload": {"fraction": 0.3}}, 0.0, 0.0)
    p = model.RoverParams()
    weight = 1.3 * p.total_mass() * model.G
    assert abs(loaded.sink[-1].sum() * p.c_z / weight - 1.0) < 0.01
    extra = loaded.sink[-1] - base.sink[-1]
    assert extra[2:4].min() > 1.5 * max(extra[:2].max(), extra[4:].max()) > 0.0
    assert abs(np.degrees(loaded.theta[-1, 3])) > 2.0 > 10 * abs(np.degrees(base.theta[-1, 3]))


def test_toe_in_rolls_the_front_wheels_at_opposite_slip_angles_and_scrubs() -> None:
    """Front wheels yawed 6 degrees inward, straight command: they roll at slip angles of
    +-tan(6 deg) (left +, right -), the others at none; the lateral forces cancel (the rover
    keeps its heading) but drag it back, so the front (driven) wheels spin more."""
    base, toe = run(), run({"toe": {"deg": 6.0}})
    ta = toe.tan_alpha[STEADY].mean(axis=0)
    assert abs(ta[0] - np.tan(np.radians(6.0))) < 0.01 and abs(ta[1] + ta[0]) < 1e-3
    assert np.abs(ta[2:]).max() < 0.005
    assert abs(toe.pose[-1, 2]) < 0.005
    front = lambda tr: float(tr.slip[STEADY, :2].mean())  # noqa: E731
    assert front(toe) < front(base) - 0.003


def test_brake_drag_on_a_free_wheel_slows_it_and_pulls_the_rover_to_its_side() -> None:
    base, braked = run(), run({"brake_drag": {"torque": 0.3, "wheel": 4}})  # on 3L
    om = braked.omega[STEADY].mean(axis=0)
    assert om[4] < om[5] - 0.1  # 3L turns slower than 3R under the same (straight) command
    assert abs(base.omega[STEADY, 4].mean() - base.omega[STEADY, 5].mean()) < 0.01
    assert braked.pose[-1, 2] > 0.02 > abs(base.pose[-1, 2])  # it yaws toward the left


def test_battery_sag_lowers_the_top_speed_at_full_command_only() -> None:
    """At a target beyond reach (6.5 rad/s) the wheels run at the speed the clipped voltage
    allows, which falls with the supply (no-load speed V / k_t: 1 - fraction of nominal);
    at 2 rad/s the speed loops still hold the target."""
    top = lambda tr: float(tr.omega[STEADY, :4].mean())  # noqa: E731
    sag = {"battery_sag": {"fraction": 0.4}}
    ratio = top(run(sag, 6.5, 6.5)) / top(run(None, 6.5, 6.5))
    assert abs(ratio - 0.6) < 0.03
    assert abs(top(run(sag)) - W) < 0.02


# --------------------------------------------------------------------------- given plans


def test_a_given_schedule_is_driven_as_held_rows(tmp_path: Path) -> None:
    from rover_env.independent.drive import Schedule

    sched = Schedule(
        np.array([0.0, 0.5, 1.7, 2.0]),
        np.array([[0.0] * 4, [2.0, 2.0, 2.0, 2.0], [1.0, 3.0, 1.0, 3.0], [0.0] * 4]),
    )
    (p,) = make_independent_logs(tmp_path, {}, drives=1, seed=5, plan=sched, first_index=3)
    assert p.name == "drive_03.csv"
    log = read_log(p)
    assert log.t[-1] == 2.0 and len(log) == 101
    assert np.array_equal(log.cmd[(log.t >= 0.5) & (log.t < 1.7)][0], [2.0, 2.0, 2.0, 2.0])
    assert np.array_equal(log.cmd[(log.t >= 1.7) & (log.t < 2.0)], np.tile([1.0, 3, 1, 3], (15, 1)))
    assert np.array_equal(log.cmd[-1], [0.0] * 4)
    k05, k17 = 25, 85
    assert log.phi[k17, 0] - log.phi[k05, 0] > 1.5  # ~2 rad/s for 1.2 s after its rise
    last = log.phi[-1] - log.phi[k17]
    assert last[1] > last[0] + 0.2 and last[3] > last[2] + 0.2  # then the right side faster
    truth = yaml.safe_load((tmp_path / "truth.yaml").read_text())
    assert truth["drives"][0]["schedule"]["t"] == [0.0, 0.5, 1.7, 2.0]
    # the same rover: the first drives of seed 5 carry the same build in truth.yaml
    other = make_independent_logs(tmp_path / "first", {}, drives=1, seed=5, duration=1.0)
    assert (
        yaml.safe_load((other[0].parent / "truth.yaml").read_text())["nuisance"]
        == truth["nuisance"]
    )


def test_drive_kinds_given_replace_the_rotation(tmp_path: Path) -> None:
    """``kinds``: drive i is of kinds[i % len]; the reversals kind runs along one line,
    forwards and back, never turning."""
    paths = make_independent_logs(
        tmp_path, {}, drives=3, seed=7, duration=12.0, kinds=["reversals"]
    )
    truth = yaml.safe_load((tmp_path / "truth.yaml").read_text())
    assert [d["kind"] for d in truth["drives"]] == ["reversals"] * 3
    for path in paths:
        cmd = read_log(path).cmd
        assert np.array_equal(cmd[:, 0], cmd[:, 1]) and cmd.min() < 0 < cmd.max()
    rotated = make_independent_logs(tmp_path / "r", {}, drives=3, seed=7, duration=2.0)
    kinds = [
        d["kind"] for d in yaml.safe_load((rotated[0].parent / "truth.yaml").read_text())["drives"]
    ]
    assert len(set(kinds)) == 3
    with pytest.raises(ValueError, match="unknown drive kind"):
        make_independent_logs(tmp_path / "x", {}, drives=1, duration=1.0, kinds=["spin"])


def test_given_manoeuvres_and_the_cli_plan_csv(tmp_path: Path) -> None:
    from rover_env.independent.__main__ import main

    (p,) = make_independent_logs(
        tmp_path / "m", {}, drives=1, plan=[(1.0, 0, 0, 0), (1.5, 2, 2, 0.5)]
    )
    log = read_log(p)
    assert log.t[-1] == 2.5 and log.cmd[-1, 0] == 2.0 and log.cmd[60, 0] == pytest.approx(0.8)
    csv_path = tmp_path / "plan.csv"
    csv_path.write_text("t,cmd_1L,cmd_1R,cmd_2L,cmd_2R\n0,0,0,0,0\n0.4,1,1,1,1\n1.0,0,0,0,0\n")
    args = ["--plan-csv", str(csv_path), "--drives", "1", "--first-index", "4", "--out"]
    assert main([*args, str(tmp_path / "c")]) == 0
    log = read_log(tmp_path / "c" / "drive_04.csv")
    assert log.t[-1] == 1.0 and log.cmd[20, 0] == 1.0 and log.cmd[19, 0] == 0.0
    csv_path.write_text("time,a,b\n0,1,2\n")
    assert main([*args, str(tmp_path / "bad")]) == 2


# --------------------------------------------------------------------------- (d) nuisance


@pytest.mark.parametrize("seed", range(50))
def test_nuisance_draws_stay_within_tolerance(seed: int) -> None:
    d = nuisance.draw(seed)
    assert nuisance.within_tolerance(d) == []
    p = nuisance.apply(model.RoverParams(), d)
    assert abs(p.total_mass() / model.RoverParams().total_mass() - 1) <= 0.05


def test_nuisance_check_catches_an_out_of_band_draw() -> None:
    d = nuisance.draw(0)
    d["wheel_radius"][2] = 1.02
    assert nuisance.within_tolerance(d) == ["wheel_radius"]


def test_a_partial_build_draws_only_the_parts_named(tmp_path: Path) -> None:
    full, drawing = nuisance.draw(3), nuisance.nominal()
    d = nuisance.partial(3, ["centres_of_mass", "springs"])
    for k in d:
        inside = k in ("seg_com_offset_m", "spring_k", "spring_c")
        assert d[k] == (full[k] if inside else drawing[k]), k
    assert d["seg_com_offset_m"] != drawing["seg_com_offset_m"]
    assert sorted(k for g in nuisance.GROUPS.values() for k in g) == sorted(full)  # every part
    with pytest.raises(ValueError, match="wheels"):
        nuisance.partial(3, ["wheels"])
    for given in (["centres_of_mass"], "centres_of_mass"):  # a list of parts, or one name
        out = tmp_path / type(given).__name__
        paths = make_independent_logs(out, {}, drives=1, seed=3, duration=1.0, nuisance=given)
        truth = yaml.safe_load((paths[0].parent / "truth.yaml").read_text())
        assert truth["nuisance"] == nuisance.partial(3, ["centres_of_mass"])
        assert truth["nuisance_groups"] == ["centres_of_mass"]


# --------------------------------------------------------------------------- (e) independence


def test_imports_nothing_from_rover_env_but_logs() -> None:
    bad = []
    for path in sorted(PKG.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    bad.append(f"{path.name}: relative import")
                names = [node.module or ""]
            for n in names:
                top = n.split(".")[0]
                if top == "rover_env" and not (
                    n == "rover_env.logs" or n.startswith("rover_env.independent")
                ):
                    bad.append(f"{path.name}: {n}")
                if (
                    top not in {"rover_env", "mujoco", "numpy", "scipy", "yaml", "__future__"}
                    and top not in _STDLIB
                ):
                    bad.append(f"{path.name}: third-party {n}")
    assert not bad, bad


_STDLIB = {
    "argparse",
    "ast",
    "collections",
    "csv",
    "dataclasses",
    "functools",
    "math",
    "pathlib",
    "sys",
    "typing",
}


# --------------------------------------------------------------------------- entry point


def test_cli_writes_logs_and_truth(tmp_path: Path) -> None:
    from rover_env.independent.__main__ import main

    args = "--effect slope=5,heading_deg=90 --drives 1 --duration 1.0 --no-nuisance --out"
    rc = main([*args.split(), str(tmp_path)])
    assert rc == 0
    truth = yaml.safe_load((tmp_path / "truth.yaml").read_text())
    assert truth["effects"] == {"slope": {"deg": 5.0, "heading_deg": 90.0}}
    assert truth["nuisance"] is None
    assert len(read_log(tmp_path / "drive_00.csv")) == 51
    assert main(["--effect", "friction=2", "--out", str(tmp_path)]) == 2  # out of range


def test_effect_parsing_and_ranges() -> None:
    assert effects.parse_cli("rolling_resistance=0.05") == ("rolling_resistance", {"c_rr": 0.05})
    assert effects.resolve({"torque_limit": {"fraction": -0.5}}).current_limit_scale == 0.5
    with pytest.raises(effects.EffectError):
        effects.resolve({"command_lag": {"tau": 3.0}})
    with pytest.raises(effects.EffectError):
        effects.resolve({"wheel_wobble": {"x": 1.0}})
    with pytest.raises(effects.EffectError):
        effects.resolve({"brake_drag": {"torque": 0.2, "wheel": 2.5}})
    e = effects.resolve({"battery_sag": {"fraction": 0.3}, "brake_drag": {"torque": 0.2}})
    assert e.supply_scale == pytest.approx(0.7) and (e.brake_wheel, e.brake_torque) == (4, 0.2)


def test_effort_is_the_drivers_current_on_its_own_stream(tmp_path: Path) -> None:
    """``effort``: the drivers' reported torque, held at the cut current limit when a step
    asks for more; every other column the same as without it (its noise has its own stream)."""
    plan = [(0.5, 0.0, 0.0, 0.0), (1.0, 3.0, 3.0, 0.0), (0.5, 3.0, 3.0, 0.0)]
    kw = {"drives": 1, "seed": 7, "plan": plan}
    cut = {"torque_limit": {"fraction": -0.4}}
    (p,) = make_independent_logs(tmp_path / "e", cut, effort=True, **kw)  # type: ignore[arg-type]
    (q,) = make_independent_logs(tmp_path / "n", cut, **kw)  # type: ignore[arg-type]
    with_e, without = read_log(p), read_log(q)
    assert with_e.has_effort and not without.has_effort
    for name in ("cmd", "phi", "theta"):
        assert np.array_equal(getattr(with_e, name), getattr(without, name))
    ceiling = 0.6 * motor.I_MAX * motor.K_T_DATASHEET * motor.GEAR * motor.EFF
    top = np.abs(with_e.effort).max()
    assert abs(top - ceiling) < 0.05  # the 3 rad/s step saturates every motor
    assert (np.abs(with_e.effort) > ceiling - 0.05).sum() >= 4
