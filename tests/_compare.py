"""Comparison helper shared by the tests that demand bit-identical results."""

from __future__ import annotations

from typing import Any

import numpy as np


def same(a: Any, b: Any, where: str = "") -> None:
    """Equal structure, dtypes and bits (nested tuples, lists, dicts and arrays)."""
    if isinstance(a, tuple | list):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            same(x, y, f"{where}[{k}]")
    elif isinstance(a, dict):
        assert list(a) == list(b), (where, list(a), list(b))
        for k in a:
            same(a[k], b[k], f"{where}/{k}")
    else:
        x, y = np.asarray(a), np.asarray(b)
        assert (x.dtype, x.shape) == (y.dtype, y.shape), (where, x.dtype, y.dtype, x.shape, y.shape)
        if x.dtype == object:
            for u, v in zip(x, y, strict=True):
                same(u, v, where)
        else:
            np.testing.assert_array_equal(x, y, err_msg=where)
