"""The seed plan, re-exported: it lives in :mod:`rover_env.seeds` (bottom layer, so the envs
can keep a seed inside its split too)."""

from rover_env.seeds import (
    HELD_OUT,
    SPENT,
    SPLITS,
    assert_disjoint,
    check_split,
    draw_seed,
    refuse_final_only,
    seeds,
    split_of,
    training_seed,
)

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
