"""The layer rule: physics -> simulation -> estimation/control/calibration -> experiments/tasks
-> envs -> policies -> benchmark -> training (import circles: tests/test_import_cycles.py)."""

from __future__ import annotations

import ast
from pathlib import Path

import rover_env

PKG = Path(rover_env.__file__).parent

# Rank of each part of the package; a module may import rover_env modules of equal or lower rank.
RANKS = {
    "rover_env.tire": 0,
    "rover_env.soil": 0,
    "rover_env.terrain": 0,
    "rover_env.rut": 0,
    "rover_env.kinematics": 0,
    "rover_env.config": 0,
    "rover_env.drive_datasheet": 0,  # a drive's datasheet -> the wheel-referred motor block
    "rover_env.logs": 0,
    "rover_env.bags": 0,  # ROS bags <-> SPEC §6 logs (rosbags, numpy)
    "rover_env.bag_map": 0,  # import-bag's topic map
    "rover_env.effects": 0,
    "rover_env.native": 0,  # C sources compiled on first use (ctypes; no mujoco)
    "rover_env.seeds": 0,
    "rover_env.executor": 0,
    "rover_env.sim": 1,
    "rover_env.warp": 1,  # MuJoCo Warp simulation and its tire-layer kernels (docs/gpu.md)
    "rover_env.warp.env": 7,  # torch from here on: the batched env, its PPO, the benchmark
    "rover_env.warp.estimator": 7,  # the slip estimator in torch, for the env
    "rover_env.warp.ppo": 7,
    "rover_env.warp.bench": 7,
    "rover_env.independent": 1,  # the SPEC-only log generator (issue 47): rover_env.logs only
    "rover_env.estimation": 2,
    "rover_env.control": 2,
    "rover_env.calibration": 2,
    "rover_env.generators": 2,  # synthetic drive logs and the drive plans they share
    "rover_env.experiments": 3,
    "rover_env.tasks": 3,  # what an episode asks: commands, setup, reward terms (no gymnasium)
    "rover_env.envs": 4,
    "rover_env.policies": 5,  # controllers and learned policies as the env runs them
    "rover_env.benchmark": 6,
    "rover_env.training": 7,
    "rover_env.cli": 8,
    "rover_env.validation": 8,
    "rover_env": 8,
}
# Third-party packages each rank may not import.
_NO_ML = {"stable_baselines3", "torch", "optuna"}
BANNED = {
    0: {"mujoco", "gymnasium", *_NO_ML},
    1: {"gymnasium", *_NO_ML},
    2: {"gymnasium", *_NO_ML},
    3: {"gymnasium", *_NO_ML},
    4: _NO_ML,
    5: _NO_ML,
    6: _NO_ML,
    7: set(),
    8: _NO_ML,
}
# The lazily loaded PPO/SAC/TD3 policy is the one module below training allowed torch/SB3.
EXEMPT = {"rover_env.policies.ppo"}


def _rank(module: str) -> int:
    best = max((k for k in RANKS if module == k or module.startswith(k + ".")), key=len)
    return RANKS[best]


def _modules() -> list[tuple[str, Path]]:
    out = []
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG.parent).with_suffix("")
        name = ".".join(rel.parts)
        out.append((name.removesuffix(".__init__"), path))
    return out


def _imports(path: Path) -> list[str]:
    names = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
    return names


def test_layer_rule() -> None:
    violations = []
    for module, path in _modules():
        rank = _rank(module)
        for imp in _imports(path):
            top = imp.split(".")[0]
            if top in BANNED[rank] and module not in EXEMPT:
                violations.append(f"{module} (rank {rank}) imports {imp}")
            if top == "rover_env" and imp != "rover_env" and _rank(imp) > rank:
                violations.append(f"{module} (rank {rank}) imports higher layer {imp}")
    assert not violations, "\n".join(violations)


def test_rule_catches_a_violation(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("import mujoco\nfrom rover_env.sim import simulator\n")
    assert "mujoco" in _imports(bad) and _rank("rover_env.sim.simulator") > _rank("rover_env.tire")


def test_tire_module_is_numpy_only() -> None:
    tops = {i.split(".")[0] for i in _imports(PKG / "tire.py")}
    assert tops <= {"numpy", "dataclasses", "typing", "collections", "math", "__future__"}, tops
