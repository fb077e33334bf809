"""The speed loop's form fitted as one (``form_loop.fit_motor_loop``, ``--joint-motor-loop``):
nothing adopted on the model's own drive; another loop (conditional anti-windup, a stiffer
proportional gain, a heavier rotor) found together and adopted; applied by ``with_form``."""

from __future__ import annotations

import pytest

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnosis.form import FormFit, with_form
from rover_env.calibration.diagnosis.form_loop import LOOP_PARTS, fit_motor_loop, with_loop
from rover_env.calibration.diagnosis.state import Options
from rover_env.calibration.replay import ReplaySettings, make_windows, prepare
from rover_env.config import ANTI_WINDUP_FORMS, load_rover
from rover_env.generators.make_logs import make_logs
from rover_env.logs import read_log

CFG = load_rover()
ST = ReplaySettings()
OTHER = with_loop(
    CFG,
    (
        ANTI_WINDUP_FORMS.index("conditional"),
        4.0 * CFG.motor.speed_gain,
        CFG.motor.integral_gain,
        2.0 * CFG.motor.armature,
    ),
)


@pytest.fixture(scope="module")
def loops(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, FormFit]]:
    """The loop fitted on a hard drive of the model itself and of the model with ``OTHER``'s
    loop."""
    out = {}
    for key, truth in {"own": CFG, "other": OTHER}.items():
        root = tmp_path_factory.mktemp(f"loop{key}")
        paths = make_logs(
            root, {}, drives=2, seed=3, duration=40.0, truth_rover=truth, progress=False
        )
        prepared = [prepare(read_log(p), CFG, p.name, ST) for p in paths]
        windows = make_windows(prepared, ST)
        fits = fit_motor_loop(CFG, prepared, windows, ST, rs.noise_floor(prepared))
        out[key] = {f.name: f for f in fits}
    return out


def test_every_part_is_reported(loops: dict[str, dict[str, FormFit]]) -> None:
    for fits in loops.values():
        assert list(fits) == [name for name, _ in LOOP_PARTS]
        assert len({(f.gain, f.p, f.d_bic) for f in fits.values()}) == 1  # one judgement


def test_nothing_is_adopted_on_the_models_own_drive(loops: dict[str, dict[str, FormFit]]) -> None:
    assert not any(f.adopted for f in loops["own"].values()), loops["own"]


def test_another_loop_is_found_together(loops: dict[str, dict[str, FormFit]]) -> None:
    fits = loops["other"]
    assert fits["anti_windup"].adopted, fits["anti_windup"]
    assert fits["anti_windup"].labels[int(fits["anti_windup"].value)] == "conditional"
    assert fits["speed_gain"].d_bic < 0, fits["speed_gain"]
    assert 2.8 * CFG.motor.speed_gain < fits["speed_gain"].value < 5.7 * CFG.motor.speed_gain
    arm = fits["armature"].value / CFG.motor.armature
    assert 1.4 < arm < 2.9, fits["armature"]
    cfg = CFG
    for f in fits.values():
        cfg = with_form(cfg, f) if f.adopted else cfg
    assert cfg.motor.anti_windup == "conditional"
    assert cfg.motor.speed_gain == fits["speed_gain"].value


def test_the_joint_loop_is_opt_in() -> None:
    import argparse

    from rover_env.calibration.diagnose import add_cli

    ap = argparse.ArgumentParser()
    add_cli(ap.add_subparsers())
    assert not Options().joint_motor_loop
    assert not ap.parse_args(["diagnose", "a.csv", "--out", "o"]).joint_motor_loop
    args = ap.parse_args(["diagnose", "a.csv", "--out", "o", "--joint-motor-loop"])
    assert args.joint_motor_loop
