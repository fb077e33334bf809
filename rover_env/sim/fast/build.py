"""Compile the C tire plugin on first use and load it into MuJoCo, once per process.

The C source ships in the package and is built by :func:`rover_env.native.compile_library`
(a cache keyed by the source hash, the MuJoCo version and the compiler flags, published by
atomic rename) against the headers and ``libmujoco.so.<version>`` inside the installed
``mujoco`` wheel.
"""

from __future__ import annotations

import ctypes
import threading
from pathlib import Path

import mujoco

from rover_env.native import NativeBuildError, cache_dir, compile_library

__all__ = [
    "MUJOCO_VERSION",
    "PLUGIN_NAME",
    "FastBackendError",
    "cache_dir",
    "compile_core",
    "compile_plugin",
    "load_core",
    "load_plugin",
]

MUJOCO_VERSION = "4.0.0"
"""The MuJoCo release the plugin is written and verified against (pyproject pins it)."""

PLUGIN_NAME = "rover_env.tire"
SOURCE = "tire_plugin.c"
HEADERS = {"tire_plugin.c": ("soil_nodes.h",)}
"""Headers each source includes from its own directory (copied beside it for the build)."""
CORE_SOURCE = "env_core.c"

_lock = threading.Lock()
_loaded: Path | None = None
_core: ctypes.CDLL | None = None


class FastBackendError(NativeBuildError):
    """The plugin backend cannot be used here (compiler missing, wrong MuJoCo, failed build)."""


def _mujoco_paths() -> tuple[Path, Path]:
    if mujoco.__version__ != MUJOCO_VERSION:
        raise FastBackendError(
            f"backend='plugin' is built for MuJoCo {MUJOCO_VERSION}, but mujoco "
            f"{mujoco.__version__} is installed; install mujoco=={MUJOCO_VERSION} "
            "(the README's set-up command does) or use backend='numpy'"
        )
    pkg = Path(mujoco.__file__).resolve().parent
    include = pkg / "include"
    lib = pkg / f"libmujoco.so.{MUJOCO_VERSION}"
    if not (include / "mujoco" / "mujoco.h").is_file() or not lib.is_file():
        raise FastBackendError(
            f"the mujoco package at {pkg} lacks include/mujoco/mujoco.h or {lib.name};"
            " reinstall mujoco from its wheel, or use backend='numpy'"
        )
    return include, lib


def compile_plugin() -> Path:
    """Path of the compiled plugin library, building it into the cache if needed."""
    return _compile(SOURCE, "rover_env_tire")


def compile_core() -> Path:
    """Path of the compiled env core (sensor model, slip estimator, sample loop)."""
    return _compile(CORE_SOURCE, "rover_env_core")


def _compile(source_name: str, stem: str) -> Path:
    include, lib = _mujoco_paths()
    try:
        return compile_library(
            "rover_env.sim.fast",
            source_name,
            f"{stem}-mujoco{MUJOCO_VERSION}",
            headers=HEADERS.get(source_name, ()),
            pre=(f"-I{include}",),
            post=(f"-L{lib.parent}", f"-l:{lib.name}", f"-Wl,-rpath,{lib.parent}", "-lm"),
            key=MUJOCO_VERSION.encode(),
            hint="; backend='numpy' works without one",
        )
    except NativeBuildError as e:
        raise FastBackendError(str(e)) from e


def load_plugin() -> Path:
    """Build (if needed) and register the plugin with MuJoCo; later calls return at once."""
    global _loaded
    with _lock:
        if _loaded is None:
            path = compile_plugin()
            mujoco.mj_loadPluginLibrary(str(path))
            _loaded = path
        return _loaded


def load_core() -> ctypes.CDLL:
    """Build (if needed) and open the env core library (``env_core.c``); cached per process."""
    global _core
    with _lock:
        if _core is None:
            _core = ctypes.CDLL(str(compile_core()))
        return _core
