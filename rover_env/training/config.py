"""Hyperparameters of PPO, SAC and TD3: one YAML entry per env id (rl-zoo style), validated
before any training.

A typo in a hyperparameter file must fail at start-up with the key and file named, not after
an hour of training with a default silently used instead. ``load_algo_config(algo, file,
env_id)`` reads an entry of any algorithm (``ALGOS``); ``load_config`` is the PPO one.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rover_env.config import ConfigError, configs_dir, load_yaml
from rover_env.training.signature import check_hyperparams, defaults, number, parameters

ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu", "gelu", "silu")
VEC_ENVS = ("subproc", "dummy", "batch")
POLICIES = ("MlpPolicy",)
ALGOS = ("ppo", "sac", "td3")
NOISE_TYPES = ("normal", "ornstein-uhlenbeck")


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
class OffPolicyKwargs:
    """SAC/TD3 networks: one layer list for actor and critics, or ``{pi: [...], qf: [...]}``."""

    net_arch: tuple[int, ...] | dict[str, tuple[int, ...]] = (256, 256)
    activation: str = "relu"
    log_std_init: float | None = None
    """SAC only (its gSDE's initial log std); None: SB3's default."""
    n_critics: int = 2


@dataclasses.dataclass(frozen=True)
class ActionNoise:
    """Exploration noise added to the actor's action (TD3's; SAC may take one too)."""

    type: str = "normal"
    sigma: float = 0.1
    """Standard deviation in action units (the env's actions span [-1, 1])."""


@dataclasses.dataclass(frozen=True)
class AlgoConfig:
    """One env id's entry: the run's own settings, typed here, and the algorithm's arguments
    (``hyperparams``, read with ``cfg["gamma"]``), checked against its stable-baselines3
    signature (:mod:`rover_env.training.signature`) rather than declared a second time."""

    algo: str = "ppo"
    hyperparams: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    """Every argument of the SB3 class a config may set: the stated value, else SB3's
    default (schedules as :class:`Schedule`)."""
    n_timesteps: int = 1_000_000
    n_envs: int = 1
    policy: str = "MlpPolicy"
    policy_kwargs: PolicyKwargs | OffPolicyKwargs | None = None
    """None: the algorithm's default network (PPO's or SAC/TD3's)."""
    normalize: NormalizeConfig = NormalizeConfig()
    action_noise: ActionNoise | None = None
    """SAC/TD3 only: exploration noise added to the actor's action."""
    env_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    max_episode_steps: int | None = None
    eval_freq: int = 10_000
    n_eval_episodes: int = 5
    n_eval_envs: int = 1
    checkpoint_freq: int = 50_000
    vec_env: str = "subproc"

    def __post_init__(self) -> None:
        check_algo(self.algo)
        given = {**defaults(self.algo), **self.hyperparams}
        hp = check_hyperparams(self.algo, given, self.algo.upper(), _schedule)
        hp = {k: _range(self.algo, k, v, k) for k, v in hp.items()}
        object.__setattr__(self, "hyperparams", hp)
        if self.policy_kwargs is None:
            pk = PolicyKwargs() if self.algo == "ppo" else OffPolicyKwargs()
            object.__setattr__(self, "policy_kwargs", pk)

    def __getitem__(self, name: str) -> Any:
        """The SB3 argument ``name`` (stated or SB3's default)."""
        return self.hyperparams[name]

    @property
    def off_policy(self) -> bool:
        return self.algo != "ppo"

    @property
    def rollout_size(self) -> int:
        """Env steps per update (PPO: n_steps * n_envs; SAC/TD3: train_freq * n_envs):
        checkpoints fall on multiples of it."""
        return int(self["train_freq" if self.off_policy else "n_steps"]) * self.n_envs

    def to_dict(self) -> dict[str, Any]:
        """The YAML form, every SB3 argument resolved; ``load_algo_config`` reads it back to
        an equal config."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "hyperparams":
                out.update({k: x.to_yaml() if isinstance(x, Schedule) else x for k, x in v.items()})
            elif f.name == "action_noise":
                if self.off_policy:
                    out[f.name] = None if v is None else {"type": v.type, "sigma": v.sigma}
            elif f.name == "policy_kwargs":
                out[f.name] = _policy_kwargs_yaml(v)
            elif f.name == "normalize":
                norm = {g.name: getattr(v, g.name) for g in dataclasses.fields(v)}
                out[f.name] = (
                    {k: x for k, x in norm.items() if k != "enabled"} if v.enabled else False
                )
            elif f.name == "env_kwargs":
                out[f.name] = _plain(v)
            elif f.name != "algo":
                out[f.name] = v
        return out


def _policy_kwargs_yaml(pk: Any) -> dict[str, Any]:
    """Networks as lists, None-valued options left out."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(pk):
        v = getattr(pk, f.name)
        if f.name == "net_arch":
            v = {k: list(a) for k, a in v.items()} if isinstance(v, dict) else list(v)
        if v is not None:
            out[f.name] = v
    return out


def _plain(value: Any) -> Any:
    """YAML-safe copy (tuples become lists) so a resolved config can be dumped with safe_dump."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


# --------------------------------------------------------------------------- field checks


def _int(v: Any, where: str, lo: int) -> int:
    x = number(v, where)
    if x != int(x):
        raise ConfigError(f"{where}: expected an integer, got {v!r}")
    if x < lo:
        raise ConfigError(f"{where}: must be >= {lo}, got {v!r}")
    return int(x)


def _positive(v: Any, where: str) -> float:
    x = number(v, where)
    if x <= 0:
        raise ConfigError(f"{where}: must be > 0, got {v!r}")
    return x


def _nonneg(v: Any, where: str) -> float:
    x = number(v, where)
    if x < 0:
        raise ConfigError(f"{where}: must be >= 0, got {v!r}")
    return x


def _unit(v: Any, where: str) -> float:
    x = number(v, where)
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
    if isinstance(v, Schedule):
        return v
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


def _net_arch(v: Any, where: str, keys: tuple[str, ...]) -> Any:
    if isinstance(v, Mapping):
        arch_m = _mapping(v, where, set(keys))
        return {k: _layers(arch_m.get(k, []), f"{where}.{k}") for k in keys}
    return _layers(v, where)


def _policy_kwargs(v: Any, where: str) -> PolicyKwargs:
    names = {f.name for f in dataclasses.fields(PolicyKwargs)}
    m = _mapping(v, where, names)
    out: dict[str, Any] = {}
    if "net_arch" in m:
        out["net_arch"] = _net_arch(m["net_arch"], f"{where}.net_arch", ("pi", "vf"))
    if "activation" in m:
        out["activation"] = _choice(m["activation"], f"{where}.activation", ACTIVATIONS)
    if "log_std_init" in m:
        out["log_std_init"] = number(m["log_std_init"], f"{where}.log_std_init")
    if "ortho_init" in m:
        out["ortho_init"] = _bool(m["ortho_init"], f"{where}.ortho_init")
    return PolicyKwargs(**out)


def _off_policy_kwargs(v: Any, where: str, sac: bool) -> OffPolicyKwargs:
    names = {f.name for f in dataclasses.fields(OffPolicyKwargs)} - (
        set() if sac else {"log_std_init"}
    )
    m = _mapping(v, where, names)
    out: dict[str, Any] = {}
    if "net_arch" in m:
        out["net_arch"] = _net_arch(m["net_arch"], f"{where}.net_arch", ("pi", "qf"))
    if "activation" in m:
        out["activation"] = _choice(m["activation"], f"{where}.activation", ACTIVATIONS)
    if m.get("log_std_init") is not None:
        out["log_std_init"] = number(m["log_std_init"], f"{where}.log_std_init")
    if "n_critics" in m:
        out["n_critics"] = _int(m["n_critics"], f"{where}.n_critics", 1)
    return OffPolicyKwargs(**out)


def _action_noise(v: Any, where: str) -> ActionNoise | None:
    if v is None:
        return None
    m = _mapping(v, where, {"type", "sigma"})
    return ActionNoise(
        type=_choice(m.get("type", "normal"), f"{where}.type", NOISE_TYPES),
        sigma=_positive(m.get("sigma", 0.1), f"{where}.sigma"),
    )


def _auto_or_number(v: Any, where: str, nonneg: bool) -> str | float:
    """``auto``, ``auto_<number>`` (SAC's learnt entropy weight and its start) or a number."""
    if v == "auto":
        return "auto"
    if isinstance(v, str) and v.startswith("auto_") and nonneg:
        return f"auto_{_positive(v[5:], where)!r}"
    return _nonneg(v, where) if nonneg else number(v, where)


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


def _gradient_steps(v: Any, where: str) -> int:
    x = _int(v, where, -1)
    if x == 0:
        raise ConfigError(f"{where}: must be -1 (as many as env steps) or >= 1, got {v!r}")
    return x


_INT_MIN = {
    "batch_size": 2,
    "n_epochs": 1,
    "n_steps": 1,
    "buffer_size": 1,
    "learning_starts": 0,
    "train_freq": 1,
    "sde_sample_freq": -1,
    "policy_delay": 1,
    "stats_window_size": 1,
    "target_update_interval": 1,
}
_FLOAT_RANGE: dict[str, Any] = {
    "gamma": _unit,
    "gae_lambda": _unit,
    "tau": _unit,
    "vf_coef": _nonneg,
    "max_grad_norm": _positive,
    "target_kl": _positive,
    "target_policy_noise": _nonneg,
    "target_noise_clip": _nonneg,
    "gradient_steps": _gradient_steps,
    "ent_coef": lambda v, w: _auto_or_number(v, w, nonneg=True),
    "target_entropy": lambda v, w: _auto_or_number(v, w, nonneg=False),
}
"""What SB3's signature does not say: the ranges a value must lie in (its name and type it does)."""


def _range(algo: str, key: str, v: Any, where: str) -> Any:
    """``v`` checked against the range of ``key`` (and ``auto_<x>`` written as ``auto_<float>``)."""
    if v is None or isinstance(v, Schedule):
        return v
    lo = 2 if (algo, key) == ("ppo", "n_steps") else _INT_MIN.get(key)
    if lo is not None:
        return _int(v, where, lo)
    return _FLOAT_RANGE[key](v, where) if key in _FLOAT_RANGE else v


_RUN_KEYS: dict[str, Any] = {
    "n_timesteps": lambda v, w: _int(v, w, 1),
    "n_envs": lambda v, w: _int(v, w, 1),
    "policy": lambda v, w: _choice(v, w, POLICIES),
    "normalize": _normalize,
    "env_kwargs": lambda v, w: dict(_mapping(v, w, set(map(str, v or {})))),
    "max_episode_steps": lambda v, w: None if v is None else _int(v, w, 1),
    "eval_freq": lambda v, w: _int(v, w, 0),
    "n_eval_episodes": lambda v, w: _int(v, w, 1),
    "n_eval_envs": lambda v, w: _int(v, w, 1),
    "checkpoint_freq": lambda v, w: _int(v, w, 1),
    "vec_env": lambda v, w: _choice(v, w, VEC_ENVS),
}
"""The run's own settings (not SB3 arguments) and their checks."""


def check_algo(algo: str) -> str:
    if algo not in ALGOS:
        raise ConfigError(f"unknown algorithm {algo!r}; available: {', '.join(ALGOS)}")
    return algo


def parse_algo_config(algo: str, data: Any, where: str = "") -> AlgoConfig:
    """Validate one env id's entry for ``algo``; every error names ``where`` and the key."""
    check_algo(algo)
    own = {**_RUN_KEYS, "policy_kwargs": None} | ({"action_noise": None} if algo != "ppo" else {})
    m = _mapping(data, where or f"{algo.upper()} config", set(own) | set(parameters(algo)))
    key = lambda k: f"{where}.{k}" if where else k  # noqa: E731
    kwargs: dict[str, Any] = {k: _RUN_KEYS[k](v, key(k)) for k, v in m.items() if k in _RUN_KEYS}
    if "policy_kwargs" in m:
        pk = m["policy_kwargs"]
        kwargs["policy_kwargs"] = (
            _policy_kwargs(pk, key("policy_kwargs"))
            if algo == "ppo"
            else _off_policy_kwargs(pk, key("policy_kwargs"), sac=algo == "sac")
        )
    if "action_noise" in m:
        kwargs["action_noise"] = _action_noise(m["action_noise"], key("action_noise"))
    hp = check_hyperparams(algo, {k: v for k, v in m.items() if k not in own}, where, _schedule)
    hp = {k: _range(algo, k, v, key(k)) for k, v in hp.items()}
    cfg = AlgoConfig(algo=algo, hyperparams=hp, **kwargs)
    if not cfg.off_policy and cfg["batch_size"] > cfg.rollout_size:
        raise ConfigError(
            f"{where}.batch_size: {cfg['batch_size']} exceeds n_steps * n_envs = {cfg.rollout_size}"
        )
    if cfg.off_policy and cfg["batch_size"] > cfg["buffer_size"]:
        raise ConfigError(
            f"{where}.batch_size: {cfg['batch_size']} exceeds buffer_size = {cfg['buffer_size']}"
        )
    if cfg.n_eval_envs > cfg.n_eval_episodes:
        raise ConfigError(
            f"{where}.n_eval_envs: {cfg.n_eval_envs} exceeds n_eval_episodes = {cfg.n_eval_episodes}"
        )
    return cfg


def parse_config(data: Any, where: str = "") -> AlgoConfig:
    """Validate one env id's PPO entry; every error names ``where`` (file and env id) and the key."""
    return parse_algo_config("ppo", data, where)


def config_for(config: str | Path, algo: str) -> str | Path:
    """A folder of per-algorithm files (``configs/agents_soil``) names ``DIR/{algo}.yaml``."""
    p = Path(config)
    if p.is_dir():
        return p / f"{algo}.yaml"
    shipped = configs_dir() / str(config)
    if not p.suffix and shipped.is_dir():
        return shipped / f"{algo}.yaml"
    return config


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


def entries(config: str | Path) -> tuple[Path, Mapping[str, Any]]:
    """(file, env id -> raw entry) of a hyperparameter file, its ``base:`` chain merged in;
    ``.``-prefixed keys (shared YAML blocks) are left out."""
    path = resolve_config_path(config)
    data = load_yaml(path)
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path}: expected a mapping of env ids to hyperparameters")
    return path, {str(k): v for k, v in data.items() if not str(k).startswith(".")}


def env_ids(config: str | Path) -> list[str]:
    """The env ids a hyperparameter file has entries for."""
    return list(entries(config)[1])


def read_entry(config: str | Path, env_id: str) -> tuple[Path, Any]:
    """(file, raw entry for ``env_id``) of a hyperparameter file (path or shipped name)."""
    path, data = entries(config)
    if env_id not in data:
        raise ConfigError(f"{path}: no entry for env id {env_id!r}; have {sorted(data)}")
    return path, data[env_id]


def load_algo_config(algo: str, config: str | Path, env_id: str) -> AlgoConfig:
    """The ``algo`` entry for ``env_id`` in a hyperparameter file (path, shipped name, or a
    folder of ``{algo}.yaml`` files)."""
    path, entry = read_entry(config_for(config, check_algo(algo)), env_id)
    return parse_algo_config(algo, entry, f"{path}: {env_id}")


def load_config(config: str | Path, env_id: str) -> AlgoConfig:
    """The PPO entry for ``env_id`` in a hyperparameter file (path or shipped name)."""
    path, entry = read_entry(config, env_id)
    return parse_config(entry, f"{path}: {env_id}")
