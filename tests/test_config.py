"""Typed configuration: clear errors that name the key or file."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from rover_env.config import ConfigError, RoverConfig, load_rover, load_terrain


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


def test_terrain_friction_patch_validation(tmp_path: Path) -> None:
    p = tmp_path / "t.yaml"
    p.write_text(
        yaml.safe_dump(
            {"patches": [{"name": "ice", "center": [0, 0], "size": [1, 1], "mu_x": 0, "mu_y": 0.1}]}
        )
    )
    with pytest.raises(ConfigError, match=r"t\.yaml.*ice.*mu_x"):
        load_terrain(p)
