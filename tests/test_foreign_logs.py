"""The second, deliberately different log generator (issue 16)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from rover_env.calibration.foreign_logs import FOREIGN_EFFECTS, ForeignRover, make_foreign_logs
from rover_env.calibration.make_logs import make_logs
from rover_env.config import RoverConfig
from rover_env.logs import read_log
from rover_env.sim.simulator import RoverSim


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

    assert foreign.meta.rover == own.meta.rover


def test_foreign_rover_drives_like_the_project_rover_but_is_not_its_code() -> None:
    """The same command from rest for 1.5 s: wheel and free-wheel travel agree to 2 %
    (the same physical rover and speed-loop gains), but not to the last bit."""
    cmd = np.array([2.0, 2.0, 2.0, 2.0])
    fr = ForeignRover(RoverConfig(), {})
    fr.run(cmd, 1.5)
    phi_f = fr.sample()[0]
    sim = RoverSim(RoverConfig(), backend="plugin")
    sim.set_speed_targets(cmd)
    sim.step(1500)
    phi_o = sim.sensors().phi
    np.testing.assert_allclose(phi_f, phi_o, rtol=0.02)
    assert np.abs(phi_f - phi_o).max() > 1e-4


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


def test_foreign_lateral_slip_is_eq_11() -> None:
    """The second implementation's lateral slip is the SPEC's eq. (11), written apart from
    rover_env.tire: same-sign wheel and ground speeds, skidding and spinning alike."""
    from rover_env.calibration.foreign_logs import lateral_slip
    from rover_env.tire import lateral_slip as eq11
    from rover_env.tire import slip_ratio

    rng = np.random.default_rng(11)
    v_x = rng.uniform(0.06, 0.5, 400) * rng.choice([-1, 1], 400)
    v_w = np.abs(v_x) * rng.uniform(0.2, 3.0, 400) * np.sign(v_x)
    v_y = rng.uniform(-0.2, 0.2, 400)
    S = slip_ratio(v_x, v_w, 1e-3)
    assert np.sum(S < 0) > 100 and np.sum(S > 0) > 100  # both regimes are tested
    np.testing.assert_allclose(lateral_slip(v_x, v_y, v_w), eq11(v_x, v_y, v_w, S, 1e-3), rtol=1e-9)


def test_foreign_generator_refuses_an_effect_it_does_not_implement(tmp_path: Path) -> None:
    from rover_env.config import ConfigError
    from rover_env.effects import CATALOGUE

    with pytest.raises(ConfigError, match="loose_soil: the second generator does not"):
        make_foreign_logs(tmp_path, {"loose_soil": {"k_phi": 1e6}}, drives=1, progress=False)
    assert not list(tmp_path.iterdir())  # nothing written
    assert FOREIGN_EFFECTS == set(CATALOGUE) - {"loose_soil"}
