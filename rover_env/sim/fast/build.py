"""Compile the C tire plugin on first use and load it into MuJoCo, once per process.

pip builds the package in an isolated environment whose paths vanish, so nothing is
compiled at install time: the C source ships in the package and is built here against the
headers and ``libmujoco.so.<version>`` inside the installed ``mujoco`` wheel, into a cache
directory keyed by the source hash, the MuJoCo version and the compiler flags. Concurrent
processes each compile to a private temporary file and publish it with an atomic rename,
so they never see a half-written library and need no lock.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
import threading
from importlib import resources
from pathlib import Path

import mujoco

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
# -ffp-contract=off: a fused multiply-add would round differently from numpy's reference.
CFLAGS = ("-O2", "-std=c11", "-fPIC", "-shared", "-ffp-contract=off", "-fno-math-errno")

_lock = threading.Lock()
_loaded: Path | None = None
_core: ctypes.CDLL | None = None


class FastBackendError(RuntimeError):
    """The plugin backend cannot be used here (compiler missing, wrong MuJoCo, failed build)."""


def cache_dir() -> Path:
    """``$ROVER_ENV_CACHE``, else ``$XDG_CACHE_HOME/rover_env``, else ``~/.cache/rover_env``."""
    env = os.environ.get("ROVER_ENV_CACHE")
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "rover_env"


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


def _compiler() -> str:
    for name in (os.environ.get("CC"), "gcc", "cc"):
        if name and (path := shutil.which(name)):
            return path
    raise FastBackendError(
        "backend='plugin' compiles a small C library on first use and needs a C compiler:"
        " install gcc (Debian/Ubuntu: `apt-get install gcc`, Fedora: `dnf install gcc`),"
        " or set CC; backend='numpy' works without one"
    )


def compile_plugin() -> Path:
    """Path of the compiled plugin library, building it into the cache if needed."""
    return _compile(SOURCE, "rover_env_tire")


def compile_core() -> Path:
    """Path of the compiled env core (sensor model, slip estimator, sample loop)."""
    return _compile(CORE_SOURCE, "rover_env_core")


def _compile(source_name: str, stem: str) -> Path:
    include, lib = _mujoco_paths()
    package = resources.files("rover_env.sim.fast")
    source = package.joinpath(source_name).read_bytes()
    headers = {h: package.joinpath(h).read_bytes() for h in HEADERS.get(source_name, ())}
    key = hashlib.sha256(
        b"\0".join([source, *headers.values(), MUJOCO_VERSION.encode(), " ".join(CFLAGS).encode()])
    ).hexdigest()[:16]
    out_dir = cache_dir()
    target = out_dir / f"{stem}-mujoco{MUJOCO_VERSION}-{key}.so"
    if target.is_file():
        return target
    cc = _compiler()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise FastBackendError(
            f"cannot create the plugin cache {out_dir} ({e}); set ROVER_ENV_CACHE"
        ) from e
    with tempfile.TemporaryDirectory(dir=out_dir, prefix=".build-") as tmp:
        src = Path(tmp) / source_name
        src.write_bytes(source)
        for name, text in headers.items():
            (Path(tmp) / name).write_bytes(text)
        obj = Path(tmp) / target.name
        cmd = [
            cc,
            *CFLAGS,
            f"-I{include}",
            str(src),
            "-o",
            str(obj),
            f"-L{lib.parent}",
            f"-l:{lib.name}",
            f"-Wl,-rpath,{lib.parent}",
            "-lm",
        ]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            raise FastBackendError(
                f"compiling {source_name} failed:\n$ {' '.join(cmd)}\n{proc.stderr.strip()}"
            )
        # Atomic publish: a concurrent process either sees no file or a complete one.
        os.replace(obj, target)
    return target


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
