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
    OffPolicyConfig,
    PPOConfig,
    SACConfig,
    Schedule,
    TD3Config,
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


def _action_noise(cfg: OffPolicyConfig, n_actions: int) -> ActionNoise | None:
    """Gaussian or Ornstein-Uhlenbeck noise; it draws from numpy's global generator, whose
    state the checkpoints keep."""
    n = cfg.action_noise
    if n is None:
        return None
    mean, sigma = np.zeros(n_actions), n.sigma * np.ones(n_actions)
    if n.type == "normal":
        return NormalActionNoise(mean, sigma)
    return OrnsteinUhlenbeckActionNoise(mean, sigma)


def build_model(cfg: AlgoConfig, env: VecEnv) -> BaseAlgorithm:
    """A fresh model of the config's algorithm on ``env`` (CPU, unseeded: the caller seeds)."""
    if isinstance(cfg, PPOConfig):
        pk = cfg.policy_kwargs
        return PPO(
            cfg.policy,
            env,
            learning_rate=_schedule(cfg.learning_rate),
            n_steps=cfg.n_steps,
            batch_size=cfg.batch_size,
            n_epochs=cfg.n_epochs,
            gamma=cfg.gamma,
            gae_lambda=cfg.gae_lambda,
            clip_range=_schedule(cfg.clip_range),
            ent_coef=cfg.ent_coef,
            vf_coef=cfg.vf_coef,
            max_grad_norm=cfg.max_grad_norm,
            target_kl=cfg.target_kl,
            use_sde=cfg.use_sde,
            sde_sample_freq=cfg.sde_sample_freq,
            policy_kwargs={
                "net_arch": _net_arch(pk.net_arch),
                "activation_fn": _ACTIVATIONS[pk.activation],
                "log_std_init": pk.log_std_init,
                "ortho_init": pk.ortho_init,
            },
            device="cpu",
            seed=None,
        )
    opk = cfg.policy_kwargs
    policy_kwargs: dict[str, Any] = {
        "net_arch": _net_arch(opk.net_arch),
        "activation_fn": _ACTIVATIONS[opk.activation],
        "n_critics": opk.n_critics,
    }
    if opk.log_std_init is not None:
        policy_kwargs["log_std_init"] = opk.log_std_init
    shape = env.action_space.shape or (1,)
    common: dict[str, Any] = {
        "learning_rate": _schedule(cfg.learning_rate),
        "buffer_size": cfg.buffer_size,
        "learning_starts": cfg.learning_starts,
        "batch_size": cfg.batch_size,
        "tau": cfg.tau,
        "gamma": cfg.gamma,
        "train_freq": (cfg.train_freq, "step"),
        "gradient_steps": cfg.gradient_steps,
        "action_noise": _action_noise(cfg, int(np.prod(shape))),
        "policy_kwargs": policy_kwargs,
        "device": "cpu",
        "seed": None,
    }
    if isinstance(cfg, SACConfig):
        return SAC(
            cfg.policy,
            env,
            ent_coef=cfg.ent_coef,
            target_entropy=cfg.target_entropy,
            use_sde=cfg.use_sde,
            sde_sample_freq=cfg.sde_sample_freq,
            **common,
        )
    assert isinstance(cfg, TD3Config)
    return TD3(
        cfg.policy,
        env,
        policy_delay=cfg.policy_delay,
        target_policy_noise=cfg.target_policy_noise,
        target_noise_clip=cfg.target_noise_clip,
        **common,
    )
