"""Hyperparameter search with Optuna: each trial a short training run scored on validation seeds.

A trial takes the base entry of a hyperparameter file (``--config``, the algorithm's entry for
the env id), replaces the searched keys with the sampler's values, and trains it for
``timesteps_per_trial`` env steps with run seed ``run_seed`` (the same training seeds for every
trial, so trials differ only by their hyperparameters). Its score is the mean return of the
last validation evaluation (the validation seeds of the seed plan; never the test seeds); the
evaluations in between (``evaluations`` of them per trial) are reported to a median pruner,
which stops trials that fall below the median of earlier ones at the same step.

The sampler is TPE seeded with ``seed`` (plus the number of trials already in a resumed study,
so a resumed study does not draw its first random trials again). The study lives in
``storage`` (``sqlite:///OUT/study.db`` by default), so a killed search resumes where it
stopped: trials it left running are marked failed and queued again with the same parameters
(one search process per study). ``budget_minutes`` stops the search from starting a trial
after that much wall time (a running trial finishes); ``trials`` is the study's total of
finished (complete or pruned) trials.

Writes to ``out``: ``trial_NNN/hparams.yaml`` (the trial's entry) and ``trial_NNN/run/`` (its
run dir, checkpoints removed), ``trials.csv`` (one row per trial: state, score, best
validation return, steps, wall time, parameters) and ``best.yaml``, the best trial's entry as
``{env_id: entry}`` with the base file's ``n_timesteps``, ``eval_freq`` and
``checkpoint_freq``, usable as ``--config``.

``init_from`` (a trained agent's folder) makes every trial a fine-tune of that agent (its
weights and observation statistics, :func:`rover_env.training.run.train`): a study of the
fine-tune's settings, where a short trial already ranks them because it starts from a policy
that drives. Keys that set the network's shape cannot be searched then. The study records
the agent (``init_from`` user attribute) and refuses to resume from another.

The search space (:data:`SPACES`, replaceable by a YAML file) maps config keys (dotted for
nested ones: ``policy_kwargs.net_arch``, ``action_noise.sigma``) to ``{choices: [...]}`` or
``{low, high, log, int}``; ``net_arch`` choices are strings such as ``"128x128"``.
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import math
import shutil
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import optuna
import yaml
from optuna.trial import TrialState
from stable_baselines3.common.callbacks import BaseCallback

from rover_env.config import ConfigError, load_yaml
from rover_env.training.config import (
    AlgoConfig,
    check_algo,
    config_for,
    load_algo_config,
    parse_algo_config,
    resolve_config_path,
)

__all__ = ["SPACES", "SearchResult", "load_space", "search"]

_ARCHS = ["64x64", "128x128", "256x256"]
_GAMMAS = [0.95, 0.97, 0.98, 0.99]
_OFF_POLICY: dict[str, dict[str, Any]] = {
    "learning_rate": {"low": 1e-5, "high": 1e-3, "log": True},
    "batch_size": {"choices": [64, 128, 256, 512]},
    "buffer_size": {"choices": [100_000, 300_000, 1_000_000]},
    "learning_starts": {"choices": [1000, 5000, 10000]},
    "train_freq": {"choices": [1, 4, 8]},
    "tau": {"choices": [0.005, 0.01, 0.02]},
    "gamma": {"choices": _GAMMAS},
}
"""What the SAC and TD3 spaces share (SB3's off-policy settings)."""

SPACES: dict[str, dict[str, dict[str, Any]]] = {
    "ppo": {
        "learning_rate": {"low": 1e-5, "high": 1e-3, "log": True},
        "n_steps": {"choices": [256, 512, 1024, 2048]},
        "batch_size": {"choices": [64, 128, 256]},
        "n_epochs": {"choices": [5, 10, 20]},
        "gamma": {"choices": _GAMMAS},
        "gae_lambda": {"choices": [0.9, 0.95, 0.98]},
        "clip_range": {"choices": [0.1, 0.2, 0.3]},
        "ent_coef": {"low": 1e-8, "high": 1e-2, "log": True},
        "policy_kwargs.log_std_init": {"low": -3.0, "high": 0.0},
        "policy_kwargs.net_arch": {"choices": _ARCHS},
    },
    "sac": {
        **_OFF_POLICY,
        "ent_coef": {"choices": ["auto", "auto_0.1", "auto_0.01"]},
        "policy_kwargs.net_arch": {"choices": _ARCHS},
    },
    "td3": {
        **_OFF_POLICY,
        "policy_delay": {"choices": [1, 2, 3]},
        "target_policy_noise": {"choices": [0.1, 0.2]},
        "action_noise.sigma": {"low": 0.02, "high": 0.3, "log": True},
        "policy_kwargs.net_arch": {"choices": _ARCHS},
    },
}
"""Default search spaces per algorithm (rl-zoo's, narrowed to what fits a 2-core budget)."""

CSV_FIXED = (
    "number",
    "state",
    "value",
    "best_mean_reward",
    "num_timesteps",
    "seconds",
    "run_dir",
)


@dataclasses.dataclass(frozen=True)
class SearchResult:
    out: Path
    best_number: int | None
    best_value: float
    best_params: dict[str, Any]
    n_complete: int
    n_pruned: int


def load_space(path: str | Path, where: str | None = None) -> dict[str, dict[str, Any]]:
    """A search space from YAML ``{key: {choices: [...]} | {low, high, log?, int?}}``."""
    p = Path(path)
    return check_space(load_yaml(p), where or str(p))


def check_space(data: Any, where: str) -> dict[str, dict[str, Any]]:
    if not isinstance(data, Mapping) or not data:
        raise ConfigError(f"{where}: expected a mapping of hyperparameter keys to ranges")
    out: dict[str, dict[str, Any]] = {}
    for key, spec in data.items():
        w = f"{where}: {key}"
        if not isinstance(spec, Mapping):
            raise ConfigError(f"{w}: expected {{choices: [...]}} or {{low, high}}")
        if "choices" in spec:
            if (
                set(spec) != {"choices"}
                or not isinstance(spec["choices"], list)
                or not spec["choices"]
            ):
                raise ConfigError(f"{w}: choices must be a non-empty list, alone")
            for c in spec["choices"]:
                if not (c is None or isinstance(c, bool | int | float | str)):
                    raise ConfigError(f"{w}: choice {c!r} is not a number, string or null")
        else:
            extra = set(spec) - {"low", "high", "log", "int"}
            if extra or not {"low", "high"} <= set(spec):
                raise ConfigError(f"{w}: expected low, high and optionally log, int")
            lo, hi = spec["low"], spec["high"]
            if not all(isinstance(x, int | float) and not isinstance(x, bool) for x in (lo, hi)):
                raise ConfigError(f"{w}: low and high must be numbers")
            if not lo < hi or (spec.get("log") and lo <= 0):
                raise ConfigError(f"{w}: need low < high (and low > 0 with log)")
        out[str(key)] = dict(spec)
    return out


def _suggest(trial: optuna.Trial, key: str, spec: Mapping[str, Any]) -> Any:
    if "choices" in spec:
        return trial.suggest_categorical(key, spec["choices"])
    if spec.get("int"):
        return trial.suggest_int(
            key, int(spec["low"]), int(spec["high"]), log=bool(spec.get("log"))
        )
    return trial.suggest_float(
        key, float(spec["low"]), float(spec["high"]), log=bool(spec.get("log"))
    )


def _arch(value: Any) -> Any:
    """``"128x128"`` -> [128, 128]; other values unchanged."""
    if isinstance(value, str):
        try:
            return [int(x) for x in value.split("x")]
        except ValueError:
            raise ConfigError(f"net_arch choice {value!r} is not like 128x128") from None
    return value


def apply_params(entry: Mapping[str, Any], params: Mapping[str, Any]) -> dict[str, Any]:
    """The entry with the sampled values set (dotted keys into nested mappings). A schedule
    that is linear in the entry (``lin_3e-4``) stays linear from the sampled start. PPO's
    batch_size is capped at its rollout (n_steps * n_envs), as the config requires."""
    out = copy.deepcopy(dict(entry))
    for key, value in params.items():
        old = out.get(key)
        if isinstance(old, str) and old.startswith("lin_") and isinstance(value, int | float):
            value = f"lin_{float(value)!r}"
        *parents, leaf = key.split(".")
        node = out
        for part in parents:
            if not isinstance(node.get(part), dict):
                node[part] = {}
            node = node[part]
        node[leaf] = _arch(value) if leaf == "net_arch" else value
    if "n_steps" in out and "batch_size" in out:
        out["batch_size"] = min(int(out["batch_size"]), int(out["n_steps"]) * int(out["n_envs"]))
    return out


class _ReportEvaluations(BaseCallback):
    """After each validation evaluation: report its mean return; stop the run if pruned."""

    def __init__(self, trial: optuna.Trial) -> None:
        super().__init__()
        self.trial = trial
        self.pruned = False

    def _on_step(self) -> bool:
        parent: Any = self.parent
        self.trial.report(float(parent.last_mean_reward), self.num_timesteps)
        if self.trial.should_prune():
            self.pruned = True
            return False
        return True


def _write_csv(study: optuna.Study, path: Path) -> None:
    keys = sorted({k for t in study.trials for k in t.params})
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([*CSV_FIXED, *keys])
        for t in study.trials:
            a = t.user_attrs
            w.writerow(
                [
                    t.number,
                    t.state.name,
                    "" if t.value is None else t.value,
                    a.get("best_mean_reward", ""),
                    a.get("num_timesteps", ""),
                    a.get("seconds", ""),
                    a.get("run_dir", ""),
                    *(t.params.get(k, "") for k in keys),
                ]
            )
    tmp.replace(path)


@dataclasses.dataclass(frozen=True)
class _Objective:
    """One trial: the base entry with the sampled values, trained for ``timesteps_per_trial``
    steps with run seed ``run_seed``; scored by its last validation evaluation."""

    algo: str
    env_id: str
    root: Path
    base: AlgoConfig
    base_entry: dict[str, Any]
    space: Mapping[str, Mapping[str, Any]]
    timesteps_per_trial: int
    eval_freq: int
    run_seed: int
    keep_checkpoints: bool
    init_from: str | Path | None

    def _prepare(self, number: int, params: Mapping[str, Any]) -> Path:
        """Write the trial's ``hparams.yaml`` (checked first); returns its empty run dir."""
        entry = apply_params(self.base_entry, params)
        entry.update(
            n_timesteps=self.timesteps_per_trial,
            eval_freq=self.eval_freq,
            checkpoint_freq=self.timesteps_per_trial,
        )
        tdir = self.root / f"trial_{number:03d}"
        parse_algo_config(self.algo, entry, f"{tdir}: {self.env_id}")  # fail before any env
        tdir.mkdir(parents=True, exist_ok=True)
        hp = tdir / "hparams.yaml"
        hp.write_text(yaml.safe_dump({self.env_id: entry}, sort_keys=False))
        run_dir = tdir / "run"
        if run_dir.exists():
            shutil.rmtree(run_dir)
        return run_dir

    def __call__(self, trial: optuna.Trial) -> float:
        from rover_env.training.run import train

        params = {k: _suggest(trial, k, s) for k, s in self.space.items()}
        run_dir = self._prepare(trial.number, params)
        report = _ReportEvaluations(trial)
        t0 = time.perf_counter()
        res = train(
            self.env_id,
            run_dir.parent / "hparams.yaml",
            self.run_seed,
            run_dir,
            total_timesteps=self.timesteps_per_trial,
            progress=False,
            algo=self.algo,
            after_eval=report,
            init_from=self.init_from,
        )
        trial.set_user_attr("seconds", round(time.perf_counter() - t0, 1))
        trial.set_user_attr("num_timesteps", res.num_timesteps)
        trial.set_user_attr("best_mean_reward", res.best_mean_reward)
        trial.set_user_attr("run_dir", str(run_dir))
        if not self.keep_checkpoints:
            shutil.rmtree(run_dir / "checkpoints", ignore_errors=True)
        if report.pruned:
            raise optuna.TrialPruned()
        if not math.isfinite(res.last_mean_reward):
            raise ConfigError(
                f"{run_dir.parent}: the run made no validation evaluation (eval_freq)"
            )
        return float(res.last_mean_reward)


def _fine_tune_origin(init_from: str | Path | None, space: Mapping[str, Any]) -> str:
    """The agent every trial fine-tunes ("" for none), checked before the study folder and
    storage exist: a refused search leaves nothing."""
    origin = "" if init_from is None else str(Path(init_from).resolve())
    if origin:
        shaped = sorted(k for k in space if k.startswith("policy_kwargs."))
        if shaped:
            raise ConfigError(f"init_from {init_from}: cannot search {shaped} in a fine-tune")
        if not Path(origin).is_dir():
            raise ConfigError(f"init_from {init_from}: no such agent folder")
    return origin


def _open_study(
    storage: str, name: str, seed: int, startup_trials: int, pruner_startup: int, origin: str
) -> optuna.Study:
    """The stored study (new or resumed), its killed trials queued again, with a TPE sampler
    that does not repeat a resumed study's first draws and a median pruner."""
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    prior = optuna.create_study(
        storage=storage, study_name=name, direction="maximize", load_if_exists=True
    )
    for t in prior.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        prior.tell(t.number, state=TrialState.FAIL)  # left running by a killed search
        prior.enqueue_trial(t.params, user_attrs={"retry_of": t.number})
    n_before = len(prior.trials)
    sampler = optuna.samplers.TPESampler(seed=seed + n_before, n_startup_trials=startup_trials)
    pruner = optuna.pruners.MedianPruner(n_startup_trials=pruner_startup, n_warmup_steps=0)
    study = optuna.load_study(study_name=name, storage=storage, sampler=sampler, pruner=pruner)
    seen = study.user_attrs.get("init_from")
    if seen is None:
        study.set_user_attr("init_from", origin)
    elif seen != origin:
        raise ConfigError(
            f"{storage}: the study {name!r} fine-tunes {seen or 'nothing'}, not {origin or 'nothing'}"
        )
    return study


def _optimize(
    study: optuna.Study, objective: _Objective, trials: int, budget_minutes: float | None
) -> None:
    """Run trials until the study holds ``trials`` finished ones or the budget is spent,
    rewriting ``trials.csv`` after each."""
    csv_path = objective.root / "trials.csv"
    finished = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.PRUNED))
    remaining = trials - len(finished)
    try:
        if remaining > 0:
            study.optimize(
                objective,
                n_trials=remaining,
                timeout=None if budget_minutes is None else budget_minutes * 60.0,
                callbacks=[lambda s, _t: _write_csv(s, csv_path)],
            )
    finally:
        _write_csv(study, csv_path)


def _best(
    study: optuna.Study, objective: _Objective, storage: str, cfg_path: Path, seed: int
) -> SearchResult:
    """Write ``best.yaml`` (the best trial's entry with the base file's step counts and
    frequencies) and return the study's result."""
    root, base, env_id = objective.root, objective.base, objective.env_id
    complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    n_pruned = len(study.get_trials(deepcopy=False, states=(TrialState.PRUNED,)))
    if not complete:
        return SearchResult(root, None, float("-inf"), {}, 0, n_pruned)
    best = study.best_trial
    entry = apply_params(objective.base_entry, best.params)
    entry.update(
        n_timesteps=base.n_timesteps,
        eval_freq=base.eval_freq,
        checkpoint_freq=base.checkpoint_freq,
    )
    parse_algo_config(objective.algo, entry, f"{root / 'best.yaml'}: {env_id}")
    (root / "best.yaml").write_text(
        f"# best of {len(complete)} complete trials of study {study.study_name!r} ({storage}): "
        f"trial {best.number}, mean validation return {best.value:.4f} after "
        f"{objective.timesteps_per_trial} steps\n# base entry: {cfg_path}; run seed "
        f"{objective.run_seed}; sampler seed {seed}\n"
        + yaml.safe_dump({env_id: entry}, sort_keys=False)
    )
    return SearchResult(
        root,
        best.number,
        float(best.value if best.value is not None else float("nan")),
        dict(best.params),
        len(complete),
        n_pruned,
    )


def search(
    algo: str,
    config: str | Path,
    env_id: str,
    out: str | Path,
    trials: int = 20,
    timesteps_per_trial: int = 50_000,
    budget_minutes: float | None = None,
    storage: str | None = None,
    study_name: str | None = None,
    seed: int = 0,
    run_seed: int = 0,
    evaluations: int = 4,
    space: Mapping[str, Mapping[str, Any]] | None = None,
    startup_trials: int = 5,
    pruner_startup: int = 3,
    keep_checkpoints: bool = False,
    init_from: str | Path | None = None,
) -> SearchResult:
    """Run (or resume) the study; see the module docstring."""
    algo = check_algo(algo)
    if trials < 1 or timesteps_per_trial < 1 or evaluations < 1:
        raise ConfigError("trials, timesteps_per_trial and evaluations must be >= 1")
    if budget_minutes is not None and not budget_minutes > 0:
        raise ConfigError(f"budget_minutes must be > 0, got {budget_minutes}")
    cfg_path = resolve_config_path(config_for(config, algo)).resolve()
    base = load_algo_config(algo, cfg_path, env_id)  # a bad file or env id fails here
    space = check_space(space if space is not None else SPACES[algo], f"{algo} search space")
    origin = _fine_tune_origin(init_from, space)
    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    storage = storage or f"sqlite:///{(root / 'study.db').resolve()}"
    study = _open_study(
        storage, study_name or f"{algo}|{env_id}", seed, startup_trials, pruner_startup, origin
    )
    objective = _Objective(
        algo=algo,
        env_id=env_id,
        root=root,
        base=base,
        base_entry=base.to_dict(),
        space=space,
        timesteps_per_trial=timesteps_per_trial,
        eval_freq=max(timesteps_per_trial // evaluations, base.n_envs),
        run_seed=run_seed,
        keep_checkpoints=keep_checkpoints,
        init_from=init_from,
    )
    _optimize(study, objective, trials, budget_minutes)
    return _best(study, objective, storage, cfg_path, seed)
