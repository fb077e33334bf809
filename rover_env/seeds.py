"""The project's one seed plan: which seeds tune, train, validate and test.

Every number reported for a controller is measured on seeds it was never fitted on. Disjoint
blocks of integers, one per use:

=============  =====================  ==========================================================
split          seeds                  used by
=============  =====================  ==========================================================
``tuning``     1000 .. 1099           gain tuning of hand-built controllers (``tune-slip-pi``)
``validation`` 2000 .. 2099           model selection while training (early stopping, sweeps)
``test``       4000 .. 4999           the benchmark's final runs only (``--final``), each one a
                                      look at a registered question (the test ledger)
``spent``      3000 .. 3999           the former test block, looked at by the final runs before
                                      issue 46: refused for every new use (history only)
``training``   100_000 .. 1_099_999   RL training: environment i of a run seeds with
                                      ``training_seed(run, i)``, episodes continue the stream
=============  =====================  ==========================================================

A seed drives one episode: the env's ``reset(seed=...)`` (sensor and IMU noise streams) and
the scenario's jitter of start pose and ground (:mod:`rover_env.benchmark.scenarios`). The
same seed gives every controller the same episode, so differences are paired.

Every entry point keeps a seed inside its split (:func:`split_of`): a validation seed plays a
validation episode wherever it enters (the env, the scenario mix, the wrappers, the benchmark,
the training callbacks), and where an entry point draws further episode seeds itself it draws
them from the split of the seed it was given (:func:`draw_seed`). Seeds outside every block
(e.g. 0 or 7 in a quick test) are not held out: they count as training seeds. Test seeds are
played only by a final run, spent seeds by nothing (:func:`refuse_final_only`).

This module sits at the bottom of the layers (numpy only) so that the envs can check seeds
too; ``rover_env.benchmark.seeds`` re-exports it.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

__all__ = [
    "HELD_OUT",
    "SPENT",
    "SPLITS",
    "assert_disjoint",
    "check_split",
    "draw_seed",
    "refuse_final_only",
    "seeds",
    "split_of",
    "training_seed",
]

SPLITS: dict[str, range] = {
    "tuning": range(1000, 1100),
    "validation": range(2000, 2100),
    "test": range(4000, 5000),
    "spent": range(3000, 4000),
    "training": range(100_000, 1_100_000),
}

HELD_OUT = ("tuning", "validation", "test", "spent")
"""Splits whose seeds no training may touch."""

SPENT = "spent"
"""The split no one may use again (the test block of the final runs before issue 46)."""


def _usable(split: str, where: str) -> None:
    if split not in SPLITS:
        raise ValueError(f"{where}: unknown seed split {split!r}; have {', '.join(SPLITS)}")
    if split == SPENT:
        block = SPLITS[SPENT]
        raise ValueError(
            f"{where}: the {SPENT} seeds {block.start}..{block.stop - 1} were looked at by "
            "earlier final runs and take no new use; the test block is "
            f"{SPLITS['test'].start}..{SPLITS['test'].stop - 1} (rover_env.seeds)"
        )


def refuse_final_only(seed_list: Iterable[int], where: str, final: bool = False) -> None:
    """ValueError naming ``where`` for any spent seed, and for test seeds unless ``final``
    (a final run, which the test ledger records)."""
    s = [int(x) for x in seed_list]
    spent = sorted({x for x in s if split_of(x) == SPENT})
    if spent:
        _usable(SPENT, f"{where} (seeds {spent[:5]})")
    test = sorted({x for x in s if split_of(x) == "test"})
    if test and not final:
        raise ValueError(
            f"{where}: seeds {test[:5]} are test seeds, played only by a final run "
            "(rover-env benchmark --final --question ID), which the test ledger records"
        )


_TRAINING_ENVS_PER_RUN = 1000


def split_of(seed: int) -> str:
    """The split ``seed`` belongs to; seeds outside every block count as ``"training"``."""
    s = int(seed)
    for name in HELD_OUT:
        if s in SPLITS[name]:
            return name
    return "training"


def draw_seed(split: str, rng: np.random.Generator) -> int:
    """One episode seed of ``split``, uniform over its block, from ``rng`` (never spent)."""
    _usable(split, "draw_seed")
    block = SPLITS[split]
    return int(rng.integers(block.start, block.stop))


def check_split(seed_list: Iterable[int], split: str, where: str) -> list[int]:
    """``seed_list`` as ints, each checked to lie in ``split`` (ValueError naming ``where``)."""
    _usable(split, where)
    out = [int(s) for s in seed_list]
    bad = [s for s in out if split_of(s) != split]
    if bad:
        raise ValueError(
            f"{where}: seeds {bad[:5]} are not {split} seeds ({split} is "
            f"{SPLITS[split].start}..{SPLITS[split].stop - 1}; rover_env.seeds)"
        )
    return out


def seeds(split: str, n: int | None = None) -> list[int]:
    """The first ``n`` seeds of ``split`` (all when None); always the same ones, in order."""
    _usable(split, "seeds")
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
