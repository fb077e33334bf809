"""One YAML loader: ``base:`` inheritance (deep merge, lists and ``!replace`` mappings replace,
cycles refused) and errors naming the file and the key."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from rover_env.config import (
    BASE_KEY,
    ConfigError,
    Replace,
    base_path,
    configs_dir,
    load_rover,
    load_terrain,
    load_yaml,
    read_yaml,
)
from rover_env.training.config import env_ids, load_algo_config


def _files(tmp_path: Path, **texts: str) -> dict[str, Path]:
    out = {}
    for name, text in texts.items():
        p = tmp_path / f"{name}.yaml"
        p.write_text(text)
        out[name] = p
    return out


def test_base_deep_merges_mappings_and_replaces_lists(tmp_path: Path) -> None:
    f = _files(
        tmp_path,
        a="x: {p: 1, q: [1, 2], r: {s: 1, t: 2}}\nmix: {u: 1.0, v: 2.0}\n",
        b="base: a.yaml\nx: {q: [3], r: {t: 5}}\nmix: !replace {v: 2.0, u: 1.0}\nnew: !replace {w: 1}\n",
    )
    data = load_yaml(f["b"])
    assert data == {
        "x": {"p": 1, "q": [3], "r": {"s": 1, "t": 5}},
        "mix": {"v": 2.0, "u": 1.0},
        "new": {"w": 1},
    }
    assert list(data["mix"]) == ["v", "u"]  # !replace keeps the variant's order
    assert type(data["new"]) is dict and yaml.safe_dump(data)  # plain, dumpable mappings
    assert BASE_KEY not in data


def test_base_chain_and_subfolder(tmp_path: Path) -> None:
    sub = tmp_path / "sub"
    sub.mkdir()
    _files(tmp_path, root="k: 1\nm: {a: 1}\n")
    (sub / "mid.yaml").write_text("base: ../root.yaml\nm: {b: 2}\n")
    (sub / "leaf.yaml").write_text("base: mid.yaml\nk: 3\n")
    assert load_yaml(sub / "leaf.yaml") == {"k": 3, "m": {"a": 1, "b": 2}}


def test_base_cycle_is_refused_naming_the_chain(tmp_path: Path) -> None:
    f = _files(tmp_path, a="base: b.yaml\nk: 1\n", b="base: c.yaml\n", c="base: a.yaml\n")
    with pytest.raises(
        ConfigError, match=r"circular chain .*a\.yaml -> .*b\.yaml -> .*c\.yaml -> .*a\.yaml"
    ):
        load_yaml(f["a"])
    selfref = _files(tmp_path, s="base: s.yaml\n")["s"]
    with pytest.raises(ConfigError, match="circular chain"):
        load_yaml(selfref)


def test_missing_or_bad_base_is_named(tmp_path: Path) -> None:
    f = _files(tmp_path, a="base: nowhere.yaml\n", b="base: [1]\n")
    with pytest.raises(ConfigError, match=r"a\.yaml: base: 'nowhere\.yaml'"):
        load_yaml(f["a"])
    with pytest.raises(ConfigError, match=r"b\.yaml: base: expected a file name"):
        load_yaml(f["b"])


def test_errors_name_the_variant_file_and_key(tmp_path: Path) -> None:
    base = configs_dir() / "rover" / "proto_explorer.yaml"
    bad = tmp_path / "heavy.yaml"
    bad.write_text(f"base: {base}\nmasses: {{wheel: -1.0}}\n")
    with pytest.raises(ConfigError, match=r"heavy\.yaml: .*masses\.wheel"):
        load_rover(bad)
    typo = tmp_path / "typo.yaml"
    typo.write_text(f"base: {configs_dir() / 'terrain' / 'flat.yaml'}\nroughness: {{rmss: 1}}\n")
    with pytest.raises(ConfigError, match=r"typo\.yaml: roughness: unknown key\(s\) rmss"):
        load_terrain(typo)


def test_a_variant_equals_the_full_file_it_abbreviates(tmp_path: Path) -> None:
    agent = configs_dir() / "agents" / "axle-schedule.yaml"
    env_id = env_ids(agent)[0]
    ft = tmp_path / "ft.yaml"
    ft.write_text(f"base: {agent}\n{env_id}:\n  learning_rate: 1.0e-4\n")
    full = tmp_path / "full.yaml"
    full.write_text(yaml.safe_dump({env_id: load_yaml(ft)[env_id]}))
    assert load_algo_config("ppo", ft, env_id) == load_algo_config("ppo", full, env_id)
    assert load_algo_config("ppo", ft, env_id)["learning_rate"].start == 1e-4  # the variant's own
    assert load_algo_config("ppo", ft, env_id)["gamma"] == 0.97  # from its base


def _leaves(over: object, base: object, path: str) -> list[str]:
    """Keys a variant states with the value its base already has."""
    if isinstance(over, Replace):
        return []  # a whole mapping, restated for its order
    if isinstance(over, dict) and isinstance(base, dict):
        return [
            p
            for k, v in over.items()
            if k != BASE_KEY and k in base
            for p in _leaves(v, base[k], f"{path}.{k}")
        ]
    return [path] if over == base and type(over) is type(base) else []


def test_shipped_variants_state_only_what_differs(tmp_path: Path) -> None:
    """A shipped ``base:`` variant restates no value its base already has (the check itself is
    shown to catch one on a made-up variant: no shipped file is a variant today)."""
    base = tmp_path / "base.yaml"
    base.write_text("a: {b: 1, c: 2}\n")
    redundant = {BASE_KEY: str(base), "a": {"b": 1, "c": 3}}
    assert _leaves(redundant, read_yaml(base), "") == [".a.b"]
    variants = [
        p for p in sorted(configs_dir().rglob("*.yaml")) if "\nbase:" in "\n" + p.read_text()
    ]
    repeated = []
    for p in variants:
        own = read_yaml(p)
        base_data = load_yaml(base_path(own[BASE_KEY], p))
        repeated += [f"{p.name}{k}" for k in _leaves(own, base_data, "")]
    assert not repeated, repeated


def test_merge_key_lists_are_refused_with_file_and_line(tmp_path: Path) -> None:
    """``<<: [*a, *b]`` resolves a shared key one way in PyYAML 6.0.3, the other in 6.0.4:
    refused, naming the file and the line; a single ``<<: *a`` still merges."""
    (f,) = _files(
        tmp_path,
        bad="a: &a {x: 1}\nb: &b {x: 2}\nc:\n  <<: [*a, *b]\n  y: 3\n",
    ).values()
    with pytest.raises(ConfigError, match=r"(?s)bad\.yaml.*merge key takes one mapping.*line 4"):
        read_yaml(f)
    (g,) = _files(tmp_path, good="a: &a {x: 1}\nc:\n  <<: *a\n  y: 3\n").values()
    assert read_yaml(g)["c"] == {"x": 1, "y": 3}
