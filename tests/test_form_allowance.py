"""benchmarks/form_allowance.py: the clean-fit allowance read from stored block results, the
interval widened by it, what it covers and what it would refuse. Blocks are built by hand."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
import yaml
from _bench import load_bench


@pytest.fixture(scope="module")
def fa() -> ModuleType:
    return load_bench("form_allowance")


def _clean(block: Path, i: int, delay: float, tilt: float) -> None:
    out = block / "work" / f"clean_none_{i}" / "out"
    out.mkdir(parents=True)
    fits = {
        "command_delay": {"params": {"command_delay": {"delay": [delay, 0.0, 2 * delay]}}},
        "slope": {"params": {"slope": {"deg": [tilt, 0.0, 1.0], "heading_deg": [10, None, None]}}},
        "combined_slip": {"params": {"combined_slip": {"on": [1.0, 1.0, 1.0]}}},
    }
    (out / "result.json").write_text(json.dumps({"fits": fits}))


def test_the_allowance_is_the_spread_of_what_clean_logs_fit(fa: ModuleType, tmp_path: Path) -> None:
    for i in range(21):
        _clean(tmp_path, i, 0.001 * i, 0.1 * i)
    fits = fa.clean_fits([tmp_path])
    assert set(fits) == {"command_delay", "slope"}  # a switch has no size
    allow = fa.allowance(fits)
    q05, q95, n = allow["command_delay"]
    assert n == 21 and q05 == pytest.approx(0.001) and q95 == pytest.approx(0.019)
    assert allow["slope"][1] == pytest.approx(1.9)
    # A delay fitted 0.112 [0.100, 0.120] for a truth of 0.091 (spent case 51324's pattern):
    lo, hi = fa.widened("command_delay", 0.100, 0.120, allow["command_delay"])
    assert lo == pytest.approx(0.081) and lo <= 0.091 <= hi
    assert hi == 0.120  # q05 is above 0 here: an allowance widens, it never narrows
    # A tilt can gain or lose the spurious one: widened both ways, never below level.
    assert fa.widened("slope", 1.0, 2.0, allow["slope"]) == pytest.approx((0.0, 3.9))


def test_named_effects_are_scored_covered_and_refused(fa: ModuleType) -> None:
    allow = {"command_delay": (0.0, 0.026, 43), "friction": (-0.242, 0.061, 43)}
    rows = [
        {  # a right delay, biased long: covered only once widened
            "case": "single_command_delay_1",
            "kind": "single",
            "truth": {"command_delay": {"delay": 0.091}},
            "named": ["command_delay"],
            "named_fits": {"command_delay": {"delay": [0.112, 0.100, 0.120]}},
            "fits": {"command_delay": {"truth": 0.091}},
        },
        {  # a clean case's friction: within what clean logs fit, refused
            "case": "clean_none_2",
            "kind": "clean",
            "truth": "none",
            "named": ["friction"],
            "named_fits": {"friction": {"fraction": [-0.244, -0.286, -0.201]}},
            "fits": {},
        },
    ]
    got = fa.named(rows, allow)
    assert [(g["effect"], g["right"], g["refused"]) for g in got] == [
        ("command_delay", True, False),
        ("friction", False, True),
    ]
    lines = fa.table(allow, got)
    assert "| command_delay | 43 | 0 | 0.026 | 0/1 | 1/1 | 0/1 | 0/0 |" in lines
    assert "| friction | 43 | -0.242 | 0.061 | 0/0 | 0/0 | 0/0 | 1/1 |" in lines


def test_the_written_table_is_what_diagnose_reads(fa: ModuleType, tmp_path: Path) -> None:
    from rover_env.calibration.form_allowance import load_allowance

    for i in range(21):
        _clean(tmp_path, i, 0.001 * i, 0.1 * i)
    allow = fa.allowance(fa.clean_fits([tmp_path]))
    path = tmp_path / "table.yaml"
    fa.write_table(allow, [tmp_path], [], path)
    got = load_allowance(path)
    assert set(got.effects) == {"command_delay", "slope"}
    # measured as bench_independent.py diagnoses: default options, the configured rover
    assert (got.options, got.rover) == ({}, "proto_explorer")
    b = got.effects["command_delay"]
    assert (b.low, b.high, b.cases) == (pytest.approx(0.001), pytest.approx(0.019), 21)
    # diagnose's interval for the truth is the benchmark's widened one
    lo, hi = fa.widened("command_delay", 0.100, 0.120, allow["command_delay"])
    below, above = got.pad("command_delay")
    assert (0.100 - below, 0.120 + above) == (pytest.approx(lo), pytest.approx(hi))


def test_a_table_from_clean_runs_records_their_procedure(fa: ModuleType, tmp_path: Path) -> None:
    """``--runs`` (stop 112): any diagnoses of clean drives, made with other options, make a
    table that says so; diagnose run the same way finds no difference, run by default one."""
    from rover_env.calibration.diagnosis.procedure import differences
    from rover_env.calibration.diagnosis.state import Options
    from rover_env.calibration.form_allowance import load_allowance
    from rover_env.config import load_rover, resolve_path

    for i in range(20):
        _clean(tmp_path, i, 0.002 * i, 0.1 * i)
    runs = sorted((tmp_path / "work").glob("clean_*/out"))
    options = fa.parse_options(["torque-forms=true", "max_nfev=6"])
    assert options == {"torque_forms": True, "max_nfev": 6}
    path = tmp_path / "mine.yaml"
    fa.write_table(fa.allowance(fa.run_fits(runs)), [], [], path, {}, [], runs, options)
    got = load_allowance(path)
    assert got.effects["command_delay"].cases == 20
    assert got.options == options and got.rover == "proto_explorer"
    assert "20 clean diagnoses" in yaml.safe_load(path.read_text())["source"]
    same = Options(torque_forms=True, max_nfev=6)
    assert differences(same, got, load_rover()) == []
    assert len(differences(Options(), got, load_rover())) == 2
    # Written over another procedure's table, it keeps none of that one's entries.
    shipped = yaml.safe_load(resolve_path("form_allowance", "calibration").read_text())
    path.write_text(yaml.safe_dump(shipped))
    fa.write_table(fa.allowance(fa.run_fits(runs)), [], [], path, None, [], runs, options)
    again = load_allowance(path)
    assert set(again.effects) == {"command_delay", "slope"}
    assert again.effects["command_delay"].named == 0
    with pytest.raises(SystemExit, match="expected KEY=VALUE"):
        fa.parse_options(["torque_forms"])
    with pytest.raises(SystemExit, match=r"options\.workers: not an option"):
        fa.parse_options(["workers=2"])
    with pytest.raises(SystemExit, match=r"no result\.json"):
        fa.run_fits([tmp_path])


def _soil_block(block: Path, ratios: list[float], named: bool = True) -> None:
    rows = [
        {
            "case": f"single_loose_soil_{i}",
            "kind": "single",
            "truth": {"loose_soil": {"k_phi": 1e6}},
            "named": ["loose_soil"] if named else ["rolling_resistance"],
            "named_fits": {"loose_soil": {"k_phi": [1e6 * r, 0.98e6 * r, 1.02e6 * r]}},
            "fits": {"loose_soil": {"value": 1e6 * r, "truth": 1e6}},
        }
        for i, r in enumerate(ratios)
    ]
    block.mkdir(parents=True, exist_ok=True)
    (block / "independent.json").write_text(json.dumps(rows))


def test_the_soil_factor_is_the_spread_of_fitted_over_true_k_phi(
    fa: ModuleType, tmp_path: Path
) -> None:
    """Stop 81: named soils only, read as factors; quantiles on the logarithms."""
    ratios = [2.0 ** (k / 10) for k in range(-10, 11)]  # 0.5 .. 2, even in log
    _soil_block(tmp_path / "b1", ratios)
    _soil_block(tmp_path / "b2", [9.0, 0.1], named=False)  # soils not named: not counted
    got = fa.soil_ratios([tmp_path / "b1", tmp_path / "b2"])
    assert got == pytest.approx(ratios)
    q05, q95, n = fa.factor(got)
    assert n == 21 and q05 == pytest.approx(2.0**-0.9) and q95 == pytest.approx(2.0**0.9)
    # An interval for the truth: [lo / q95, hi / q05]. A fit 1.9 x the truth, +-2 %:
    lo, hi = fa.widened("loose_soil", 1.86e6, 1.94e6, (q05, q95, n))
    assert lo == pytest.approx(1.86e6 / q95) and lo <= 1e6 <= hi
    assert fa.widened("loose_soil", 1.86e6, 1.94e6, (0.5, 3.5, n))[1] == pytest.approx(3.88e6)
    rows = json.loads((tmp_path / "b1" / "independent.json").read_text())
    g = fa.named(rows, {"loose_soil": (q05, q95, n)})
    stored = sum(x["fit"][1] <= x["truth"] <= x["fit"][2] for x in g)
    wide = sum(x["widened"][0] <= x["truth"] <= x["widened"][1] for x in g)
    assert (stored, wide, sum(x["refused"] for x in g)) == (1, 19, 0)  # never refuses a soil


def _clean_table(fa: ModuleType, tmp_path: Path) -> Path:
    """A table written from 21 clean cases (delays 0-20 ms, tilts 0-2 deg) at tmp/table.yaml."""
    for i in range(21):
        _clean(tmp_path / "clean", i, 0.001 * i, 0.1 * i)
    path = tmp_path / "table.yaml"
    fa.write_table(
        fa.allowance(fa.clean_fits([tmp_path / "clean"])), [tmp_path / "clean"], [], path
    )
    return path


def test_soil_alone_updates_a_table_keeping_its_clean_entries(
    fa: ModuleType, tmp_path: Path
) -> None:
    from rover_env.calibration.form_allowance import load_allowance

    path = _clean_table(fa, tmp_path)
    before = path.read_text()
    fa.write_table({"loose_soil": (0.6, 3.4, 12)}, [], [tmp_path / "b9"], path)
    got = load_allowance(path)
    assert set(got.effects) == {"command_delay", "loose_soil", "slope"}
    assert got.pad("loose_soil") == (3.4, 0.6)
    assert got.effects["command_delay"].high == pytest.approx(0.019)
    assert (
        "clean cases of blocks clean" in path.read_text()
        and "named soils of blocks b9" in path.read_text()
    )
    fa.write_table({"loose_soil": (0.5, 3.0, 13)}, [], [tmp_path / "b8"], path)  # again: replaced
    assert load_allowance(path).pad("loose_soil") == (3.0, 0.5)
    assert "b9" not in path.read_text() and before.count("command_delay") == 1


def test_the_command_line_evaluates_with_or_without_soils(
    fa: ModuleType,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    clean, soils = tmp_path / "clean", tmp_path / "soils"
    for i in range(21):
        _clean(clean, i, 0.001 * i, 0.1 * i)
    _soil_block(soils, [2.0 ** (k / 10) for k in range(-10, 11)])
    for extra in ([], ["--soil", str(soils)]):
        argv = ["form_allowance.py", "--calibrate", str(clean), "--evaluate", str(soils)]
        monkeypatch.setattr("sys.argv", [*argv, "--out", str(tmp_path / "out"), *extra])
        fa.main()
        text = (tmp_path / "out" / "allowance.md").read_text()
        assert ("| loose_soil | 21 |" in text) == bool(extra)
        assert (tmp_path / "out" / "allowance.png").stat().st_size > 0
    monkeypatch.setattr(
        "sys.argv",
        ["form_allowance.py", "--soil", str(tmp_path), "--evaluate", str(soils), "--out", "o"],
    )
    with pytest.raises(SystemExit):
        fa.main()  # a folder without independent.json: one clear error
    assert f"no independent.json in {tmp_path}" in capsys.readouterr().err
    monkeypatch.setattr(
        "sys.argv", ["form_allowance.py", "--soil", str(soils), "--write", "t.yaml"]
    )
    with pytest.raises(SystemExit):
        fa.main()  # --soil alone updates a table: none there
    assert "--soil or --named alone updates an existing table" in capsys.readouterr().err


def _named_block(block: Path, cases: list[tuple[float, float, float, float]], raw: bool) -> None:
    """Right single lags (truth, value, lo, hi); ``raw``: stored with the pre-widening
    interval (``lo_raw``, ``hi_raw``; lo widened by 0.04 as the shipped table would)."""
    rows = []
    for i, (t, v, lo, hi) in enumerate(cases):
        fit: dict[str, float] = {"truth": t, "value": v, "lo": lo, "hi": hi}
        if raw:
            fit |= {"lo": lo - 0.04, "lo_raw": lo, "hi_raw": hi}
        rows.append(
            {
                "case": f"single_command_lag_{i}",
                "kind": "single",
                "truth": {"command_lag": {"tau": t}},
                "named": ["command_lag"],
                "fits": {"command_lag": fit},
            }
        )
    rows.append(  # named but not the truth: not counted
        {
            "case": "single_command_delay_9",
            "kind": "single",
            "truth": {"command_delay": {"delay": 0.05}},
            "named": ["command_lag"],
            "fits": {"command_lag": {"truth": None, "value": 0.1, "lo": 0.0, "hi": 0.2}},
        }
    )
    block.mkdir(parents=True, exist_ok=True)
    (block / "independent.json").write_text(json.dumps(rows))


def test_the_truth_beyond_right_names_is_read_from_their_unwidened_intervals(
    fa: ModuleType, tmp_path: Path
) -> None:
    """Stop 99: how far the truth sat outside a right name's own interval, per side."""
    # 20 lags fitted short: truth above hi by 0 .. 0.0019 s (every other one inside)
    cases = [(0.1, 0.095, 0.09, 0.1 - 0.0001 * i * (i % 2)) for i in range(20)]
    _named_block(tmp_path / "old", cases[:10], raw=False)
    _named_block(tmp_path / "new", cases[10:], raw=True)
    found = fa.misses([tmp_path / "old", tmp_path / "new"])
    assert set(found) == {"command_lag"} and len(found["command_lag"]) == 20
    below, above, n, reach = fa.beyond(found)["command_lag"]
    assert n == 20 and below == 0.0
    # the fits sat 5 ms under the truth every time: the far end's floor
    assert reach == pytest.approx(0.005)
    assert above == pytest.approx(np.quantile([0.0001 * i * (i % 2) for i in range(20)], 0.95))
    assert fa.beyond(found, least=21) == {}  # too few names: not measured
    # the combined pad covers a truth 1.5 ms above that the clean one left out
    q = (0.0, 0.042, 100)
    assert fa.widened("command_lag", 0.09, 0.0985, q)[1] == 0.0985
    assert fa.widened("command_lag", 0.09, 0.0985, q, (below, above, n, reach))[1] >= 0.1


def test_the_far_end_floor_counts_from_the_fit_away_from_off(
    fa: ModuleType, tmp_path: Path
) -> None:
    """Stop 101: a name's truth beyond its fit, away from "off", whatever its interval; a
    radius fitted below "off" reaches down, a lag above it reaches up."""
    lags = [(0.2 + 0.001 * i, 0.2, 0.198, 0.202) for i in range(10)]  # 0..9 ms short
    _named_block(tmp_path / "lags", lags, raw=True)
    rows = [
        {
            "case": f"single_rolling_radius_{i}",
            "kind": "single",
            "truth": {"rolling_radius": {"delta": -0.05 - 0.001 * i}},
            "named": ["rolling_radius"],
            "fits": {
                "rolling_radius": {
                    "truth": -0.05 - 0.001 * i,
                    "value": -0.05,
                    "lo": -0.052,
                    "hi": -0.048,
                    "lo_raw": -0.052,
                    "hi_raw": -0.048,
                }
            },
        }
        for i in range(10)
    ]
    (tmp_path / "radii").mkdir()
    (tmp_path / "radii" / "independent.json").write_text(json.dumps(rows))
    found = fa.misses([tmp_path / "lags", tmp_path / "radii"])
    assert all(m[3] for m in found["command_lag"]) and not any(
        m[3] for m in found["rolling_radius"]
    )
    out = fa.beyond(found)
    q = np.quantile([0.001 * i for i in range(10)], 0.95)
    assert out["command_lag"][3] == pytest.approx(q) and out["rolling_radius"][3] == pytest.approx(
        q
    )
    # coverage: a 9 ms short lag is outside a 2 ms pad, inside the floor of its reach
    miss = found["command_lag"][9]
    assert not fa.covered(miss, (0.0, 0.002)) and fa.covered(miss, (0.0, 0.002), 0.0095)
    # the floor never reaches across: a radius's floor does not cover a truth above its hi
    assert not fa.covered((-0.01, 0.01, -0.011, False), (0.0, 0.0), 0.05)
    path = tmp_path / "table.yaml"
    fa.write_table({"command_lag": (0.0, 0.04, 50)}, [tmp_path], [], path, out, [tmp_path])
    from rover_env.calibration.form_allowance import load_allowance

    assert load_allowance(path).reach("command_lag") == pytest.approx(q, abs=1e-6)


def test_named_alone_updates_a_table_keeping_clean_and_soil_entries(
    fa: ModuleType, tmp_path: Path
) -> None:
    from rover_env.calibration.form_allowance import load_allowance

    path = _clean_table(fa, tmp_path)
    fa.write_table({"loose_soil": (0.6, 3.4, 12)}, [], [tmp_path / "b9"], path)
    blocks = [tmp_path / "calibration" / "b7", tmp_path / "study1" / "p1"]
    fa.write_table({}, [], [], path, {"command_delay": (0.01, 0.003, 30, 0.0)}, blocks)
    got = load_allowance(path)
    assert set(got.effects) == {"command_delay", "loose_soil", "slope"}
    d = got.effects["command_delay"]
    assert (d.high, d.below, d.above, d.named) == (pytest.approx(0.019), 0.01, 0.003, 30)
    assert got.pad("command_delay") == (pytest.approx(0.019), 0.003)
    assert got.effects["slope"].named == 0  # not measured there
    text = yaml.safe_load(path.read_text())["source"]
    assert (
        "named soils of blocks b9" in text
        and "right single names' own intervals in blocks b7" in text
    )
    # clean entries calibrated again: the named-side entries and the soil stay
    fa.write_table(
        fa.allowance(fa.clean_fits([tmp_path / "clean"])), [tmp_path / "clean"], [], path
    )
    got = load_allowance(path)
    assert got.effects["command_delay"].named == 30 and got.pad("loose_soil") == (3.4, 0.6)
    assert path.read_text().count("b7") == 1
