"""The ``ppo:PATH``, ``sac:PATH`` and ``td3:PATH`` controllers: a stable-baselines3 policy
acting on the env's observation.

Imported only when a learned controller is asked for (``make_controller``), so the rest of the
benchmark never loads torch. PATH is a ``.zip`` saved by ``PPO.save`` (``SAC.save``,
``TD3.save``) or a run folder holding
one (``best_model.zip`` preferred, then ``final_model.zip``, ``model.zip``, or the only
``.zip``). VecNormalize statistics saved beside it (``vecnormalize.pkl`` or
``vec_normalize.pkl``; for ``best_model.zip``, ``best_vecnormalize.pkl``, the statistics it was
selected with, when present) normalise the observation as in training, frozen (no updates).

The policy must have been trained on the plain ``ProtoExplorerEnv`` observation (46 values,
``OBS_NAMES``); its action space decides the env's action layout (4 values: "wheels",
2: "sides"). Actions are the deterministic (mean) ones. If the run's ``config.yaml`` beside
the model sets ``env_kwargs.action_residual`` (``ScenarioMixEnv``), the policy's action is a
residual on a base controller (``env_kwargs.residual_base``) and is mapped the same way here;
``env_kwargs.action_schedule`` likewise makes it a gain schedule of the slip PI
(:class:`rover_env.policies.residual.Schedule`).
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from rover_env.config import load_yaml
from rover_env.envs.proto_explorer import OBS_NAMES, ProtoExplorerEnv
from rover_env.policies.memory import StallClock, stall_clock_from
from rover_env.policies.residual import Residual, Schedule

__all__ = ["PPOController", "SB3Controller", "resolve_model_path"]

Obs = npt.NDArray[np.float32]

_MODEL_NAMES = ("best_model.zip", "final_model.zip", "model.zip")
_STATS_NAMES = ("vecnormalize.pkl", "vec_normalize.pkl")


def resolve_model_path(path: str | Path) -> tuple[Path, Path | None]:
    """(model .zip, VecNormalize stats or None) for a run folder or a .zip path."""
    p = Path(path)
    if p.is_dir():
        found = [p / n for n in _MODEL_NAMES if (p / n).is_file()]
        if not found:
            zips = sorted(p.glob("*.zip"))
            if len(zips) != 1:
                raise FileNotFoundError(
                    f"{p}: no {', '.join(_MODEL_NAMES)} and {len(zips)} other .zip files"
                )
            found = zips
        model = found[0]
    elif p.is_file() or p.with_suffix(".zip").is_file():
        model = p if p.is_file() else p.with_suffix(".zip")
    else:
        raise FileNotFoundError(f"model not found: {p}")
    stats = next((model.parent / n for n in _STATS_NAMES if (model.parent / n).is_file()), None)
    best_stats = model.parent / "best_vecnormalize.pkl"
    if model.name == "best_model.zip" and best_stats.is_file():
        stats = best_stats  # the statistics the best model was selected with
    return model, stats


def _run_algo(folder: Path) -> str | None:
    """The algorithm a training run dir records (``command.txt``; before SAC/TD3: ppo)."""
    cmd = folder / "command.txt"
    if not cmd.is_file():
        return None
    data = yaml.safe_load(cmd.read_text())
    first = data[0] if isinstance(data, list) and data and isinstance(data[0], dict) else {}
    return str(first.get("algo") or "ppo")


class SB3Controller:
    """Deterministic actions of a PPO, SAC or TD3 policy from the (normalised) env observation."""

    def __init__(self, path: str | Path, name: str | None = None, algo: str = "ppo") -> None:
        import torch
        from stable_baselines3 import PPO, SAC, TD3

        classes: dict[str, Any] = {"ppo": PPO, "sac": SAC, "td3": TD3}
        if algo not in classes:
            raise ValueError(f"unknown algorithm {algo!r}; use one of {', '.join(classes)}")
        torch.set_num_threads(1)  # one benchmark worker per core
        self.model_path, self.stats_path = resolve_model_path(path)
        self.algo = algo
        self.name = name or f"{algo}:{path}"
        trained = _run_algo(self.model_path.parent)
        if trained is not None and trained != algo:
            raise ValueError(f"{path} holds a {trained} agent; use {trained}:{path}")
        try:
            self.model: Any = classes[algo].load(str(self.model_path), device="cpu")
        except (AttributeError, KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{self.model_path}: not a {algo.upper()} model ({exc})") from None
        self.normalizer: Any = None
        if self.stats_path is not None:
            with self.stats_path.open("rb") as fh:
                self.normalizer = pickle.load(fh)  # a VecNormalize without its venv
            self.normalizer.training = False
        self.residual: Residual | Schedule | None = None
        self.clock: StallClock | None = None
        self._first = True
        cfg_file = self.model_path.parent / "config.yaml"
        if cfg_file.is_file():
            data = load_yaml(cfg_file) or {}
            entry: dict[str, Any] = next(iter(data.values()), {}) or {}
            kw = entry.get("env_kwargs") or {}
            self.clock = stall_clock_from(kw.get("stall_clock"), f"{cfg_file}: stall_clock")
            if kw.get("action_residual") is not None:
                base = str(kw.get("residual_base", "open-loop"))
                ramp = float(kw.get("residual_ramp", 0.0))
                self.residual = Residual(base, float(kw["action_residual"]), ramp)
            elif kw.get("action_schedule") is not None:
                base = str(kw.get("residual_base", "slip-pi"))
                self.residual = Schedule(base, kw["action_schedule"])
        shape = tuple(self.model.action_space.shape or ())
        if isinstance(self.residual, Schedule):
            if shape != (self.residual.n_actions,):
                raise ValueError(
                    f"{self.model_path}: action space {shape}, but its action_schedule has "
                    f"{self.residual.n_actions} knob(s) ({', '.join(self.residual.knobs)})"
                )
            self.action_layout = "wheels"  # the PI drives the wheels; the policy sets its gains
        elif shape in ((4,), (2,)):
            self.action_layout = "wheels" if shape == (4,) else "sides"
        else:
            raise ValueError(f"{self.model_path}: action space {shape}, expected (4,) or (2,)")
        obs_shape = tuple(self.model.observation_space.shape or ())
        want = (len(OBS_NAMES) + (1 if self.clock is not None else 0),)
        if obs_shape != want:
            raise ValueError(
                f"{self.model_path}: observation space {obs_shape}; the benchmark feeds the "
                f"ProtoExplorerEnv observation{' and the stall clock' if self.clock else ''} "
                f"{want}"
            )

    def reset(self, env: ProtoExplorerEnv) -> None:
        """The MLP is stateless; a residual's base controller and the stall clock are reset."""
        if self.residual is not None:
            self.residual.reset(env)
        if self.clock is not None:
            self.clock.reset()
        self._first = True

    def _policy_input(self, env: ProtoExplorerEnv, obs: Obs) -> Obs:
        """The observation as the policy was trained on it: with the stall clock advanced
        (by one control step, 0 on an episode's first) when the run had one."""
        o = np.asarray(obs, dtype=np.float32)
        if self.clock is not None:
            dt = 0.0 if self._first else env.control_dt
            o = self.clock.extend(o, dt)
            self._first = False
        return o

    def action(self, env: ProtoExplorerEnv, obs: Obs) -> Obs:
        o = self._policy_input(env, obs)
        if self.normalizer is not None:
            o = np.asarray(self.normalizer.normalize_obs(o), dtype=np.float32)
        act, _ = self.model.predict(o, deterministic=True)
        a = np.asarray(act, dtype=np.float32).reshape(-1)
        if self.residual is not None:
            a = self.residual(a, env, np.asarray(obs, dtype=np.float32))
        return a

    def spread(self, obs: Obs) -> tuple[Obs, Obs] | None:
        """The policy's action mean and standard deviation in its own units (a residual
        before its base is added; PPO: before clipping, SAC: before its tanh); None for a
        policy without a Gaussian head (TD3). Why: to tell a policy held at the clip bound,
        where exploring no longer changes the action, from one that chooses its action."""
        import torch

        o = np.asarray(obs, dtype=np.float32)
        if self.clock is not None:  # the clock as of the last action, not advanced
            o = np.append(o, np.float32(self.clock.t)).astype(np.float32)
        if self.normalizer is not None:
            o = np.asarray(self.normalizer.normalize_obs(o), dtype=np.float32)
        t = torch.as_tensor(o[None])
        with torch.no_grad():
            if self.algo == "ppo":
                dist = self.model.policy.get_distribution(t).distribution
                mean, std = dist.mean, dist.stddev
            elif self.algo == "sac":
                mean, log_std, _ = self.model.policy.actor.get_action_dist_params(t)
                std = log_std.exp()
            else:
                return None
        return (
            np.asarray(mean.numpy()[0], dtype=np.float32),
            np.asarray(std.numpy()[0], dtype=np.float32),
        )


class PPOController(SB3Controller):
    """The ``ppo:PATH`` controller (:class:`SB3Controller` of a PPO model)."""

    def __init__(self, path: str | Path, name: str | None = None) -> None:
        super().__init__(path, name, algo="ppo")
