"""Callbacks: per-episode task log, validation with planned seeds, resumable checkpoints."""

from __future__ import annotations

import csv
import os
import pickle
import random
import re
from pathlib import Path
from typing import Any

import numpy as np
import torch
from stable_baselines3.common.callbacks import BaseCallback, EvalCallback
from stable_baselines3.common.vec_env import VecEnv

EPISODE_FIELDS = (
    "timesteps",
    "env",
    "return",
    "length",
    "slip_mean_abs",
    "tracking_error_speed",
    "tracking_error_yaw_rate",
    "energy",
)
EVAL_FIELDS = ("timesteps", "mean_reward", "std_reward", "mean_length", "slip_mean_abs")


def trim_csv(path: Path, max_step: int, column: str = "timesteps") -> None:
    """Drop the rows a killed run logged after the checkpoint it is resumed from."""
    if not path.is_file():
        return
    lines = path.read_text().splitlines(keepends=True)
    if not lines:
        return
    header = next(csv.reader([lines[0]]))
    if column not in header:
        return
    col = header.index(column)
    kept = [lines[0]]
    for line in lines[1:]:
        row = next(csv.reader([line]), [])
        try:
            step = float(row[col])
        except (IndexError, ValueError):
            kept.append(line)  # rows without a step (none expected) are kept
            continue
        if step <= max_step:
            kept.append(line)
    path.write_text("".join(kept))


def _append_row(path: Path, fields: tuple[str, ...], row: dict[str, Any]) -> None:
    new = not path.is_file() or path.stat().st_size == 0
    with path.open("a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        if new:
            w.writeheader()
        w.writerow(row)


class EpisodeLog(BaseCallback):
    """One ``episodes.csv`` row per finished training episode: return and task terms.

    The Monitor only keeps return and length; mean |S| (the learning curve's second panel),
    tracking errors and energy are averaged here from the step infos.
    """

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = path
        self._acc: np.ndarray | None = None  # per env: steps, slip, e_v, e_w, energy

    def _on_step(self) -> bool:
        infos = self.locals["infos"]
        dones = self.locals["dones"]
        if self._acc is None:
            self._acc = np.zeros((len(infos), 5))
        for i, info in enumerate(infos):
            if "slip_true_mean_abs" in info:
                self._acc[i] += (
                    1.0,
                    info["slip_true_mean_abs"],
                    info["tracking_error_speed"],
                    info["tracking_error_yaw_rate"],
                    info["energy"],
                )
            if dones[i] and "episode" in info:
                n, slip, ev, ew, energy = self._acc[i]
                n = max(n, 1.0)
                row = {
                    "timesteps": self.num_timesteps,
                    "env": i,
                    "return": float(info["episode"]["r"]),
                    "length": int(info["episode"]["l"]),
                    "slip_mean_abs": slip / n,
                    "tracking_error_speed": ev / n,
                    "tracking_error_yaw_rate": ew / n,
                    "energy": energy,
                }
                _append_row(self.path, EPISODE_FIELDS, row)
                self.logger.record_mean("rollout/ep_slip_mean_abs", slip / n)
                self.logger.record_mean("rollout/ep_tracking_error_speed", ev / n)
                self.logger.record_mean("rollout/ep_energy", energy)
                self._acc[i] = 0.0
            elif dones[i]:
                self._acc[i] = 0.0
        return True


class ValidationEval(EvalCallback):
    """EvalCallback on the validation seeds, saving the normalisation stats with each best model.

    Every evaluation replays the same seeds (``rewind``), so "best" compares policies on the
    same episodes; ``state``/``load_state`` carry the best mean reward across a resume.
    """

    def __init__(self, eval_env: VecEnv, run_dir: Path, **kwargs: Any) -> None:
        super().__init__(
            eval_env,
            best_model_save_path=str(run_dir),
            log_path=str(run_dir),
            deterministic=True,
            verbose=0,
            **kwargs,
        )
        self.run_dir = run_dir
        self._slip: list[float] = []
        self._acc = np.zeros((eval_env.num_envs, 2))

    def _log_success_callback(self, locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        super()._log_success_callback(locals_, globals_)
        i, info = locals_["i"], locals_["info"]
        if "slip_true_mean_abs" in info:
            self._acc[i] += (1.0, info["slip_true_mean_abs"])
        if locals_["done"]:
            n, s = self._acc[i]
            self._slip.append(s / max(n, 1.0))
            self._acc[i] = 0.0
            if len(self._slip) == self.n_eval_episodes:  # before EvalCallback dumps the row
                self.logger.record("eval/slip_mean_abs", float(np.mean(self._slip)))

    def _on_step(self) -> bool:
        if not (self.eval_freq > 0 and self.n_calls % self.eval_freq == 0):
            return True
        self.eval_env.env_method("rewind")
        self._slip, self._acc[:] = [], 0.0
        best_before = self.best_mean_reward
        cont = super()._on_step()
        slip = float(np.mean(self._slip)) if self._slip else float("nan")
        res = self.evaluations_results[-1]
        _append_row(
            self.run_dir / "evaluations.csv",
            EVAL_FIELDS,
            {
                "timesteps": self.num_timesteps,
                "mean_reward": float(np.mean(res)),
                "std_reward": float(np.std(res)),
                "mean_length": float(np.mean(self.evaluations_length[-1])),
                "slip_mean_abs": slip,
            },
        )
        if self.best_mean_reward > best_before:
            vn = self.model.get_vec_normalize_env()
            if vn is not None:
                vn.save(str(self.run_dir / "best_vecnormalize.pkl"))
        return cont

    def state(self) -> dict[str, Any]:
        return {
            "best_mean_reward": self.best_mean_reward,
            "last_mean_reward": self.last_mean_reward,
            "evaluations_timesteps": list(self.evaluations_timesteps),
            "evaluations_results": list(self.evaluations_results),
            "evaluations_length": list(self.evaluations_length),
        }

    def load_state(self, state: dict[str, Any]) -> None:
        self.best_mean_reward = float(state["best_mean_reward"])
        self.last_mean_reward = float(state["last_mean_reward"])
        self.evaluations_timesteps = list(state["evaluations_timesteps"])
        self.evaluations_results = list(state["evaluations_results"])
        self.evaluations_length = list(state["evaluations_length"])
        if self.log_path is not None and self.evaluations_timesteps:
            np.savez(
                self.log_path,
                timesteps=self.evaluations_timesteps,
                results=self.evaluations_results,
                ep_lengths=self.evaluations_length,
            )


# --------------------------------------------------------------------------- checkpoints

_STATE_RE = re.compile(r"^(ppo|sac|td3)_state_(\d+)_steps\.pkl$")


def checkpoint_paths(ckpt_dir: Path, steps: int, algo: str = "ppo") -> tuple[Path, Path, Path]:
    """Model, VecNormalize stats and training state of the checkpoint at ``steps``."""
    return (
        ckpt_dir / f"{algo}_{steps}_steps.zip",
        ckpt_dir / f"{algo}_vecnormalize_{steps}_steps.pkl",
        ckpt_dir / f"{algo}_state_{steps}_steps.pkl",
    )


def replay_buffer_path(ckpt_dir: Path, steps: int, algo: str) -> Path:
    """An off-policy checkpoint's replay buffer (only the newest checkpoint keeps one)."""
    return ckpt_dir / f"{algo}_replay_buffer_{steps}_steps.pkl"


def latest_checkpoint(ckpt_dir: Path, algo: str = "ppo") -> int | None:
    """Step count of the newest complete checkpoint (the state file is written last)."""
    steps = []
    for p in ckpt_dir.glob(f"{algo}_state_*_steps.pkl") if ckpt_dir.is_dir() else []:
        m = _STATE_RE.match(p.name)
        if m and all(q.is_file() for q in checkpoint_paths(ckpt_dir, int(m.group(2)), algo)):
            steps.append(int(m.group(2)))
    return max(steps) if steps else None


def checkpoint_algo(ckpt_dir: Path) -> str | None:
    """The algorithm whose checkpoints a folder holds (from the state files' names)."""
    for p in sorted(ckpt_dir.glob("*_state_*_steps.pkl")) if ckpt_dir.is_dir() else []:
        m = _STATE_RE.match(p.name)
        if m:
            return m.group(1)
    return None


def rng_state() -> dict[str, Any]:
    """The process-global generators SB3 draws from (actions: torch; minibatches: numpy)."""
    return {
        "python": random.getstate(),
        "numpy": np.random.get_state(),  # noqa: NPY002 - SB3's minibatch shuffling uses it
        "torch": torch.get_rng_state(),
    }


def set_rng_state(state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])  # noqa: NPY002
    torch.set_rng_state(state["torch"])


def _atomic(path: Path, write: Any) -> None:
    tmp = path.with_name(path.name + ".tmp")
    write(tmp)
    os.replace(tmp, path)


class RolloutCheckpoint(BaseCallback):
    """Checkpoint at the start of a rollout, once ``freq`` steps have passed since the last one.

    Only there do the weights, VecNormalize statistics, step count and RNG agree with each
    other (no half-collected rollout), so a resumed run reaches exactly the step counts of an
    uninterrupted one. Saves the model, the VecNormalize statistics and a state file: global
    RNGs, the action space's generator (an off-policy algorithm's random warm-up actions),
    each env's generator, and the evaluation callback's best-so-far. An off-policy
    algorithm's replay buffer is saved with the newest checkpoint (and removed from the one
    before, as it is as large as the buffer), so a resumed SAC/TD3 run continues from the
    same transitions.
    """

    def __init__(self, ckpt_dir: Path, freq: int, meta: dict[str, Any], algo: str = "ppo") -> None:
        super().__init__()
        self.algo = algo
        self.ckpt_dir = ckpt_dir
        self.freq = freq
        self.meta = meta
        self.eval_cb: ValidationEval | None = None
        self.last_saved = 0

    def _on_step(self) -> bool:
        return True

    def _on_rollout_start(self) -> None:
        if self.num_timesteps - self.last_saved >= self.freq:
            self.save()

    def save(self) -> None:
        steps = self.model.num_timesteps
        self.ckpt_dir.mkdir(parents=True, exist_ok=True)
        model_p, vn_p, state_p = checkpoint_paths(self.ckpt_dir, steps, self.algo)
        _atomic(model_p, lambda p: self.model.save(p))
        buffers = sorted(self.ckpt_dir.glob(f"{self.algo}_replay_buffer_*_steps.pkl"))
        has_buffer = getattr(self.model, "replay_buffer", None) is not None
        rb_p = replay_buffer_path(self.ckpt_dir, steps, self.algo)
        if has_buffer:
            _atomic(rb_p, lambda p: self.model.save_replay_buffer(p))  # type: ignore[attr-defined]
        vn = self.model.get_vec_normalize_env()
        if vn is None:
            raise RuntimeError("training env is expected to be wrapped in VecNormalize")
        _atomic(vn_p, lambda p: vn.save(str(p)))
        env = self.model.get_env()
        assert env is not None
        state = {
            **self.meta,
            "num_timesteps": steps,
            "rng": rng_state(),
            "action_space_rng": self.model.action_space.np_random.bit_generator.state,
            "env_rng": env.env_method("rng_state"),
            "eval": None if self.eval_cb is None else self.eval_cb.state(),
        }

        def dump(p: Path) -> None:
            with p.open("wb") as fh:
                pickle.dump(state, fh)

        _atomic(state_p, dump)
        self.last_saved = steps
        for old in buffers if has_buffer else []:
            if old != rb_p:
                old.unlink(missing_ok=True)
