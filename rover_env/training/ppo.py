"""PPO training of the rover env from a YAML hyperparameter entry, resumable from checkpoints.

Run dir (``ppo:RUN_DIR`` in the benchmark loads it)::

    config.yaml            resolved hyperparameters, {env_id: entry}; loadable as --config
    command.txt            YAML list, one item per invocation: argv, env id, seed, versions, git commit
    model.zip              final policy          vecnormalize.pkl       its VecNormalize statistics
    best_model.zip         best on validation    best_vecnormalize.pkl  the statistics it was evaluated with
    checkpoints/           ppo_{N}_steps.zip, ppo_vecnormalize_{N}_steps.pkl, ppo_state_{N}_steps.pkl
    episodes.csv           per training episode: steps, return, mean |S|, tracking errors, energy
    evaluations.csv/.npz   per validation evaluation (mean return, mean |S|)
    progress.csv, tb/      SB3 log (CSV, TensorBoard)      monitor/  SB3 Monitor files per env
    learning_curve.png     return and mean |S| against env steps
"""

from __future__ import annotations

import dataclasses
import os
import pickle
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import torch
import yaml
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.logger import (
    HumanOutputFormat,
    KVWriter,
    Logger,
    TensorBoardOutputFormat,
)
from stable_baselines3.common.utils import LinearSchedule, set_random_seed
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from rover_env.config import ConfigError
from rover_env.training.callbacks import (
    EpisodeLog,
    RolloutCheckpoint,
    ValidationEval,
    checkpoint_paths,
    latest_checkpoint,
    set_rng_state,
    trim_csv,
)
from rover_env.training.config import PPOConfig, Schedule, load_config
from rover_env.training.envs import (
    check_env_kwargs,
    make_vec_env,
    split_episodes,
    training_env_seeds,
    validation_seeds,
)
from rover_env.training.plots import plot_learning_curve
from rover_env.training.rundir import ResumedCSV, read_commands, record_command

_ACTIVATIONS = {
    "tanh": torch.nn.Tanh,
    "relu": torch.nn.ReLU,
    "elu": torch.nn.ELU,
    "leaky_relu": torch.nn.LeakyReLU,
    "gelu": torch.nn.GELU,
    "silu": torch.nn.SiLU,
}
RUN_FILES = ("config.yaml", "command.txt", "model.zip", "checkpoints")


@dataclasses.dataclass(frozen=True)
class TrainResult:
    run_dir: Path
    num_timesteps: int
    best_mean_reward: float
    steps_per_second: float
    """Env steps per wall second of this invocation, evaluations and checkpoints included."""
    resumed_from: int | None


def _schedule(s: Schedule) -> float | LinearSchedule:
    return LinearSchedule(s.start, 0.0, 1.0) if s.linear else s.start


def _policy_kwargs(cfg: PPOConfig) -> dict[str, Any]:
    pk = cfg.policy_kwargs
    arch = (
        {k: list(v) for k, v in pk.net_arch.items()}
        if isinstance(pk.net_arch, dict)
        else list(pk.net_arch)
    )
    return {
        "net_arch": arch,
        "activation_fn": _ACTIVATIONS[pk.activation],
        "log_std_init": pk.log_std_init,
        "ortho_init": pk.ortho_init,
    }


def _normalized(venv: VecEnv, cfg: PPOConfig, training: bool) -> VecNormalize:
    """Always wrapped (pass-through when disabled) so every run dir has ``vecnormalize.pkl``."""
    n = cfg.normalize
    return VecNormalize(
        venv,
        training=training,
        norm_obs=n.enabled and n.norm_obs,
        norm_reward=training and n.enabled and n.norm_reward,
        clip_obs=n.clip_obs,
        clip_reward=n.clip_reward,
        gamma=cfg.gamma,
        epsilon=n.epsilon,
    )


def _logger(run_dir: Path, keep_until: int | None, verbose: int) -> Logger:
    formats: list[KVWriter] = [
        ResumedCSV(str(run_dir / "progress.csv"), keep_until),
        TensorBoardOutputFormat(str(run_dir / "tb")),
    ]
    if verbose:
        formats.insert(0, HumanOutputFormat(sys.stdout))
    return Logger(str(run_dir), formats)


def _resolve_resume(run_dir: Path, env_id: str | None, seed: int | None) -> tuple[str, int, int]:
    """Env id, seed and checkpoint step of a run dir; the caller's values must agree with it."""
    cfg_file = run_dir / "config.yaml"
    if not cfg_file.is_file():
        raise ConfigError(f"cannot resume {run_dir}: no config.yaml (not a training run dir)")
    ids = list(yaml.safe_load(cfg_file.read_text()) or {})
    if len(ids) != 1:
        raise ConfigError(f"{cfg_file}: expected exactly one env id, got {ids}")
    run_env = str(ids[0])
    commands = read_commands(run_dir)
    run_seed = int(commands[0]["seed"]) if commands else None
    if env_id is not None and env_id != run_env:
        raise ConfigError(
            f"cannot resume {run_dir} with env id {env_id!r}: the run trains {run_env!r}"
        )
    if run_seed is None:
        raise ConfigError(f"cannot resume {run_dir}: command.txt does not record the seed")
    if seed is not None and seed != run_seed:
        raise ConfigError(f"cannot resume {run_dir} with seed {seed}: the run uses seed {run_seed}")
    step = latest_checkpoint(run_dir / "checkpoints")
    if step is None:
        raise ConfigError(
            f"cannot resume {run_dir}: no complete checkpoint in {run_dir / 'checkpoints'}"
        )
    return run_env, run_seed, step


def train(
    env_id: str | None,
    config_path: str | Path | None,
    seed: int | None,
    out_dir: str | Path,
    resume: bool = False,
    total_timesteps: int | None = None,
    progress: bool = True,
    callbacks: Sequence[BaseCallback] = (),
    verbose: int = 0,
) -> TrainResult:
    """Train PPO on ``env_id`` with the file's entry for it; write a run dir at ``out_dir``.

    ``total_timesteps`` overrides the entry's ``n_timesteps`` and is the run's total, also when
    resuming (so resuming a run killed at step k trains the remaining steps on the same
    learning-rate schedule). ``resume=True`` takes env id, seed and hyperparameters from the
    run dir (``config_path`` is then ignored; env id and seed may be None) and continues from its
    newest checkpoint. ``callbacks`` are added to the run's own (e.g. to stop early).
    """
    run_dir = Path(out_dir)
    torch.set_num_threads(1)
    os.environ.setdefault("OMP_NUM_THREADS", "1")  # inherited by the env subprocesses

    start_step: int | None = None
    if resume:
        env_id, seed, start_step = _resolve_resume(run_dir, env_id, seed)
        cfg_file = run_dir / "config.yaml"
        cfg = load_config(cfg_file, env_id)
    else:
        if env_id is None or config_path is None or seed is None:
            raise ConfigError("a new run needs env_id, config_path and seed")
        if any((run_dir / f).exists() for f in RUN_FILES):
            raise ConfigError(
                f"{run_dir} already holds a training run; resume it or choose another directory"
            )
        cfg = load_config(config_path, env_id)
        cfg_file = Path(config_path)
    if total_timesteps is not None:
        if total_timesteps < 1:
            raise ConfigError(f"total_timesteps must be >= 1, got {total_timesteps}")
        cfg = dataclasses.replace(cfg, n_timesteps=int(total_timesteps))
    check_env_kwargs(env_id, cfg, f"{cfg_file}: {env_id}")

    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "config.yaml").write_text(
        "# resolved PPO hyperparameters of this run; loadable as --config\n"
        + yaml.safe_dump({env_id: cfg.to_dict()}, sort_keys=False)
    )
    train_seeds = training_env_seeds(seed, cfg.n_envs)
    val_seeds = validation_seeds()
    record_command(
        run_dir,
        {
            "env_id": env_id,
            "seed": seed,
            "config": str(config_path if not resume else run_dir / "config.yaml"),
            "total_timesteps": cfg.n_timesteps,
            "resumed_from_step": start_step,
            "training_env_seeds": list(train_seeds),
        },
    )

    monitor_dir = run_dir / "monitor"
    # A resumed env continues its own generator (restored below), so no planned seed again.
    env_seeds = [[] for _ in range(cfg.n_envs)] if resume else [[s] for s in train_seeds]
    venv = make_vec_env(env_id, cfg, cfg.n_envs, env_seeds, monitor_dir, "train", append=resume)
    eval_venv: VecEnv | None = None
    try:
        state: dict[str, Any] = {}
        if start_step is not None:
            model_p, vn_p, state_p = checkpoint_paths(run_dir / "checkpoints", start_step)
            with state_p.open("rb") as fh:
                state = pickle.load(fh)
            vn = VecNormalize.load(str(vn_p), venv)
            vn.training = True
            # seed=None: loading must not reseed; the checkpoint's RNG states are restored instead.
            model = PPO.load(str(model_p), env=vn, device="cpu", seed=None)
            model.seed = seed
            set_rng_state(state["rng"])
            for i, s in enumerate(state["env_rng"]):
                venv.env_method("set_rng_state", s, indices=[i])
            for name in ("episodes.csv", "evaluations.csv"):
                trim_csv(run_dir / name, start_step)
        else:
            set_random_seed(seed)
            vn = _normalized(venv, cfg, training=True)
            model = PPO(
                cfg.policy,
                vn,
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
                policy_kwargs=_policy_kwargs(cfg),
                device="cpu",
                seed=None,
            )
            model.seed = seed
        model.set_logger(_logger(run_dir, start_step, verbose))

        ckpt = RolloutCheckpoint(
            run_dir / "checkpoints",
            max(cfg.checkpoint_freq, 1),
            {"env_id": env_id, "seed": seed},
        )
        ckpt.last_saved = start_step or 0
        cbs: list[BaseCallback] = [EpisodeLog(run_dir / "episodes.csv"), ckpt]
        eval_cb: ValidationEval | None = None
        if cfg.eval_freq > 0:
            eval_seeds = split_episodes(val_seeds, cfg.n_eval_episodes, cfg.n_eval_envs)
            eval_venv = _normalized(
                make_vec_env(
                    env_id, cfg, cfg.n_eval_envs, eval_seeds, None, "eval", split="validation"
                ),
                cfg,
                training=False,
            )
            eval_cb = ValidationEval(
                eval_venv,
                run_dir,
                n_eval_episodes=cfg.n_eval_episodes,
                eval_freq=max(cfg.eval_freq // cfg.n_envs, 1),
            )
            if state.get("eval"):
                eval_cb.load_state(state["eval"])
            # Keep evaluations on the same step grid as an uninterrupted run.
            eval_cb.n_calls = (start_step or 0) // cfg.n_envs
            ckpt.eval_cb = eval_cb
            cbs.append(eval_cb)
        cbs.extend(callbacks)

        first = model.num_timesteps
        remaining = cfg.n_timesteps - first
        t0 = time.perf_counter()
        if remaining > 0:
            model.learn(
                total_timesteps=remaining,
                callback=CallbackList(cbs),
                reset_num_timesteps=False,
                progress_bar=progress,
            )
        elapsed = time.perf_counter() - t0
        done = model.num_timesteps
        model.save(str(run_dir / "model.zip"))
        vn.save(str(run_dir / "vecnormalize.pkl"))
        if done % cfg.rollout_size == 0 and done != ckpt.last_saved:
            ckpt.save()  # a clean end is a rollout boundary: checkpoint it for later extension
        model.logger.close()
    finally:
        venv.close()
        if eval_venv is not None:
            eval_venv.close()
    plot_learning_curve(run_dir)
    return TrainResult(
        run_dir=run_dir,
        num_timesteps=done,
        best_mean_reward=eval_cb.best_mean_reward if eval_cb is not None else float("-inf"),
        steps_per_second=(done - first) / elapsed if elapsed > 0 else float("nan"),
        resumed_from=start_step,
    )
