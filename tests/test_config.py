"""Typed configuration: clear errors that name the key or file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from rover_env.config import ConfigError, RoverConfig, load_rover, load_terrain
from rover_env.terrain import Terrain


def _write(tmp_path: Path, data: dict) -> Path:
    p = tmp_path / "rover.yaml"
    p.write_text(yaml.safe_dump(data))
    return p


def test_defaults_load() -> None:
    cfg = load_rover()
    assert isinstance(cfg, RoverConfig)
    assert cfg.geometry.wheel_radius == 0.085
    assert cfg.tire.C_z == 1000.0


def test_unknown_key_is_named(tmp_path: Path) -> None:
    p = _write(tmp_path, {"geometry": {"wheel_radiuss": 0.1}})
    with pytest.raises(ConfigError, match=r"rover\.yaml.*geometry.*wheel_radiuss"):
        load_rover(p)


def test_negative_mass_is_named(tmp_path: Path) -> None:
    p = _write(tmp_path, {"masses": {"wheel": -0.35}})
    with pytest.raises(ConfigError, match=r"masses\.wheel"):
        load_rover(p)


def test_negative_friction_is_named(tmp_path: Path) -> None:
    p = _write(tmp_path, {"tire": {"mu_x": -0.4}})
    with pytest.raises(ConfigError, match=r"tire.*mu_x"):
        load_rover(p)


def test_wrong_type_is_named(tmp_path: Path) -> None:
    p = _write(tmp_path, {"sim": {"timestep": "fast"}})
    with pytest.raises(ConfigError, match=r"sim\.timestep.*number"):
        load_rover(p)


def test_missing_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"nope\.yaml"):
        load_rover(tmp_path / "nope.yaml")
    with pytest.raises(ConfigError, match="no shipped terrain configuration named 'lava'"):
        load_terrain("lava")


def test_malformed_yaml_is_named(tmp_path: Path) -> None:
    p = tmp_path / "bad.yaml"
    p.write_text("geometry: [unclosed\n")
    with pytest.raises(ConfigError, match=r"bad\.yaml.*malformed YAML"):
        load_rover(p)


def test_extensions_are_validated_against_the_catalogue(tmp_path: Path) -> None:
    # Extensions come from rover_env.effects; anything else is refused naming the key.
    assert load_rover(
        _write(tmp_path, {"extensions": {"rolling_resistance": {"c_rr": 0.05}}})
    ).extensions == {"rolling_resistance": {"c_rr": 0.05}}
    with pytest.raises(ConfigError, match="rolling_resistence"):
        load_rover(_write(tmp_path, {"extensions": {"rolling_resistence": {"c_rr": 0.05}}}))
    with pytest.raises(ConfigError, match=r"extensions\.rolling_resistance\.c_rr"):
        load_rover(_write(tmp_path, {"extensions": {"rolling_resistance": {"c_rr": 5.0}}}))


def test_wheel_radius_is_a_configuration_value(tmp_path: Path) -> None:
    p = _write(tmp_path, {"geometry": {"wheel_radius": 0.17, "axle_spacing": 0.5}})
    cfg = load_rover(p)
    assert cfg.geometry.wheel_radius == 0.17


def test_joint_and_mass_heights_are_configuration_values(tmp_path: Path) -> None:
    """Heights SPEC does not give: a rover's own go in its YAML, and one below the ground
    or above the chassis is refused naming the key."""
    from rover_env.sim.model import robot_xml, segment_inertia

    cfg = load_rover(_write(tmp_path, {"geometry": {"joint_height": 0.05, "com_height": 0.03}}))
    assert (cfg.geometry.joint_height, cfg.geometry.com_height) == (0.05, 0.03)
    assert [segment_inertia(cfg, s).com[2] for s in (1, 2, 3)] == [0.03] * 3
    assert 'pos="0.18 0 0.05"' in robot_xml(cfg)
    nominal = load_rover()
    assert nominal.geometry.com_height is None and nominal.geometry.joint_height == 0.0
    assert 0.07 < segment_inertia(nominal, 1).com[2] < 0.1  # the chassis box's and motors'
    for key, bad in (("joint_height", -0.1), ("com_height", 0.5), ("com_height", float("nan"))):
        with pytest.raises(ConfigError, match=rf"geometry\.{key}"):
            load_rover(_write(tmp_path, {"geometry": {key: bad}}))


def test_terrain_friction_patch_validation(tmp_path: Path) -> None:
    p = tmp_path / "t.yaml"
    p.write_text(
        yaml.safe_dump(
            {"patches": [{"name": "ice", "center": [0, 0], "size": [1, 1], "mu_x": 0, "mu_y": 0.1}]}
        )
    )
    with pytest.raises(ConfigError, match=r"t\.yaml.*ice.*mu_x"):
        load_terrain(p)


def test_bumps_starting_mid_wave_are_a_ledge_and_refused(tmp_path: Path) -> None:
    """Stop 43: soft-patch's ripples began at x = 1 m at sin(2 pi / 3), a 7.8 cm ledge of sand
    the rover hit at ~1 kN; the sine counts from the origin, so the phase must put a zero at
    the start. The error names the file, the key and the phase that fixes it."""
    bump = {"amplitude": 0.09, "wavelength": 3.0, "direction_deg": 0.0, "start": 1.0}
    p = tmp_path / "t.yaml"
    p.write_text(yaml.safe_dump({"bumps": [bump]}))
    with pytest.raises(ConfigError, match=r"t\.yaml.*bumps\[0\].*\+77\.9 mm ledge.*phase: -2\.09"):
        load_terrain(p)
    p.write_text(yaml.safe_dump({"bumps": [{**bump, "phase": -2.0943951024}]}))
    terrain = Terrain(load_terrain(p))
    h = terrain.height(np.array([1.0 - 1e-9, 1.0 + 1e-9, 1.75]), np.zeros(3))
    assert abs(h[1] - h[0]) < 1e-6  # continuous at the start
    assert h[2] == pytest.approx(0.09)  # and rising to the first crest a quarter wave on
    # a bump field that starts on a zero of its own sine needs no phase (the shipped bumps)
    p.write_text(yaml.safe_dump({"bumps": [{**bump, "wavelength": 1.0}]}))
    assert load_terrain(p).bumps[0].phase == 0.0


def test_every_shipped_ground_is_continuous() -> None:
    """No shipped terrain or scenario starts a bump field mid-wave (loading validates it)."""
    from rover_env.benchmark.scenarios import load_scenario, scenario_names

    root = Path(__file__).resolve().parents[1] / "configs"
    for f in sorted((root / "terrain").glob("*.yaml")):
        load_terrain(f)
    names = list(scenario_names()) + [str(f) for f in (root / "scenarios_train").glob("*.yaml")]
    assert "soft-patch" in names
    for name in names:
        cfg = load_scenario(name).episode(1000).terrain
        ground = Terrain(cfg)
        for b in cfg.bumps:  # just before and after the start, along the bumps' direction
            s = np.array([b.start - 1e-9, b.start + 1e-9])
            th = np.radians(b.direction_deg)
            h = ground.height(s * np.cos(th), s * np.sin(th))
            assert abs(h[1] - h[0]) < 1e-4, (name, b)
