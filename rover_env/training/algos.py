"""The stable-baselines3 algorithm behind each name (``ppo``, ``sac``, ``td3``), built from its
validated config (:mod:`rover_env.training.config`)."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.noise import (
    ActionNoise,
    NormalActionNoise,
    OrnsteinUhlenbeckActionNoise,
)
from stable_baselines3.common.utils import LinearSchedule
from stable_baselines3.common.vec_env import VecEnv

from rover_env.training.config import (
    AlgoConfig,
    OffPolicyKwargs,
    PolicyKwargs,
    Schedule,
    check_algo,
)

__all__ = ["ALGO_CLASSES", "algo_class", "build_model"]

ALGO_CLASSES: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "sac": SAC, "td3": TD3}

_ACTIVATIONS = {
    "tanh": torch.nn.Tanh,
    "relu": torch.nn.ReLU,
    "elu": torch.nn.ELU,
    "leaky_relu": torch.nn.LeakyReLU,
    "gelu": torch.nn.GELU,
    "silu": torch.nn.SiLU,
}


def algo_class(algo: str) -> type[BaseAlgorithm]:
    return ALGO_CLASSES[check_algo(algo)]


def _schedule(s: Schedule) -> float | LinearSchedule:
    return LinearSchedule(s.start, 0.0, 1.0) if s.linear else s.start


def _net_arch(arch: Any) -> Any:
    return {k: list(v) for k, v in arch.items()} if isinstance(arch, dict) else list(arch)


def _action_noise(cfg: AlgoConfig, n_actions: int) -> ActionNoise | None:
    """Gaussian or Ornstein-Uhlenbeck noise; it draws from numpy's global generator, whose
    state the checkpoints keep."""
    n = cfg.action_noise
    if n is None:
        return None
    mean, sigma = np.zeros(n_actions), n.sigma * np.ones(n_actions)
    if n.type == "normal":
        return NormalActionNoise(mean, sigma)
    return OrnsteinUhlenbeckActionNoise(mean, sigma)


def _policy_kwargs(cfg: AlgoConfig) -> dict[str, Any]:
    pk = cfg.policy_kwargs
    assert isinstance(pk, PolicyKwargs | OffPolicyKwargs)  # filled in by the config
    out: dict[str, Any] = {
        "net_arch": _net_arch(pk.net_arch),
        "activation_fn": _ACTIVATIONS[pk.activation],
    }
    if isinstance(pk, PolicyKwargs):
        return {**out, "log_std_init": pk.log_std_init, "ortho_init": pk.ortho_init}
    out["n_critics"] = pk.n_critics
    if pk.log_std_init is not None:
        out["log_std_init"] = pk.log_std_init
    return out


def build_model(cfg: AlgoConfig, env: VecEnv) -> BaseAlgorithm:
    """A fresh model of the config's algorithm on ``env`` (CPU, unseeded: the caller seeds):
    the config's SB3 arguments as they are, schedules made callables."""
    kwargs: dict[str, Any] = {
        k: _schedule(v) if isinstance(v, Schedule) else v for k, v in cfg.hyperparams.items()
    }
    if cfg.off_policy:
        kwargs["train_freq"] = (kwargs["train_freq"], "step")
        shape = env.action_space.shape or (1,)
        kwargs["action_noise"] = _action_noise(cfg, int(np.prod(shape)))
    cls = ALGO_CLASSES[cfg.algo]
    return cls(
        cfg.policy, env, policy_kwargs=_policy_kwargs(cfg), device="cpu", seed=None, **kwargs
    )
