"""Widen a residual PPO agent's authority without changing what it does.

A residual agent's env action is ``base + scale * clip(a, -1, 1)`` (``env_kwargs.action_residual``,
:class:`rover_env.policies.residual.Residual`). With ``scale`` 0.5 of the 4 rad/s range the
policy can take at most 2 rad/s off the base's targets: on soft-patch, where the base drives
the wheels at about 3.5 rad/s, a rover stalled on a ripple's face cannot stop its wheels, and
keeps digging (issue 18, stop 27); the slip PI ramps them to 0 and retries.

:func:`widen_residual` writes a copy of the agent whose scale is ``new_scale`` and whose
Gaussian policy is rescaled by ``k = old / new``: the mean's output layer (``action_net``)
times k and ``log_std`` plus ln k. Its env actions are then the old agent's wherever the old
mean lay inside [-1, 1], and the exploration noise in rad/s is unchanged; only where the old
mean was clipped does the new one reach further. A fine-tune (``--init-from``) of the copy
starts from the same driving with the wider range open. ``noise_factor`` f > 1 also widens
the exploration (``log_std`` plus ln f): the deterministic actions stay the old agent's, the
fine-tune explores f times further (issue 18, stop 36: a stalled agent explored ±0.24 rad/s
where stopping is a 4 rad/s move).

PPO only: SAC and TD3 squash their actions with tanh, which no linear rescaling preserves.
"""

from __future__ import annotations

import math
import pickle
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import torch
import yaml
from stable_baselines3 import PPO

from rover_env.config import ConfigError, load_yaml

__all__ = ["add_stall_clock", "widen_residual"]


def _agent_config(src: Path) -> tuple[Path, str, dict[str, Any]]:
    """(config file, env id, its entry) of an agent or run folder's ``config.yaml``."""
    cfg_file = src / "config.yaml"
    data = load_yaml(cfg_file)
    if not isinstance(data, dict) or len(data) != 1:
        raise ConfigError(f"{cfg_file}: expected one env id entry")
    ((env_id, entry),) = data.items()
    return cfg_file, str(env_id), dict(entry or {})


def _require_ppo(src: Path) -> None:
    """Only a PPO agent's Gaussian head can be rescaled or given an input (SAC/TD3: tanh)."""
    if (src / "command.txt").is_file() and "algo: ppo" not in (src / "command.txt").read_text():
        raise ConfigError(f"{src}: only a PPO agent can be widened (tanh-squashed SAC/TD3 cannot)")


def widen_residual(
    agent: str | Path, new_scale: float, out: str | Path, noise_factor: float = 1.0
) -> Path:
    """Copy ``agent`` (an agent or run folder: model, observation statistics, ``config.yaml``) to
    ``out`` with its residual scale ``new_scale`` and its exploration noise times
    ``noise_factor`` (module docstring); returns ``out``."""
    src, dst = Path(agent), Path(out)
    cfg_file, env_id, entry = _agent_config(src)
    kw: dict[str, Any] = dict(entry.get("env_kwargs") or {})
    old = kw.get("action_residual")
    if old is None:
        raise ConfigError(f"{cfg_file}: {env_id}.env_kwargs.action_residual is not set")
    if not (isinstance(new_scale, int | float) and 0 < new_scale <= 2):
        raise ConfigError(f"new_scale must be in (0, 2], got {new_scale!r}")
    if not (isinstance(noise_factor, int | float) and 0 < noise_factor <= 10):
        raise ConfigError(f"noise_factor must be in (0, 10], got {noise_factor!r}")
    _require_ppo(src)
    if dst.exists():
        raise ConfigError(f"{dst} already exists")
    k = float(old) / float(new_scale)

    from rover_env.policies.ppo import resolve_model_path

    model_p, stats_p = resolve_model_path(src)
    if stats_p is None:
        raise ConfigError(f"{src}: no observation statistics beside {model_p.name}")
    model = PPO.load(str(model_p), device="cpu")
    sd = model.policy.state_dict()
    with torch.no_grad():
        sd["action_net.weight"] = sd["action_net.weight"] * k
        sd["action_net.bias"] = sd["action_net.bias"] * k
        sd["log_std"] = sd["log_std"] + math.log(k) + math.log(noise_factor)
    model.policy.load_state_dict(sd)

    dst.mkdir(parents=True)
    model.save(str(dst / "model.zip"))
    shutil.copy2(stats_p, dst / "vecnormalize.pkl")
    kw["action_residual"] = float(new_scale)
    entry = {**entry, "env_kwargs": kw}
    head = (
        f"# {src} with its residual widened from {old} to {new_scale} of the wheel-speed range\n"
        f"# (rover_env.training.widen: action_net and log_std rescaled by {k:g}"
        + (f", exploration noise x {noise_factor:g})\n" if noise_factor != 1 else ")\n")
    )
    (dst / "config.yaml").write_text(head + yaml.safe_dump({env_id: entry}, sort_keys=False))
    (dst / "widened_from.yaml").write_text(
        yaml.safe_dump(
            {
                "agent": str(src),
                "model": model_p.name,
                "old_scale": float(old),
                "new_scale": float(new_scale),
                "noise_factor": float(noise_factor),
            }
        )
    )
    return dst


def add_stall_clock(agent: str | Path, out: str | Path, spec: Any = True) -> Path:
    """Copy the PPO ``agent`` to ``out`` with the stall clock (:mod:`rover_env.policies.memory`,
    ``spec`` as ``env_kwargs.stall_clock``) as a 47th input whose weights are zero, so the copy
    acts exactly as the agent until a fine-tune (``--init-from``) learns to read the clock.
    The clock's normalisation starts at mean 0 s, standard deviation 2 s; the optimiser starts
    afresh (its moments have the old input's shape). Returns ``out``."""
    from gymnasium import spaces

    from rover_env.policies.memory import stall_clock_from
    from rover_env.policies.ppo import resolve_model_path

    src, dst = Path(agent), Path(out)
    cfg_file, env_id, entry = _agent_config(src)
    kw: dict[str, Any] = dict(entry.get("env_kwargs") or {})
    if kw.get("stall_clock"):
        raise ConfigError(f"{cfg_file}: {env_id}.env_kwargs.stall_clock is already set")
    _require_ppo(src)
    try:
        stall_clock_from(spec)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    if dst.exists():
        raise ConfigError(f"{dst} already exists")
    model_p, stats_p = resolve_model_path(src)
    if stats_p is None:
        raise ConfigError(f"{src}: no observation statistics beside {model_p.name}")
    model: Any = PPO.load(str(model_p), device="cpu")
    n_old = int(model.observation_space.shape[0])
    space = spaces.Box(-np.inf, np.inf, (n_old + 1,), dtype=np.float32)
    sd = model.policy.state_dict()
    firsts = [k for k, v in sd.items() if k.endswith(".0.weight") and v.shape[-1] == n_old]
    if not firsts:
        raise ConfigError(f"{model_p}: no first layer taking the {n_old} observations")
    with torch.no_grad():
        for k in firsts:
            sd[k] = torch.cat([sd[k], torch.zeros(sd[k].shape[0], 1)], dim=1)
    policy = model.policy_class(space, model.action_space, model.lr_schedule, **model.policy_kwargs)
    policy.load_state_dict(sd)
    model.policy = policy
    model.observation_space = space
    dst.mkdir(parents=True)
    model.save(str(dst / "model.zip"))
    with stats_p.open("rb") as fh:
        stats = pickle.load(fh)
    stats.obs_rms.mean = np.append(stats.obs_rms.mean, 0.0)
    stats.obs_rms.var = np.append(stats.obs_rms.var, 4.0)
    stats.observation_space = space
    # a loaded VecNormalize lacks what its __getstate__ drops; give it back empty to re-pickle
    stats.class_attributes, stats.returns = {}, None
    with (dst / "vecnormalize.pkl").open("wb") as fh:
        pickle.dump(stats, fh)
    kw["stall_clock"] = spec
    entry = {**entry, "env_kwargs": kw}
    head = (
        f"# {src} with the stall clock as a 47th input of zero weight (rover_env.training.widen)\n"
    )
    (dst / "config.yaml").write_text(head + yaml.safe_dump({env_id: entry}, sort_keys=False))
    (dst / "widened_from.yaml").write_text(
        yaml.safe_dump({"agent": str(src), "model": model_p.name, "stall_clock": spec})
    )
    return dst
