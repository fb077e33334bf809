"""benchmarks/clean_tilt.py: a clean case's row from its diagnosis, for the slope and for any
other effect fitted alone (``--effect``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from _bench import load_bench


def _result(work: Path, folder: str, effect: str, params: dict[str, list[float]]) -> None:
    out = work / folder / "out"
    out.mkdir(parents=True)
    fits = {effect: {"params": {effect: params}}}
    (out / "result.json").write_text(json.dumps({"fits": fits}))


def test_a_case_already_diagnosed_is_read_not_run_again(tmp_path: Path) -> None:
    ct = load_bench("clean_tilt")
    _result(tmp_path, "all_70003", "slope", {"deg": [1.25, 1.0, 1.5], "heading_deg": [40.0] * 3})
    _result(
        tmp_path, "rolling_resistance_motors_70003", "rolling_resistance", {"c_rr": [0.021] * 3}
    )
    slope = ct.case(tmp_path, "all", 70003)
    assert slope == {"condition": "all", "seed": 70003, "deg": 1.25, "heading_deg": 40.0}
    rr = ct.case(tmp_path, "motors", 70003, "rolling_resistance")
    assert rr == {"condition": "motors", "seed": 70003, "c_rr": 0.021}
    assert ct._line(rr, "rolling_resistance") == "c_rr 0.021"


def test_an_effect_outside_the_catalogue_is_refused_by_name(
    capsys: pytest.CaptureFixture[str],
) -> None:
    ct = load_bench("clean_tilt")
    with pytest.raises(SystemExit):
        ct.main(["--effect", "rolling_drag", "--seeds", "0"])
    assert "rolling_drag not one of" in capsys.readouterr().err
