"""The command effects' recursions compiled (``recursions.c``), or None where they cannot be.

A command lag's state is a recursion over every substep of a replayed window (issue 47: on
Python floats it took 26 of 212 s in the profile of one lag case's diagnosis, whose partner
fits all carry the lag). The compiled loops give the same numbers to the bit; where no C
compiler is found, or with ``ROVER_ENV_NATIVE=0``, the effects run their Python loops (the
same numbers, slower).
"""

from __future__ import annotations

import ctypes
import os
import threading

import numpy as np
from numpy.typing import NDArray

from rover_env.native import NativeBuildError, compile_library

__all__ = ["lag_prime", "lag_sequence", "library"]

Array = NDArray[np.float64]
_DOUBLES = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
_lock = threading.Lock()
_lib: ctypes.CDLL | None = None
_tried = False


def library() -> ctypes.CDLL | None:
    """The compiled recursions, built on first use; None when off or unbuildable."""
    global _lib, _tried
    if os.environ.get("ROVER_ENV_NATIVE", "1") == "0":
        return None
    with _lock:
        if not _tried:
            _tried = True
            try:
                lib = ctypes.CDLL(
                    str(
                        compile_library("rover_env.effects", "recursions.c", "rover_env_recursions")
                    )
                )
            except (NativeBuildError, OSError):
                return None
            lib.lag_sequence.argtypes = [
                _DOUBLES,
                ctypes.c_long,
                ctypes.c_long,
                ctypes.c_double,
                _DOUBLES,
                _DOUBLES,
            ]
            lib.lag_sequence.restype = None
            lib.lag_prime.argtypes = [_DOUBLES, _DOUBLES, ctypes.c_long, ctypes.c_long, _DOUBLES]
            lib.lag_prime.restype = None
            _lib = lib
        return _lib


def lag_sequence(rows: Array, a: float, x: Array) -> tuple[Array, Array] | None:
    """(out, state after) of a lag with factor ``a`` from state ``x`` over ``rows`` (n, m)."""
    lib = library()
    if lib is None:
        return None
    u = np.ascontiguousarray(rows, dtype=np.float64)
    state = np.array(x, dtype=np.float64)
    out = np.empty_like(u)
    lib.lag_sequence(u, u.shape[0], u.shape[1], a, state, out)
    return out, state


def lag_prime(cmd: Array, f: Array) -> Array | None:
    """A lag's state from rest after the rows of ``cmd`` (n, m), each with its factor ``f``."""
    lib = library()
    if lib is None:
        return None
    c = np.ascontiguousarray(cmd, dtype=np.float64)
    fk = np.ascontiguousarray(f, dtype=np.float64)
    x = np.zeros(c.shape[1])
    lib.lag_prime(c, fk, c.shape[0], c.shape[1], x)
    return x
