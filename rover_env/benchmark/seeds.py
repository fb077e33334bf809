"""The project's one seed plan: which seeds tune, train, validate and test.

Every number reported for a controller is measured on seeds it was never fitted on. Four
disjoint blocks of integers, one per use:

=============  =====================  ==========================================================
split          seeds                  used by
=============  =====================  ==========================================================
``tuning``     1000 .. 1099           gain tuning of hand-built controllers (``tune-slip-pi``)
``validation`` 2000 .. 2099           model selection while training (early stopping, sweeps)
``test``       3000 .. 3099           the benchmark's reported tables; touch only to report
``training``   100_000 .. 1_099_999   RL training: environment i of a run seeds with
                                      ``training_seed(run, i)``, episodes continue the stream
=============  =====================  ==========================================================

A seed drives one episode: the env's ``reset(seed=...)`` (sensor and IMU noise streams) and
the scenario's jitter of start pose and ground (:mod:`rover_env.benchmark.scenarios`). The
same seed gives every controller the same episode, so differences are paired.
"""

from __future__ import annotations

__all__ = [
    "SPLITS",
    "assert_disjoint",
    "seeds",
    "training_seed",
]

SPLITS: dict[str, range] = {
    "tuning": range(1000, 1100),
    "validation": range(2000, 2100),
    "test": range(3000, 3100),
    "training": range(100_000, 1_100_000),
}

_TRAINING_ENVS_PER_RUN = 1000


def seeds(split: str, n: int | None = None) -> list[int]:
    """The first ``n`` seeds of ``split`` (all when None); always the same ones, in order."""
    if split not in SPLITS:
        raise ValueError(f"unknown seed split {split!r}; have {', '.join(SPLITS)}")
    block = SPLITS[split]
    if n is None:
        return list(block)
    if not 0 <= n <= len(block):
        raise ValueError(f"split {split!r} holds {len(block)} seeds, asked for {n}")
    return list(block[:n])


def training_seed(run: int, env_index: int = 0) -> int:
    """Seed of vectorised environment ``env_index`` in training run ``run`` (both >= 0)."""
    if not 0 <= env_index < _TRAINING_ENVS_PER_RUN or run < 0:
        raise ValueError(f"need run >= 0 and 0 <= env_index < {_TRAINING_ENVS_PER_RUN}")
    s = SPLITS["training"].start + run * _TRAINING_ENVS_PER_RUN + env_index
    if s not in SPLITS["training"]:
        raise ValueError(f"training run {run} is beyond the training block")
    return s


def assert_disjoint() -> None:
    """Raise AssertionError if any two splits share a seed."""
    names = list(SPLITS)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            ra, rb = SPLITS[a], SPLITS[b]
            overlap = max(ra.start, rb.start) < min(ra.stop, rb.stop)
            assert not overlap, f"seed splits {a} and {b} overlap"
