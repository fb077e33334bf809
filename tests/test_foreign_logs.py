"""The second, deliberately different log generator (issue 16)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from rover_env.calibration.foreign_logs import make_foreign_logs
from rover_env.calibration.make_logs import make_logs
from rover_env.logs import read_log


@pytest.fixture(scope="module")
def pair(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("foreign")
    a = make_foreign_logs(root / "foreign", {}, drives=1, seed=3, duration=3.0, progress=False)
    b = make_logs(root / "own", {}, drives=1, seed=3, duration=3.0, progress=False)
    return a[0], b[0]


def test_foreign_logs_are_spec_logs_of_the_nominal_rover(pair: tuple[Path, Path]) -> None:
    foreign, _ = pair
    log = read_log(foreign)
    assert log.meta.rover == "proto_explorer"
    assert log.t[1] - log.t[0] == pytest.approx(0.02)
    assert np.isfinite(log.pose[::50, 0]).all() and np.isnan(log.pose[1:50, 0]).all()
    truth = yaml.safe_load((foreign.parent / "truth.yaml").read_text())
    assert truth["generator"].startswith("foreign") and truth["effects"] == {}


def test_foreign_generator_is_the_same_rover_but_not_the_same_code(
    pair: tuple[Path, Path],
) -> None:
    foreign, own = read_log(pair[0]), read_log(pair[1])
    # Its own sensors: encoder steps of 2 pi / 2048 rad, not 0.01 rad.
    steps = np.abs(np.diff(foreign.phi[:, 0]))
    steps = steps[steps > 0]
    assert np.allclose(steps / (2 * np.pi / 2048), np.round(steps / (2 * np.pi / 2048)))

    # Same rover: the driven wheels follow their commands alike, to a few per cent of the
    # commanded angle (its own speed loop and tire, so not to the last bit).
    def follow(log: object) -> float:
        cmd_angle = np.cumsum(log.cmd[:-1, 0] * np.diff(log.t))  # type: ignore[attr-defined]
        return float(log.phi[-1, 0] / cmd_angle[-1])  # type: ignore[attr-defined]

    assert follow(foreign) == pytest.approx(follow(own), abs=0.05)
    assert follow(foreign) != follow(own)


def test_foreign_rolling_resistance_slows_the_free_wheels(tmp_path: Path) -> None:
    a = make_foreign_logs(tmp_path / "a", {}, drives=1, seed=4, duration=3.0, progress=False)
    b = make_foreign_logs(
        tmp_path / "b",
        {"rolling_resistance": {"c_rr": 0.05}},
        drives=1,
        seed=4,
        duration=3.0,
        progress=False,
    )
    free_a = np.abs(read_log(a[0]).phi[-1, 4:]).mean()
    free_b = np.abs(read_log(b[0]).phi[-1, 4:]).mean()
    assert free_b < free_a * 0.99
