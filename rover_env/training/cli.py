"""Command lines behind ``train/ppo.py`` (``sac.py``, ``td3.py``, ``train.py --algo``),
``train/sweep.py``, ``train/search.py`` and ``train/evaluate.py`` (kept here so they install)."""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from rover_env.config import ConfigError
from rover_env.training.config import ALGOS, env_ids


def only_env_id(config: str) -> str:
    """The env id of a hyperparameter file with one entry (an agent's file: ``configs/agents``)."""
    ids = env_ids(config)
    if len(ids) != 1:
        raise ConfigError(f"{config}: has entries for {ids}; name one with --env-id")
    return ids[0]


ALGO_NAMES = ALGOS


def train_main(argv: Sequence[str] | None = None, algo: str | None = None) -> int:
    """``algo`` fixes the algorithm (train/ppo.py, sac.py, td3.py); None: ``--algo`` chooses."""
    name = algo.upper() if algo else "PPO, SAC or TD3"
    ap = argparse.ArgumentParser(
        prog=f"train/{algo}.py" if algo else "train/train.py",
        description=f"Train {name} on a rover env; hyperparameters from a YAML entry keyed by "
        "env id.",
    )
    if algo is None:
        ap.add_argument(
            "--algo",
            choices=ALGO_NAMES,
            default=None,
            help="algorithm (default ppo; resume: the run dir's)",
        )
    ap.add_argument(
        "--env-id",
        help="e.g. rover_env/ProtoExplorer-v0 (default: the config file's only entry; resume: "
        "from the run dir)",
    )
    ap.add_argument(
        "--config",
        default=None,
        help="hyperparameter YAML, a shipped name, or a folder of {algo}.yaml files "
        "(default: the shipped file named for the algorithm, e.g. configs/sac.yaml)",
    )
    ap.add_argument("--seed", type=int, help="run seed (resume: from the run dir)")
    ap.add_argument("--out", help="run directory (default runs/<config name>_s<seed>)")
    ap.add_argument(
        "--resume",
        nargs="?",
        const=True,
        default=False,
        metavar="DIR",
        help="continue the run in DIR (or --out) from its newest checkpoint",
    )
    ap.add_argument(
        "--total-timesteps", type=int, help="total env steps of the run (overrides n_timesteps)"
    )
    ap.add_argument(
        "--init-from",
        default=None,
        metavar="AGENT",
        help="a new run starts from this trained agent's weights and observation statistics "
        "(rl-zoo's --trained-agent): a fine-tune",
    )
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    ap.add_argument("-v", "--verbose", action="count", default=0, help="print SB3's log table")
    args = ap.parse_args(argv)

    out = args.out
    if isinstance(args.resume, str):
        if out is not None and Path(out) != Path(args.resume):
            ap.error(f"--resume {args.resume} and --out {out} name different runs")
        out = args.resume
    resume = args.resume is not False
    chosen = algo or args.algo
    if not resume:
        if args.seed is None:
            ap.error("a new run needs --seed")
        try:
            args.env_id = args.env_id or only_env_id(args.config or chosen or "ppo")
        except ConfigError as exc:
            ap.error(str(exc))
        if out is None and args.config is not None:
            out = str(Path("runs") / f"{Path(args.config).stem}_s{args.seed}")
    if out is None:
        ap.error("--out is required (or --resume DIR)")
    from rover_env.training.run import train

    try:
        res = train(
            args.env_id,
            None if resume else (args.config or chosen or "ppo"),
            args.seed,
            out,
            resume=resume,
            total_timesteps=args.total_timesteps,
            progress=not args.no_progress,
            verbose=args.verbose,
            algo=chosen,
            init_from=args.init_from,
        )
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    resumed = f" (resumed at step {res.resumed_from})" if res.resumed_from is not None else ""
    print(
        f"{res.run_dir} ({res.algo}): {res.num_timesteps} steps{resumed}, "
        f"{res.steps_per_second:.1f} steps/s, "
        f"best validation return {res.best_mean_reward:.2f}"
    )
    return 0


def evaluate_main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="train/evaluate.py",
        description="Benchmark a trained run's agent (ppo:, sac: or td3:RUN_DIR) on the "
        "validation seeds; "
        "--final: its one run on the test seeds, recorded in the test ledger.",
    )
    ap.add_argument("run_dir", help="run directory written by train/ppo.py, sac.py or td3.py")
    ap.add_argument("--episodes", type=int, default=20, help="seeds per scenario (20)")
    ap.add_argument("--scenarios", default="all", help="comma list of benchmark scenarios, or all")
    ap.add_argument(
        "--baselines", default="", help="controllers on the same seeds first, e.g. open-loop"
    )
    ap.add_argument(
        "--which", choices=("best", "final"), default="best", help="agent: best (default) or final"
    )
    ap.add_argument("--duration", type=float, default=None, help="episode length override (s)")
    ap.add_argument("--workers", type=int, default=1, help="benchmark processes (1)")
    ap.add_argument("--out", default=None, help="output directory (default RUN_DIR/benchmark)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    ap.add_argument(
        "--final", action="store_true", help="the agent's one test-split run (test ledger)"
    )
    ap.add_argument(
        "--question", default=None, help="with --final (required): registered question id"
    )
    ap.add_argument(
        "--questions", default=None, help="questions YAML (default configs/benchmarks/)"
    )
    ap.add_argument("--force", action="store_true", help="with --final: again, marked a repeat")
    ap.add_argument("--ledger", default=None, help="test ledger CSV (default docs/benchmark/)")
    argv_list = list(sys.argv[1:] if argv is None else argv)
    args = ap.parse_args(argv_list)
    if args.force and not args.final:
        ap.error("--force only applies to --final")
    if args.final and not args.question:
        ap.error("--final needs --question ID (configs/benchmarks/questions.yaml)")

    from rover_env.benchmark.ledger import FinalRunRefused
    from rover_env.training.evaluate import evaluate

    try:
        report = evaluate(
            args.run_dir,
            episodes=args.episodes,
            out=args.out,
            scenarios=None if args.scenarios == "all" else args.scenarios.split(","),
            baselines=[b for b in args.baselines.split(",") if b],
            which=args.which,
            duration=args.duration,
            workers=args.workers,
            progress=not args.quiet,
            final=args.final,
            force=args.force,
            ledger=args.ledger,
            question=args.question,
            questions=args.questions,
            command="python train/evaluate.py " + " ".join(shlex.quote(a) for a in argv_list),
        )
    except FinalRunRefused as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 3
    except (ConfigError, FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(report)
    return 0


def sweep_main(argv: Sequence[str] | None = None) -> int:
    from rover_env.executor import add_executor_args

    ap = argparse.ArgumentParser(
        prog="train/sweep.py",
        description="One training run per (algorithm, seed), on local processes or Ray; "
        "run folders OUT/{algo}_s{seed}, one line per finished run in OUT/sweep.jsonl.",
    )
    ap.add_argument(
        "--config",
        required=True,
        help="hyperparameter YAML, a shipped name, or a folder of {algo}.yaml files",
    )
    ap.add_argument("--env-id", default=None, help="env id (default: the file's only entry)")
    ap.add_argument("--seeds", required=True, help="run seeds: 0-9, or 0,3,5-7")
    ap.add_argument("--algos", default="ppo", help="comma list of ppo, sac, td3 (default ppo)")
    ap.add_argument("--out", required=True, help="sweep folder (shared by all nodes on a cluster)")
    ap.add_argument("--total-timesteps", type=int, help="env steps per run (overrides n_timesteps)")
    ap.add_argument("--workers", type=int, default=1, help="runs side by side (default 1)")
    add_executor_args(ap)
    ap.add_argument(
        "--resume", action="store_true", help="skip finished runs, continue stopped ones"
    )
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)

    from rover_env.training.sweep import parse_seeds, sweep

    try:
        rows = sweep(
            args.config,
            parse_seeds(args.seeds),
            args.out,
            env_id=args.env_id,
            algos=[a.strip() for a in args.algos.split(",") if a.strip()],
            total_timesteps=args.total_timesteps,
            executor=args.executor,
            workers=args.workers,
            ray_address=args.ray_address,
            resume=args.resume,
            progress=not args.quiet,
        )
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for r in rows:
        print(
            f"{r['run_dir']}: {r['num_timesteps']} steps, best validation return "
            f"{r['best_mean_reward']:.2f}"
        )
    return 0


def search_main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="train/search.py",
        description="Optuna hyperparameter search: each trial a short training run scored by "
        "its mean validation return (validation seeds only), TPE sampler, median pruner on "
        "the intermediate evaluations; resumable through --storage.",
    )
    ap.add_argument("--algo", choices=ALGO_NAMES, default="ppo", help="algorithm (default ppo)")
    ap.add_argument(
        "--config",
        default=None,
        help="base hyperparameters: YAML, shipped name or folder of {algo}.yaml (default: "
        "the shipped file named for the algorithm)",
    )
    ap.add_argument("--env-id", required=True, help="env id of the entry to search around")
    ap.add_argument("--trials", type=int, default=20, help="finished trials in the study (20)")
    ap.add_argument(
        "--timesteps-per-trial", type=int, default=50_000, help="env steps per trial (50000)"
    )
    ap.add_argument(
        "--budget-minutes", type=float, default=None, help="start no trial after this wall time"
    )
    ap.add_argument(
        "--storage", default=None, help="Optuna storage URL (default sqlite:///OUT/study.db)"
    )
    ap.add_argument("--study-name", default=None, help="default '{algo}|{env id}'")
    ap.add_argument("--out", default=None, help="output folder (default runs/search/{algo})")
    ap.add_argument("--seed", type=int, default=0, help="sampler seed (0)")
    ap.add_argument("--run-seed", type=int, default=0, help="training run seed of every trial (0)")
    ap.add_argument(
        "--evaluations", type=int, default=4, help="validation evaluations per trial (4)"
    )
    ap.add_argument("--space", default=None, help="search-space YAML replacing the default")
    ap.add_argument(
        "--init-from",
        default=None,
        help="trained agent folder: every trial fine-tunes it (network keys not searchable)",
    )
    ap.add_argument(
        "--startup-trials", type=int, default=5, help="random trials before TPE models (5)"
    )
    ap.add_argument(
        "--pruner-startup", type=int, default=3, help="trials before the pruner acts (3)"
    )
    args = ap.parse_args(argv)

    from rover_env.training.search import load_space, search

    try:
        res = search(
            args.algo,
            args.config or args.algo,
            args.env_id,
            args.out or f"runs/search/{args.algo}",
            trials=args.trials,
            timesteps_per_trial=args.timesteps_per_trial,
            budget_minutes=args.budget_minutes,
            storage=args.storage,
            study_name=args.study_name,
            seed=args.seed,
            run_seed=args.run_seed,
            evaluations=args.evaluations,
            space=None if args.space is None else load_space(args.space),
            startup_trials=args.startup_trials,
            pruner_startup=args.pruner_startup,
            init_from=args.init_from,
        )
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(
        f"{res.out}: {res.n_complete} complete, {res.n_pruned} pruned trials; "
        + (
            f"best trial {res.best_number} (validation return {res.best_value:.3f}): "
            f"{res.out / 'best.yaml'}"
            if res.best_number is not None
            else "no complete trial"
        )
    )
    return 0
