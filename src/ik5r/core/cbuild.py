"""Cached C builds (bottom layer): a build directory keyed by a hash of its sources, the compiler
and the flags, and an atomic compile into it. The firmware's C solver (``ik5r.firmware_model.csolver``)
and the numeric kernel (``ik5r.numeric.lmkernel``) both build through it, so neither needs the other.

The cache is ``$IK5R_CACHE_DIR``, else ``$XDG_CACHE_HOME/ik5r``, else ``~/.cache/ik5r``; a change of
source, compiler or flag gives a new directory, an unchanged one reuses the build. Builds are
atomic (temporary file + rename), so concurrent test processes are safe, and made once: a process
wanting a build another is making waits for it (:func:`path_lock`).
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import subprocess
import tempfile
import threading
from pathlib import Path

__all__ = ["SANITIZE_FLAGS", "cache_root", "compiler", "keyed_dir", "compile_cached", "path_lock"]

#: Sanitizer build of the test driver; IK5R_CHECK_BOUNDS traps (in the firmware's C) on a narrowing out of int32.
SANITIZE_FLAGS = ("-O1", "-g", "-std=c99", "-pedantic", "-Wall", "-Wextra", "-fno-omit-frame-pointer",
                  "-fsanitize=undefined,address", "-fno-sanitize-recover=all", "-DIK5R_CHECK_BOUNDS")


def cache_root() -> Path:
    """Where build directories live: $IK5R_CACHE_DIR, $XDG_CACHE_HOME/ik5r or ~/.cache/ik5r."""
    if os.environ.get("IK5R_CACHE_DIR"):
        return Path(os.environ["IK5R_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "ik5r"


def compiler() -> str:
    """The host C compiler: $CC, else ``cc``."""
    return os.environ.get("CC", "cc")


def _write_atomic(path: Path, data: bytes) -> None:
    if path.exists() and path.read_bytes() == data:
        return
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "wb") as handle:
        handle.write(data)
    os.replace(tmp, path)


def keyed_dir(prefix: str, contents: dict[str, bytes], flags: tuple[str, ...]) -> Path:
    """A cache directory holding ``contents`` (name -> bytes), keyed by a hash of them, the
    compiler and ``flags``; any C build (this solver's, ik5r's numeric kernel) goes through it."""
    digest = hashlib.sha256()
    for name, data in contents.items():
        digest.update(name.encode() + b"\0" + data + b"\0")
    digest.update(compiler().encode() + b"\0" + "\0".join(flags).encode())
    directory = cache_root() / f"{prefix}-{digest.hexdigest()[:20]}"
    directory.mkdir(parents=True, exist_ok=True)
    for name, data in contents.items():
        _write_atomic(directory / name, data)
    return directory


_PATH_LOCKS: dict[str, threading.Lock] = {}


@contextlib.contextmanager
def path_lock(path: Path):
    """Held by one thread of one process at a time: a thread lock per path, then an exclusive
    lock on the file ``path`` (created). Around a cached build, a second process wanting the same
    build waits for the first and then finds it made (pytest-xdist workers often want the same
    build at the same time)."""
    lock = _PATH_LOCKS.setdefault(str(path), threading.Lock())
    with lock, open(path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def compile_cached(directory: Path, output: str, flags: tuple[str, ...], sources: tuple[str, ...],
                   libs: tuple[str, ...] = ()) -> Path:
    """``directory/output`` built from ``sources`` (in ``directory``) with ``flags`` (``libs``
    after the sources), once; atomic."""
    target = directory / output
    if target.exists():
        return target
    with path_lock(directory / f".{output}.lock"):
        return target if target.exists() else _compile(directory, target, flags, sources, libs)


def _compile(directory: Path, target: Path, flags, sources, libs) -> Path:
    output = target.name
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{output}.")
    os.close(fd)
    cmd = [compiler(), *flags, "-I", str(directory), *(str(directory / s) for s in sources), *libs, "-o", tmp]
    result = subprocess.run(cmd, capture_output=True, text=True)
    if result.returncode != 0:
        os.unlink(tmp)
        raise RuntimeError(f"C build failed ({' '.join(cmd)}):\n{result.stderr}")
    os.replace(tmp, target)
    return target
