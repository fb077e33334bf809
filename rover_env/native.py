"""Small C libraries shipped as source, compiled on first use and opened with ctypes.

pip builds the package in an isolated environment whose paths vanish, so nothing is compiled
at install time: each C source ships in its package and is built here into a cache directory
keyed by the source's hash and the compiler flags. Concurrent processes each compile to a
private temporary file and publish it with an atomic rename, so they never see a half-written
library and need no lock. The tire plugin (:mod:`rover_env.sim.fast.build`) adds MuJoCo's
headers and library; the command effects' recursions (:mod:`rover_env.effects.native`) need
only the C library.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

__all__ = ["CFLAGS", "NativeBuildError", "cache_dir", "compile_library", "compiler"]

# -ffp-contract=off: a fused multiply-add would round differently from numpy's and Python's
# float arithmetic, which every compiled path must reproduce to the bit.
CFLAGS = ("-O2", "-std=c11", "-fPIC", "-shared", "-ffp-contract=off", "-fno-math-errno")


class NativeBuildError(RuntimeError):
    """A shipped C library cannot be built here (no compiler, no writable cache, failed build)."""


def cache_dir() -> Path:
    """``$ROVER_ENV_CACHE``, else ``$XDG_CACHE_HOME/rover_env``, else ``~/.cache/rover_env``."""
    env = os.environ.get("ROVER_ENV_CACHE")
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "rover_env"


def compiler(hint: str = "") -> str:
    """Path of the C compiler (``$CC``, ``gcc`` or ``cc``); ``hint`` ends the error."""
    for name in (os.environ.get("CC"), "gcc", "cc"):
        if name and (path := shutil.which(name)):
            return path
    raise NativeBuildError(
        "rover_env compiles small C libraries on first use and needs a C compiler:"
        " install gcc (Debian/Ubuntu: `apt-get install gcc`, Fedora: `dnf install gcc`),"
        f" or set CC{hint}"
    )


def compile_library(
    package: str,
    source_name: str,
    stem: str,
    *,
    headers: Sequence[str] = (),
    pre: Sequence[str] = (),
    post: Sequence[str] = ("-lm",),
    key: bytes = b"",
    hint: str = "",
) -> Path:
    """Path of ``source_name`` (with ``headers`` beside it, all from ``package``) compiled to
    a shared library in the cache, built if needed. ``pre`` and ``post`` are compiler
    arguments before and after the source; ``key`` is anything else the build depends on
    (a library's version); ``hint`` ends a missing compiler's message."""
    pkg = resources.files(package)
    source = pkg.joinpath(source_name).read_bytes()
    texts = {h: pkg.joinpath(h).read_bytes() for h in headers}
    digest = hashlib.sha256(
        b"\0".join([source, *texts.values(), key, " ".join([*CFLAGS, *pre, *post]).encode()])
    ).hexdigest()[:16]
    out_dir = cache_dir()
    target = out_dir / f"{stem}-{digest}.so"
    if target.is_file():
        return target
    cc = compiler(hint)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise NativeBuildError(
            f"cannot create the library cache {out_dir} ({e}); set ROVER_ENV_CACHE"
        ) from e
    with tempfile.TemporaryDirectory(dir=out_dir, prefix=".build-") as tmp:
        src = Path(tmp) / source_name
        src.write_bytes(source)
        for name, text in texts.items():
            (Path(tmp) / name).write_bytes(text)
        obj = Path(tmp) / target.name
        cmd = [cc, *CFLAGS, *pre, str(src), "-o", str(obj), *post]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            raise NativeBuildError(
                f"compiling {source_name} failed:\n$ {' '.join(cmd)}\n{proc.stderr.strip()}"
            )
        # Atomic publish: a concurrent process either sees no file or a complete one.
        os.replace(obj, target)
    return target
