"""PPO, SAC or TD3 training of the rover env from a YAML hyperparameter entry, resumable from
checkpoints.

Run dir (``ppo:RUN_DIR``, ``sac:RUN_DIR`` or ``td3:RUN_DIR`` in the benchmark loads it)::

    config.yaml            resolved hyperparameters, {env_id: entry}; loadable as --config
    command.txt            YAML list, one item per invocation: argv, env id, seed, versions, git commit
    model.zip              final policy          vecnormalize.pkl       its VecNormalize statistics
    best_model.zip         best on validation    best_vecnormalize.pkl  the statistics it was evaluated with
    checkpoints/           {algo}_{N}_steps.zip, {algo}_vecnormalize_{N}_steps.pkl,
                           {algo}_state_{N}_steps.pkl; SAC/TD3: {algo}_replay_buffer_{N}_steps.pkl
                           (the newest checkpoint's only)
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
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.logger import (
    HumanOutputFormat,
    KVWriter,
    Logger,
    TensorBoardOutputFormat,
)
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from rover_env.config import ConfigError, load_yaml
from rover_env.training.algos import algo_class, build_model
from rover_env.training.callbacks import (
    EpisodeLog,
    RolloutCheckpoint,
    ValidationEval,
    checkpoint_paths,
    latest_checkpoint,
    replay_buffer_path,
    set_rng_state,
    trim_csv,
)
from rover_env.training.config import AlgoConfig, check_algo, load_algo_config
from rover_env.training.envs import (
    check_env_kwargs,
    make_vec_env,
    split_episodes,
    training_env_seeds,
    validation_seeds,
)
from rover_env.training.plots import plot_learning_curve
from rover_env.training.rundir import ResumedCSV, read_commands, record_command, run_algo

RUN_FILES = ("config.yaml", "command.txt", "model.zip", "checkpoints")


@dataclasses.dataclass(frozen=True)
class TrainResult:
    run_dir: Path
    num_timesteps: int
    best_mean_reward: float
    steps_per_second: float
    """Env steps per wall second of this invocation, evaluations and checkpoints included."""
    resumed_from: int | None
    last_mean_reward: float = float("-inf")
    """Mean validation return of the last evaluation (what a hyperparameter search scores)."""
    algo: str = "ppo"


def _start_from(model: BaseAlgorithm, vn: VecNormalize, path: str | Path, algo_cls: Any) -> None:
    """A new run's weights (and optimiser state) and observation statistics from the agent
    at ``path`` (a run folder, an ``agents/`` folder or a .zip)."""
    from rover_env.policies.ppo import resolve_model_path

    model_p, stats_p = resolve_model_path(path)
    src = algo_cls.load(str(model_p), device="cpu")
    try:
        model.set_parameters(src.get_parameters(), exact_match=True, device="cpu")
    except (ValueError, RuntimeError, KeyError) as exc:
        raise ConfigError(f"init_from {path}: its network does not fit this run's: {exc}") from None
    if stats_p is not None:
        with stats_p.open("rb") as fh:
            old = pickle.load(fh)
        vn.obs_rms, vn.ret_rms = old.obs_rms, old.ret_rms


def normalized(venv: VecEnv, cfg: AlgoConfig, training: bool) -> VecNormalize:
    """Always wrapped (pass-through when disabled) so every run dir has ``vecnormalize.pkl``."""
    n = cfg.normalize
    return VecNormalize(
        venv,
        training=training,
        norm_obs=n.enabled and n.norm_obs,
        norm_reward=training and n.enabled and n.norm_reward,
        clip_obs=n.clip_obs,
        clip_reward=n.clip_reward,
        gamma=cfg["gamma"],
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


def _resolve_resume(
    run_dir: Path, env_id: str | None, seed: int | None, algo: str
) -> tuple[str, int, int]:
    """Env id, seed and checkpoint step of a run dir; the caller's values must agree with it."""
    cfg_file = run_dir / "config.yaml"
    if not cfg_file.is_file():
        raise ConfigError(f"cannot resume {run_dir}: no config.yaml (not a training run dir)")
    ids = list(load_yaml(cfg_file) or {})
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
    step = latest_checkpoint(run_dir / "checkpoints", algo)
    if step is None:
        raise ConfigError(
            f"cannot resume {run_dir}: no complete checkpoint in {run_dir / 'checkpoints'}"
        )
    return run_env, run_seed, step


@dataclasses.dataclass(frozen=True)
class _Plan:
    """What a run trains, from the caller's config file (a new run) or the run dir (a resume)."""

    algo: str
    env_id: str
    seed: int
    cfg: AlgoConfig
    cfg_file: Path
    config: str
    """The hyperparameter file as ``command.txt`` records it."""
    start_step: int | None
    """The checkpoint a resumed run continues from; None for a new run."""


def _plan_resume(run_dir: Path, env_id: str | None, seed: int | None, algo: str | None) -> _Plan:
    found = run_algo(run_dir)
    if algo is not None and check_algo(algo) != found:
        raise ConfigError(f"cannot resume {run_dir} with {algo}: the run trains {found}")
    run_env, run_seed, start_step = _resolve_resume(run_dir, env_id, seed, found)
    cfg_file = run_dir / "config.yaml"
    cfg = load_algo_config(found, cfg_file, run_env)
    return _Plan(found, run_env, run_seed, cfg, cfg_file, str(cfg_file), start_step)


def _plan_new(
    run_dir: Path,
    env_id: str | None,
    config_path: str | Path | None,
    seed: int | None,
    algo: str | None,
) -> _Plan:
    algo = check_algo(algo or "ppo")
    if env_id is None or config_path is None or seed is None:
        raise ConfigError("a new run needs env_id, config_path and seed")
    if any((run_dir / f).exists() for f in RUN_FILES):
        raise ConfigError(
            f"{run_dir} already holds a training run; resume it or choose another directory"
        )
    cfg = load_algo_config(algo, config_path, env_id)
    return _Plan(algo, env_id, seed, cfg, Path(config_path), str(config_path), None)


def _plan(
    run_dir: Path,
    env_id: str | None,
    config_path: str | Path | None,
    seed: int | None,
    resume: bool,
    total_timesteps: int | None,
    algo: str | None,
    init_from: str | Path | None,
) -> _Plan:
    """The run's algorithm, env id, seed and hyperparameters, checked before anything is
    written (see :func:`train` for the arguments)."""
    if resume and init_from is not None:
        raise ConfigError("init_from starts a new run; a resumed run continues its own weights")
    if resume:
        plan = _plan_resume(run_dir, env_id, seed, algo)
    else:
        plan = _plan_new(run_dir, env_id, config_path, seed, algo)
    if total_timesteps is not None:
        if total_timesteps < 1:
            raise ConfigError(f"total_timesteps must be >= 1, got {total_timesteps}")
        cfg = dataclasses.replace(plan.cfg, n_timesteps=int(total_timesteps))
        plan = dataclasses.replace(plan, cfg=cfg)
    check_env_kwargs(plan.env_id, plan.cfg, f"{plan.cfg_file}: {plan.env_id}")
    return plan


def _record(run_dir: Path, plan: _Plan, init_from: str | Path | None) -> list[int]:
    """Write the resolved ``config.yaml`` and append this invocation to ``command.txt``;
    returns the training envs' first-reset seeds."""
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "config.yaml").write_text(
        f"# resolved {plan.algo.upper()} hyperparameters of this run; loadable as --config\n"
        + yaml.safe_dump({plan.env_id: plan.cfg.to_dict()}, sort_keys=False)
    )
    train_seeds = training_env_seeds(plan.seed, plan.cfg.n_envs)
    record_command(
        run_dir,
        {
            "algo": plan.algo,
            "env_id": plan.env_id,
            "seed": plan.seed,
            "config": plan.config,
            "total_timesteps": plan.cfg.n_timesteps,
            "resumed_from_step": plan.start_step,
            "init_from": None if init_from is None else str(init_from),
            "training_env_seeds": list(train_seeds),
        },
    )
    return train_seeds


def _restore(
    run_dir: Path, plan: _Plan, venv: VecEnv
) -> tuple[BaseAlgorithm, VecNormalize, dict[str, Any]]:
    """The model, statistics, replay buffer and random states of the newest checkpoint."""
    assert plan.start_step is not None
    ckpt_dir = run_dir / "checkpoints"
    model_p, vn_p, state_p = checkpoint_paths(ckpt_dir, plan.start_step, plan.algo)
    with state_p.open("rb") as fh:
        state: dict[str, Any] = pickle.load(fh)
    vn = VecNormalize.load(str(vn_p), venv)
    vn.training = True
    # seed=None: loading must not reseed; the checkpoint's RNG states are restored instead.
    model = algo_class(plan.algo).load(str(model_p), env=vn, device="cpu", seed=None)
    model.seed = plan.seed
    if plan.cfg.off_policy:
        rb_p = replay_buffer_path(ckpt_dir, plan.start_step, plan.algo)
        if not rb_p.is_file():
            raise ConfigError(
                f"cannot resume {run_dir}: no replay buffer {rb_p.name} beside the "
                "newest checkpoint"
            )
        model.load_replay_buffer(str(rb_p))  # type: ignore[attr-defined]
    set_rng_state(state["rng"])
    if state.get("action_space_rng") is not None:
        model.action_space.np_random.bit_generator.state = state["action_space_rng"]
    for i, s in enumerate(state["env_rng"]):
        venv.env_method("set_rng_state", s, indices=[i])
    for name in ("episodes.csv", "evaluations.csv"):
        trim_csv(run_dir / name, plan.start_step)
    return model, vn, state


def _fresh(
    plan: _Plan, venv: VecEnv, init_from: str | Path | None
) -> tuple[BaseAlgorithm, VecNormalize]:
    """A new model seeded with the run seed, or started from ``init_from``'s weights."""
    set_random_seed(plan.seed)
    vn = normalized(venv, plan.cfg, training=True)
    model = build_model(plan.cfg, vn)
    if init_from is not None:
        _start_from(model, vn, init_from, algo_class(plan.algo))
    model.action_space.seed(plan.seed)  # off-policy warm-up actions are its samples
    model.seed = plan.seed
    return model, vn


def _checkpointer(run_dir: Path, plan: _Plan) -> RolloutCheckpoint:
    """Checkpoints every ``checkpoint_freq`` steps, counted on from a resumed checkpoint."""
    ckpt = RolloutCheckpoint(
        run_dir / "checkpoints",
        max(plan.cfg.checkpoint_freq, 1),
        {"algo": plan.algo, "env_id": plan.env_id, "seed": plan.seed},
        algo=plan.algo,
    )
    ckpt.last_saved = plan.start_step or 0
    return ckpt


def _eval_venv(plan: _Plan) -> VecNormalize:
    """The validation envs (the seed plan's validation seeds), normalised but not updating."""
    cfg = plan.cfg
    eval_seeds = split_episodes(validation_seeds(), cfg.n_eval_episodes, cfg.n_eval_envs)
    return normalized(
        make_vec_env(
            plan.env_id, cfg, cfg.n_eval_envs, eval_seeds, None, "eval", split="validation"
        ),
        cfg,
        training=False,
    )


def _validation(
    run_dir: Path,
    plan: _Plan,
    eval_venv: VecNormalize,
    state: dict[str, Any],
    after_eval: BaseCallback | None,
) -> ValidationEval:
    """The evaluation callback, on the same step grid as an uninterrupted run."""
    cfg = plan.cfg
    eval_cb = ValidationEval(
        eval_venv,
        run_dir,
        n_eval_episodes=cfg.n_eval_episodes,
        eval_freq=max(cfg.eval_freq // cfg.n_envs, 1),
        callback_after_eval=after_eval,
    )
    if state.get("eval"):
        eval_cb.load_state(state["eval"])
    # Keep evaluations on the same step grid as an uninterrupted run.
    eval_cb.n_calls = (plan.start_step or 0) // cfg.n_envs
    return eval_cb


def _learn(
    model: BaseAlgorithm, cfg: AlgoConfig, cbs: list[BaseCallback], progress: bool
) -> tuple[int, float]:
    """Train up to the run's total; returns the step it started from and the wall seconds."""
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
    return first, time.perf_counter() - t0


def _save(
    run_dir: Path, model: BaseAlgorithm, vn: VecNormalize, ckpt: RolloutCheckpoint, cfg: AlgoConfig
) -> int:
    """Write the final model and statistics (and a checkpoint at a clean end); returns the
    step count reached."""
    done = model.num_timesteps
    model.save(str(run_dir / "model.zip"))
    vn.save(str(run_dir / "vecnormalize.pkl"))
    if done % cfg.rollout_size == 0 and done != ckpt.last_saved:
        ckpt.save()  # a clean end is a rollout boundary: checkpoint it for later extension
    model.logger.close()
    return done


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
    algo: str | None = None,
    after_eval: BaseCallback | None = None,
    init_from: str | Path | None = None,
) -> TrainResult:
    """Train ``algo`` (ppo, sac, td3; default ppo, or the run dir's when resuming) on
    ``env_id`` with the file's entry for it; write a run dir at ``out_dir``.

    ``total_timesteps`` overrides the entry's ``n_timesteps`` and is the run's total, also when
    resuming (so resuming a run killed at step k trains the remaining steps on the same
    learning-rate schedule). ``resume=True`` takes env id, seed and hyperparameters from the
    run dir (``config_path`` is then ignored; env id and seed may be None) and continues from its
    newest checkpoint. ``callbacks`` are added to the run's own (e.g. to stop early);
    ``after_eval`` runs after every validation evaluation (its ``parent`` is the evaluation
    callback: ``parent.last_mean_reward``), and stops training by returning False.
    ``config_path`` may also be a folder of ``{algo}.yaml`` files. ``init_from`` (a new run
    only; rl-zoo's ``--trained-agent``) starts from a trained agent's network weights and
    observation statistics instead of a fresh network: a fine-tune, e.g. of a residual policy
    on another base (the network's shape must match the config's).
    """
    run_dir = Path(out_dir)
    torch.set_num_threads(1)
    os.environ.setdefault("OMP_NUM_THREADS", "1")  # inherited by the env subprocesses
    plan = _plan(run_dir, env_id, config_path, seed, resume, total_timesteps, algo, init_from)
    cfg = plan.cfg
    train_seeds = _record(run_dir, plan, init_from)
    # A resumed env continues its own generator (restored below), so no planned seed again.
    env_seeds = [[] for _ in range(cfg.n_envs)] if resume else [[s] for s in train_seeds]
    venv = make_vec_env(
        plan.env_id, cfg, cfg.n_envs, env_seeds, run_dir / "monitor", "train", append=resume
    )
    eval_venv: VecEnv | None = None
    try:
        state: dict[str, Any] = {}
        if plan.start_step is not None:
            model, vn, state = _restore(run_dir, plan, venv)
        else:
            model, vn = _fresh(plan, venv, init_from)
        model.set_logger(_logger(run_dir, plan.start_step, verbose))
        ckpt = _checkpointer(run_dir, plan)
        cbs: list[BaseCallback] = [EpisodeLog(run_dir / "episodes.csv"), ckpt]
        eval_cb: ValidationEval | None = None
        if cfg.eval_freq > 0:
            eval_venv = _eval_venv(plan)
            eval_cb = _validation(run_dir, plan, eval_venv, state, after_eval)
            ckpt.eval_cb = eval_cb
            cbs.append(eval_cb)
        cbs.extend(callbacks)
        first, elapsed = _learn(model, cfg, cbs, progress)
        done = _save(run_dir, model, vn, ckpt, cfg)
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
        resumed_from=plan.start_step,
        last_mean_reward=eval_cb.last_mean_reward if eval_cb is not None else float("-inf"),
        algo=plan.algo,
    )
