"""diagnose's split: the last log by file name is held out, wherever its folder sorts. A
proposed drive is logged in its own folder as the next drive (drive_03 beside drive_00-02);
it is the new evidence, and sorted by whole path it went into training instead."""

from __future__ import annotations

import shutil
from pathlib import Path

from rover_env.calibration.diagnosis import split
from rover_env.calibration.diagnosis.state import Diagnosis, Options
from rover_env.generators.make_logs import make_logs


def test_the_last_drive_by_name_is_held_out_whatever_its_folder(tmp_path: Path) -> None:
    made = make_logs(tmp_path / "made", {}, drives=3, seed=2, duration=12.0, progress=False)
    first, later = tmp_path / "z_logs", tmp_path / "a_followup"
    for folder, logs in ((first, made[:2]), (later, made[2:])):
        folder.mkdir()
        for p in logs:
            shutil.copy(p, folder / p.name)
            shutil.copy(p.with_suffix(".yaml"), folder / p.with_suffix(".yaml").name)
    paths = [str(first / made[0].name), str(first / made[1].name), str(later / made[2].name)]
    assert sorted(paths)[0].startswith(str(later))  # the whole path sorts it first
    d = Diagnosis(paths, tmp_path / "out", Options(progress=False))
    split.split(d)
    held = {w.log_index for w in d.held_w}
    assert [d.files[i].name for i in held] == [made[2].name]
    assert {d.files[w.log_index].name for w in d.train_w} == {made[0].name, made[1].name}


def test_interleave_holds_out_every_other_window_of_every_drive(tmp_path: Path) -> None:
    """``Options.interleave``: each drive lends its odd windows to the held-out set, so a
    manoeuvre only one drive makes is in both sets (the last-drive split holds it out)."""
    made = make_logs(tmp_path / "made", {}, drives=3, seed=2, duration=12.0, progress=False)
    d = Diagnosis(
        [str(p) for p in made], tmp_path / "out", Options(progress=False, interleave=True)
    )
    split.split(d)
    for i in range(len(made)):
        mine = sorted((w for w in d.all_w if w.log_index == i), key=lambda w: w.k0)
        assert len(mine) >= 2
        assert [w.k0 for w in d.train_w if w.log_index == i] == [w.k0 for w in mine[0::2]]
        assert [w.k0 for w in d.held_w if w.log_index == i] == [w.k0 for w in mine[1::2]]
    assert len(d.train_w) + len(d.held_w) == len(d.all_w)
    assert "odd windows held out" in d.split


def test_a_single_log_alternates_its_windows(tmp_path: Path) -> None:
    made = make_logs(tmp_path / "made", {}, drives=1, seed=3, duration=30.0, progress=False)
    d = Diagnosis([str(made[0])], tmp_path / "out", Options(progress=False))
    split.split(d)
    assert [w.k0 for w in d.train_w] == [w.k0 for w in d.all_w[0::2]]
    assert [w.k0 for w in d.held_w] == [w.k0 for w in d.all_w[1::2]]
    assert d.split.startswith(f"one log ({made[0].name})")
