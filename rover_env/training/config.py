"""PPO hyperparameters: one YAML entry per env id (rl-zoo style), validated before any training.

A typo in a hyperparameter file must fail at start-up with the key and file named, not after
an hour of training with a default silently used instead.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from rover_env.config import ConfigError, configs_dir

ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu", "gelu", "silu")
VEC_ENVS = ("subproc", "dummy", "batch")
POLICIES = ("MlpPolicy",)


@dataclasses.dataclass(frozen=True)
class Schedule:
    """A constant or rl-zoo ``lin_<start>`` schedule (linear from start at progress 0 to 0 at the end)."""

    start: float
    linear: bool = False

    def to_yaml(self) -> float | str:
        return f"lin_{self.start!r}" if self.linear else self.start


@dataclasses.dataclass(frozen=True)
class PolicyKwargs:
    net_arch: tuple[int, ...] | dict[str, tuple[int, ...]] = (64, 64)
    activation: str = "tanh"
    log_std_init: float = 0.0
    ortho_init: bool = True


@dataclasses.dataclass(frozen=True)
class NormalizeConfig:
    """VecNormalize settings; its discount is PPO's ``gamma`` so the reward scale matches the returns."""

    enabled: bool = True
    norm_obs: bool = True
    norm_reward: bool = True
    clip_obs: float = 10.0
    clip_reward: float = 10.0
    epsilon: float = 1e-8


@dataclasses.dataclass(frozen=True)
class PPOConfig:
    n_timesteps: int = 1_000_000
    n_envs: int = 1
    policy: str = "MlpPolicy"
    learning_rate: Schedule = Schedule(3e-4)
    n_steps: int = 2048
    batch_size: int = 64
    n_epochs: int = 10
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: Schedule = Schedule(0.2)
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    target_kl: float | None = None
    use_sde: bool = False
    """Generalized state-dependent exploration (SB3's gSDE): smooth noise, a function of the
    state, redrawn every ``sde_sample_freq`` steps (-1: once per rollout)."""
    sde_sample_freq: int = -1
    policy_kwargs: PolicyKwargs = PolicyKwargs()
    normalize: NormalizeConfig = NormalizeConfig()
    env_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    max_episode_steps: int | None = None
    eval_freq: int = 10_000
    n_eval_episodes: int = 5
    n_eval_envs: int = 1
    checkpoint_freq: int = 50_000
    vec_env: str = "subproc"

    @property
    def rollout_size(self) -> int:
        """Env steps per PPO update: checkpoints fall on multiples of it."""
        return self.n_steps * self.n_envs

    def to_dict(self) -> dict[str, Any]:
        """The YAML form; ``load_config`` reads it back to an equal config."""
        pk = self.policy_kwargs
        arch: Any = (
            {k: list(v) for k, v in pk.net_arch.items()}
            if isinstance(pk.net_arch, dict)
            else list(pk.net_arch)
        )
        norm: Any = (
            {f.name: getattr(self.normalize, f.name) for f in dataclasses.fields(NormalizeConfig)}
            if self.normalize.enabled
            else False
        )
        if norm:
            del norm["enabled"]
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, Schedule):
                v = v.to_yaml()
            out[f.name] = v
        out["policy_kwargs"] = {
            "net_arch": arch,
            "activation": pk.activation,
            "log_std_init": pk.log_std_init,
            "ortho_init": pk.ortho_init,
        }
        out["normalize"] = norm
        out["env_kwargs"] = _plain(self.env_kwargs)
        return out


def _plain(value: Any) -> Any:
    """YAML-safe copy (tuples become lists) so a resolved config can be dumped with safe_dump."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


# --------------------------------------------------------------------------- field checks


def _number(v: Any, where: str) -> float:
    # PyYAML reads 3e-4 (no dot) as a string, so numeric strings are accepted.
    if isinstance(v, bool):
        raise ConfigError(f"{where}: expected a number, got {v!r}")
    if isinstance(v, str):
        try:
            v = float(v)
        except ValueError:
            raise ConfigError(f"{where}: expected a number, got {v!r}") from None
    if not isinstance(v, int | float) or not math.isfinite(v):
        raise ConfigError(f"{where}: expected a finite number, got {v!r}")
    return float(v)


def _int(v: Any, where: str, lo: int) -> int:
    x = _number(v, where)
    if x != int(x):
        raise ConfigError(f"{where}: expected an integer, got {v!r}")
    if x < lo:
        raise ConfigError(f"{where}: must be >= {lo}, got {v!r}")
    return int(x)


def _positive(v: Any, where: str) -> float:
    x = _number(v, where)
    if x <= 0:
        raise ConfigError(f"{where}: must be > 0, got {v!r}")
    return x


def _nonneg(v: Any, where: str) -> float:
    x = _number(v, where)
    if x < 0:
        raise ConfigError(f"{where}: must be >= 0, got {v!r}")
    return x


def _unit(v: Any, where: str) -> float:
    x = _number(v, where)
    if not 0 < x <= 1:
        raise ConfigError(f"{where}: must be in (0, 1], got {v!r}")
    return x


def _bool(v: Any, where: str) -> bool:
    if not isinstance(v, bool):
        raise ConfigError(f"{where}: expected true or false, got {v!r}")
    return v


def _choice(v: Any, where: str, allowed: tuple[str, ...]) -> str:
    if v not in allowed:
        raise ConfigError(f"{where}: expected one of {', '.join(allowed)}, got {v!r}")
    return str(v)


def _schedule(v: Any, where: str) -> Schedule:
    if isinstance(v, str) and v.startswith("lin_"):
        return Schedule(_positive(v[4:], where), linear=True)
    return Schedule(_positive(v, where))


def _mapping(v: Any, where: str, allowed: set[str]) -> Mapping[str, Any]:
    if v is None:
        return {}
    if not isinstance(v, Mapping):
        raise ConfigError(f"{where}: expected a mapping, got {v!r}")
    unknown = sorted(set(map(str, v)) - allowed)
    if unknown:
        raise ConfigError(
            f"{where}: unknown key(s) {', '.join(unknown)}; allowed: {', '.join(sorted(allowed))}"
        )
    return v


def _layers(v: Any, where: str) -> tuple[int, ...]:
    if not isinstance(v, list | tuple):
        raise ConfigError(f"{where}: expected a list of layer sizes, got {v!r}")
    return tuple(_int(x, f"{where}[{i}]", 1) for i, x in enumerate(v))


def _policy_kwargs(v: Any, where: str) -> PolicyKwargs:
    names = {f.name for f in dataclasses.fields(PolicyKwargs)}
    m = _mapping(v, where, names)
    out: dict[str, Any] = {}
    if "net_arch" in m:
        arch = m["net_arch"]
        if isinstance(arch, Mapping):
            arch_m = _mapping(arch, f"{where}.net_arch", {"pi", "vf"})
            out["net_arch"] = {
                k: _layers(arch_m.get(k, []), f"{where}.net_arch.{k}") for k in ("pi", "vf")
            }
        else:
            out["net_arch"] = _layers(arch, f"{where}.net_arch")
    if "activation" in m:
        out["activation"] = _choice(m["activation"], f"{where}.activation", ACTIVATIONS)
    if "log_std_init" in m:
        out["log_std_init"] = _number(m["log_std_init"], f"{where}.log_std_init")
    if "ortho_init" in m:
        out["ortho_init"] = _bool(m["ortho_init"], f"{where}.ortho_init")
    return PolicyKwargs(**out)


def _normalize(v: Any, where: str) -> NormalizeConfig:
    if isinstance(v, bool):
        return NormalizeConfig(enabled=v)
    names = {f.name for f in dataclasses.fields(NormalizeConfig)} - {"enabled"}
    m = _mapping(v, where, names)
    out: dict[str, Any] = {}
    for k in ("norm_obs", "norm_reward"):
        if k in m:
            out[k] = _bool(m[k], f"{where}.{k}")
    for k in ("clip_obs", "clip_reward", "epsilon"):
        if k in m:
            out[k] = _positive(m[k], f"{where}.{k}")
    return NormalizeConfig(**out)


_CHECKS: dict[str, Any] = {
    "n_timesteps": lambda v, w: _int(v, w, 1),
    "n_envs": lambda v, w: _int(v, w, 1),
    "policy": lambda v, w: _choice(v, w, POLICIES),
    "learning_rate": _schedule,
    "n_steps": lambda v, w: _int(v, w, 2),
    "batch_size": lambda v, w: _int(v, w, 2),
    "n_epochs": lambda v, w: _int(v, w, 1),
    "gamma": _unit,
    "gae_lambda": _unit,
    "clip_range": _schedule,
    "ent_coef": _nonneg,
    "vf_coef": _nonneg,
    "max_grad_norm": _positive,
    "target_kl": lambda v, w: None if v is None else _positive(v, w),
    "use_sde": lambda v, w: _bool(v, w),
    "sde_sample_freq": lambda v, w: _int(v, w, -1),
    "policy_kwargs": _policy_kwargs,
    "normalize": _normalize,
    "env_kwargs": lambda v, w: dict(_mapping(v, w, set(map(str, v or {})))),
    "max_episode_steps": lambda v, w: None if v is None else _int(v, w, 1),
    "eval_freq": lambda v, w: _int(v, w, 0),
    "n_eval_episodes": lambda v, w: _int(v, w, 1),
    "n_eval_envs": lambda v, w: _int(v, w, 1),
    "checkpoint_freq": lambda v, w: _int(v, w, 1),
    "vec_env": lambda v, w: _choice(v, w, VEC_ENVS),
}
assert set(_CHECKS) == {f.name for f in dataclasses.fields(PPOConfig)}


def parse_config(data: Any, where: str = "") -> PPOConfig:
    """Validate one env id's entry; every error names ``where`` (file and env id) and the key."""
    m = _mapping(data, where or "PPO config", set(_CHECKS))
    kwargs = {k: _CHECKS[k](v, f"{where}.{k}" if where else k) for k, v in m.items()}
    cfg = PPOConfig(**kwargs)
    if cfg.batch_size > cfg.rollout_size:
        raise ConfigError(
            f"{where}.batch_size: {cfg.batch_size} exceeds n_steps * n_envs = {cfg.rollout_size}"
        )
    if cfg.n_eval_envs > cfg.n_eval_episodes:
        raise ConfigError(
            f"{where}.n_eval_envs: {cfg.n_eval_envs} exceeds n_eval_episodes = {cfg.n_eval_episodes}"
        )
    return cfg


def resolve_config_path(config: str | Path) -> Path:
    """A YAML path, or the name of a shipped file in ``configs/`` (e.g. ``"ppo"``)."""
    p = Path(config)
    if p.suffix in (".yaml", ".yml") or p.exists():
        if not p.is_file():
            raise ConfigError(f"hyperparameter file not found: {p}")
        return p
    shipped = configs_dir() / f"{config}.yaml"
    if not shipped.is_file():
        raise ConfigError(f"no hyperparameter file {config!r} (not a path, not in {configs_dir()})")
    return shipped


def load_config(config: str | Path, env_id: str) -> PPOConfig:
    """The entry for ``env_id`` in a hyperparameter file (path or shipped name)."""
    path = resolve_config_path(config)
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: malformed YAML: {exc}") from None
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path}: expected a mapping of env ids to hyperparameters")
    if env_id not in data:
        ids = sorted(str(k) for k in data if not str(k).startswith("."))
        raise ConfigError(f"{path}: no entry for env id {env_id!r}; have {ids}")
    return parse_config(data[env_id], f"{path}: {env_id}")
