"""benchmarks/group_reads.py: its arguments refused by name, and each group's read in the table."""

from __future__ import annotations

import pytest
from _bench import load_bench


def test_bad_arguments_are_refused_by_name(capsys: pytest.CaptureFixture[str]) -> None:
    gr = load_bench("group_reads")
    assert gr.parse_effect("rolling_resistance") == ("rolling_resistance", "c_rr")
    assert gr.parse_effect("slope.heading_deg") == ("slope", "heading_deg")
    assert gr.parse_case("70814=0.04") == (70814, 0.04, {})
    assert gr.parse_case("70831=3,heading_deg=70", "slope") == (70831, 3.0, {"heading_deg": 70.0})
    with pytest.raises(SystemExit, match="slope has no parameter 'heading'"):
        gr.parse_case("70831=3,heading=70", "slope")
    with pytest.raises(SystemExit, match="expected SEED=VALUE"):
        gr.parse_case("70831=3,heading_deg", "slope")
    with pytest.raises(SystemExit, match="'rolling_drag' is not in the catalogue"):
        gr.parse_effect("rolling_drag")
    with pytest.raises(SystemExit, match="slope has no parameter 'tilt'"):
        gr.parse_effect("slope.tilt")
    with pytest.raises(SystemExit, match=r"expected SEED=VALUE.*, got '70814'"):
        gr.parse_case("70814")
    with pytest.raises(SystemExit, match="at least two different finite values"):
        gr.main(["--effect", "rolling_resistance", "--clean", "1", "--grid", "0.01,0.01"])
    with pytest.raises(SystemExit, match="give the values when no case has the effect"):
        gr.main(["--effect", "rolling_resistance", "--clean", "1"])
    with pytest.raises(SystemExit, match="speed_gian"):
        gr.main(["--effect", "rolling_resistance", "--cases", "1=0.02", "--motor", "speed_gian=2"])
    assert gr.parse_option("fit_com_height=true") == ("fit_com_height", True)
    with pytest.raises(SystemExit, match="'fit_com_hieght=true': expected FIELD=VALUE"):
        gr.parse_option("fit_com_hieght=true")
    with pytest.raises(SystemExit, match="'maybe' is not a bool"):
        gr.parse_option("fit_com_height=maybe")
    with pytest.raises(SystemExit, match="at least one case"):
        gr.main(["--effect", "rolling_resistance"])


def test_the_table_gives_every_groups_read_on_both_window_sets() -> None:
    gr = load_bench("group_reads")
    groups = list(gr.SIGNAL_GROUPS)
    row = {"seed": 7, "truth": 0.04, "forms": {"yaw_spring": 14.0, "zero_theta_1": 0.01}}
    for k, which in enumerate(gr.SETS):
        reads = {g: 0.01 * (i + 1) + k for i, g in enumerate(groups)}
        row[which] = {"best": 0.02 + k, "group_best": reads}
    lines = gr.table([row], "rolling_resistance", "c_rr").splitlines()
    head = [c.strip() for c in lines[4].strip("|").split("|")]
    cells = [c.strip() for c in lines[6].strip("|").split("|")]
    got = dict(zip(head, cells, strict=True))
    assert got["train: all"] == "0.02" and got["straight: all"] == "1.02"
    assert got[f"train: {groups[0]}"] == "0.01" and got[f"straight: {groups[-1]}"] == "1.04"
    assert got["forms"] == "yaw_spring 14"  # the joint zeros are left out


def test_saved_rows_are_tabulated_again(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import json

    gr = load_bench("group_reads")
    groups = list(gr.SIGNAL_GROUPS)
    rows = []
    for truth in (-0.4, 0.0):
        row = {"seed": 1, "truth": truth, "forms": {}}
        for which in gr.SETS:
            row[which] = {"best": truth, "group_best": dict.fromkeys(groups, truth)}
        rows.append(row)
    saved = tmp_path / "rows.jsonl"
    saved.write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert (
        gr.main(["--effect", "torque_limit", "--from-jsonl", str(saved), "--out", str(tmp_path)])
        == 0
    )
    assert "| 1 | -0.4 | -0.4 |" in (tmp_path / "group_reads.md").read_text()
    assert (tmp_path / "group_reads.png").stat().st_size > 1000


def test_the_grid_holds_a_cases_other_parameters() -> None:
    gr = load_bench("group_reads")
    (slope,) = gr.catalogue(["slope"])
    (rr,) = gr.catalogue(["rolling_resistance"])
    held = gr.grid_extension(slope, "heading_deg", 1, 0.0, {"deg": 2.0})
    assert held == {"slope": {"heading_deg": 0.0, "deg": 2.0}}  # heading 0 is a direction
    assert gr.grid_extension(rr, "c_rr", 0, 0.03, {}) == {"rolling_resistance": {"c_rr": 0.03}}
    along_x = gr.grid_extension(slope, "deg", 0, 3.0, {})["slope"]
    assert along_x["deg"] == pytest.approx(3.0) and along_x["heading_deg"] == pytest.approx(0.0)


def test_the_table_says_what_each_case_held() -> None:
    gr = load_bench("group_reads")
    row = {"seed": 7, "truth": 60.0, "others": {"deg": 2.0}, "forms": {}}
    for which in gr.SETS:
        row[which] = {"best": 30.0, "group_best": dict.fromkeys(gr.SIGNAL_GROUPS, 60.0)}
    lines = gr.table([row], "slope", "heading_deg").splitlines()
    head = [c.strip() for c in lines[4].strip("|").split("|")]
    cells = [c.strip() for c in lines[6].strip("|").split("|")]
    assert dict(zip(head, cells, strict=True))["held"] == "deg 2"
