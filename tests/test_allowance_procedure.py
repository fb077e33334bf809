"""The clean-fit allowance knows the procedure it was measured with (stop 112): a diagnosis
run with other fit options, or on logs of another rover, says so in its result and report;
a table naming an unknown option, or one of the wrong type, is refused naming the key."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest
import yaml

from rover_env.calibration.diagnosis import split
from rover_env.calibration.diagnosis.procedure import (
    PROCEDURE,
    changed_parts,
    check_options,
    differences,
)
from rover_env.calibration.diagnosis.state import Diagnosis, Options
from rover_env.calibration.form_allowance import FormAllowance, load_allowance
from rover_env.calibration.report_notes import procedure_note
from rover_env.config import ConfigError, load_rover, resolve_path
from rover_env.generators.make_logs import make_logs


def test_the_shipped_table_was_measured_by_default_on_the_configured_rover() -> None:
    table = load_allowance()
    assert table.options == {} and table.rover == "proto_explorer"
    assert differences(Options(), table, load_rover("proto_explorer")) == []


def test_an_option_that_shapes_fits_is_a_difference_both_ways() -> None:
    table = load_allowance()
    (line,) = differences(Options(torque_forms=True), table, load_rover())
    assert line.startswith("torque_forms: measured with off, here on")
    measured_on = dataclasses.replace(table, options={"torque_forms": True})
    assert differences(Options(torque_forms=True), measured_on, load_rover()) == []
    assert differences(Options(), measured_on, load_rover()) == [
        "torque_forms: measured with on, here off"
    ]
    # What runs a diagnosis or decides names from fits is not the procedure.
    assert differences(Options(workers=2, alpha=0.05), table, load_rover()) == []
    assert "workers" not in PROCEDURE and "candidates" not in PROCEDURE


def test_a_rover_other_than_the_measured_one_is_named_by_its_changed_fields() -> None:
    rover = load_rover()
    heavy = dataclasses.replace(
        rover, motor=dataclasses.replace(rover.motor, armature=2 * rover.motor.armature)
    )
    assert changed_parts(rover, heavy) == ["motor.armature"]
    (line,) = differences(Options(), load_allowance(), heavy)
    assert "'proto_explorer'" in line and "motor.armature" in line
    unrecorded = dataclasses.replace(load_allowance(), rover=None)
    assert differences(Options(), unrecorded, heavy) == []


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"workers": 2}, "options.workers: not an option that shapes a fit"),
        ({"torque_forms": "yes"}, "options.torque_forms: expected bool"),
        ({"max_nfev": True}, "options.max_nfev: expected int"),
    ],
)
def test_a_table_with_a_bad_option_is_refused_naming_file_and_key(
    tmp_path: Path, options: dict[str, object], message: str
) -> None:
    table = FormAllowance(effects={}, options=options)
    with pytest.raises(ConfigError, match=re.escape(message)) as err:
        check_options(table, tmp_path / "t.yaml")
    assert str(tmp_path / "t.yaml") in str(err.value)


def test_a_float_option_takes_an_integer(tmp_path: Path) -> None:
    check_options(FormAllowance(effects={}, options={"free_common": 0}), tmp_path / "t.yaml")


def test_diagnosis_records_the_difference_once_and_the_report_names_it(tmp_path: Path) -> None:
    made = make_logs(tmp_path / "made", {}, drives=3, seed=2, duration=12.0, progress=False)
    paths = [str(p) for p in made]
    d = Diagnosis(paths, tmp_path / "out", Options(progress=False))
    split.split(d)
    assert d.allowance_differs == []
    table = yaml.safe_load(resolve_path("form_allowance", "calibration").read_text())
    table["options"] = {"torque_forms": True}
    path = tmp_path / "measured_with_forms.yaml"
    path.write_text(yaml.safe_dump(table))
    d = Diagnosis(paths, tmp_path / "out2", Options(progress=False, form_allowance=str(path)))
    split.split(d)
    assert d.allowance_differs == ["torque_forms: measured with on, here off"]
    # A second pass carries the first's verdict (its own options are the pipeline's).
    d.allowance_differs = ["kept"]
    split.split(d)
    assert d.allowance_differs == ["kept"]
    assert "torque_forms: measured with on, here off" in procedure_note(
        ["torque_forms: measured with on, here off"]
    )
    table["options"] = {"bogus": 1}
    path.write_text(yaml.safe_dump(table))
    d = Diagnosis(paths, tmp_path / "out3", Options(progress=False, form_allowance=str(path)))
    with pytest.raises(ConfigError, match=r"options\.bogus"):
        split.split(d)
