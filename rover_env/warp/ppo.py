"""A compact PPO in torch for :class:`rover_env.warp.env.WarpRoverEnv`: rollouts, advantages
and updates stay on the env's device.

Why not rsl_rl (the usual choice for GPU envs): it is one more pinned dependency beside
``torch==2.13.0`` and stable-baselines3 (its ``VecEnv`` interface changed between major
versions), and what this env needs of it is ~150 lines: clipped PPO with GAE, a Gaussian
policy with a learned state-independent log-std, observation normalisation and an
adaptive learning rate (KL target), as rsl_rl's defaults do.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass

import torch
from torch import nn

from rover_env.warp.env import ACT_DIM, OBS_DIM, WarpRoverEnv


@dataclass(frozen=True)
class PPOConfig:
    """PPO settings (rsl_rl's defaults where they apply)."""

    steps_per_env: int = 24
    epochs: int = 5
    minibatches: int = 4
    gamma: float = 0.99
    lam: float = 0.95
    clip: float = 0.2
    lr: float = 1e-3
    desired_kl: float = 0.01
    entropy: float = 0.0
    value_coef: float = 1.0
    max_grad_norm: float = 1.0
    hidden: tuple[int, ...] = (128, 128)
    init_log_std: float = -0.5
    seed: int = 0


def _mlp(sizes: list[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in itertools.pairwise(sizes):
        layers += [nn.Linear(a, b), nn.ELU()]
    return nn.Sequential(*layers[:-1])


class ActorCritic(nn.Module):
    """Gaussian policy (tanh-free: the env clips actions) and value function, with running
    observation normalisation."""

    def __init__(self, cfg: PPOConfig) -> None:
        super().__init__()
        self.actor = _mlp([OBS_DIM, *cfg.hidden, ACT_DIM])
        self.critic = _mlp([OBS_DIM, *cfg.hidden, 1])
        self.log_std = nn.Parameter(torch.full((ACT_DIM,), cfg.init_log_std))
        self.obs_mean: torch.Tensor
        self.obs_var: torch.Tensor
        self.obs_count: torch.Tensor
        self.register_buffer("obs_mean", torch.zeros(OBS_DIM))
        self.register_buffer("obs_var", torch.ones(OBS_DIM))
        self.register_buffer("obs_count", torch.tensor(1e-4))

    def update_norm(self, obs: torch.Tensor) -> None:
        mean, var, n = obs.mean(0), obs.var(0, unbiased=False), obs.shape[0]
        tot = self.obs_count + n
        delta = mean - self.obs_mean
        self.obs_mean += delta * n / tot
        self.obs_var = (self.obs_var * self.obs_count + var * n) / tot + delta**2 * (
            self.obs_count * n / tot**2
        )
        self.obs_count = tot

    def norm(self, obs: torch.Tensor) -> torch.Tensor:
        return ((obs - self.obs_mean) / torch.sqrt(self.obs_var + 1e-8)).clamp(-10, 10)

    def dist(self, obs: torch.Tensor) -> torch.distributions.Normal:
        return torch.distributions.Normal(self.actor(self.norm(obs)), self.log_std.exp())

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.critic(self.norm(obs)).squeeze(-1)

    def act(self, obs: torch.Tensor) -> torch.Tensor:
        """The deterministic action (the mean)."""
        return self.actor(self.norm(obs))


def train(
    env: WarpRoverEnv,
    iterations: int,
    cfg: PPOConfig | None = None,
    log: Callable[[dict[str, float]], None] | None = None,
) -> tuple[ActorCritic, list[dict[str, float]]]:
    """PPO on ``env`` for ``iterations`` rollouts; the policy and a row per iteration
    (mean reward per step, env steps per second of the rollout and of the whole iteration)."""
    cfg = cfg or PPOConfig()
    torch.manual_seed(cfg.seed)
    dev, n, T = env.device, env.n, cfg.steps_per_env
    ac = ActorCritic(cfg).to(dev)
    opt = torch.optim.Adam(ac.parameters(), lr=cfg.lr)
    lr = cfg.lr
    obs = env.reset()
    buf_obs = torch.zeros(T, n, OBS_DIM, device=dev)
    buf_act = torch.zeros(T, n, ACT_DIM, device=dev)
    buf_logp = torch.zeros(T, n, device=dev)
    buf_rew = torch.zeros(T, n, device=dev)
    buf_done = torch.zeros(T, n, device=dev)
    buf_val = torch.zeros(T + 1, n, device=dev)
    rows = []
    for it in range(iterations):
        t0 = time.perf_counter()
        with torch.no_grad():
            for k in range(T):
                ac.update_norm(obs)
                d = ac.dist(obs)
                a = d.sample()
                buf_obs[k], buf_act[k], buf_logp[k] = obs, a, d.log_prob(a).sum(-1)
                buf_val[k] = ac.value(obs)
                obs, rew, term, trunc = env.step(a)
                # a time limit is not a failure: bootstrap it with the value of where it was
                buf_rew[k] = rew + cfg.gamma * torch.where(trunc, buf_val[k], 0.0)
                buf_done[k] = (term | trunc).float()
            buf_val[T] = ac.value(obs)
            if dev.type == "cuda":
                torch.cuda.synchronize(dev)
            t_roll = time.perf_counter() - t0
            adv = torch.zeros(T, n, device=dev)
            last = torch.zeros(n, device=dev)
            for k in reversed(range(T)):
                nonterm = 1.0 - buf_done[k]
                delta = buf_rew[k] + cfg.gamma * buf_val[k + 1] * nonterm - buf_val[k]
                last = delta + cfg.gamma * cfg.lam * nonterm * last
                adv[k] = last
            ret = adv + buf_val[:T]
        b_obs, b_act = buf_obs.reshape(T * n, -1), buf_act.reshape(T * n, -1)
        b_logp, b_adv, b_ret = buf_logp.reshape(-1), adv.reshape(-1), ret.reshape(-1)
        b_adv = (b_adv - b_adv.mean()) / (b_adv.std() + 1e-8)
        size = T * n // cfg.minibatches
        for _ in range(cfg.epochs):
            perm = torch.randperm(T * n, device=dev)
            for j in range(cfg.minibatches):
                idx = perm[j * size : (j + 1) * size]
                d = ac.dist(b_obs[idx])
                logp = d.log_prob(b_act[idx]).sum(-1)
                ratio = torch.exp(logp - b_logp[idx])
                s1, s2 = ratio * b_adv[idx], ratio.clamp(1 - cfg.clip, 1 + cfg.clip) * b_adv[idx]
                v_loss = (ac.value(b_obs[idx]) - b_ret[idx]).pow(2).mean()
                ent = d.entropy().sum(-1).mean()
                loss = -torch.min(s1, s2).mean() + cfg.value_coef * v_loss - cfg.entropy * ent
                with torch.no_grad():  # rsl_rl's adaptive rate: keep the KL near its target
                    kl = (b_logp[idx] - logp).mean()
                    if kl > 2 * cfg.desired_kl:
                        lr = max(1e-5, lr / 1.5)
                    elif kl < cfg.desired_kl / 2:
                        lr = min(1e-2, lr * 1.5)
                for g in opt.param_groups:
                    g["lr"] = lr
                opt.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(ac.parameters(), cfg.max_grad_norm)
                opt.step()
        if dev.type == "cuda":
            torch.cuda.synchronize(dev)
        t_all = time.perf_counter() - t0
        row = {
            "iteration": float(it),
            "mean_reward": float(buf_rew.mean()),
            "rollout_steps_per_s": T * n / t_roll,
            "steps_per_s": T * n / t_all,
        }
        rows.append(row)
        if log is not None:
            log(row)
    return ac, rows
