"""Verilator's runtime objects, built once per flag set (bottom layer).

Every Verilator model links ``verilated.o`` and its kin (threads, DPI, VPI, timing): the same
objects for every model built with the same Verilator, flags and compiler options, and most of
a small model's build (tens of CPU seconds). :func:`reusing_runtime` copies the objects of an
earlier build with the same key into a new object folder before the build, and keeps those of
the first build of a key afterwards, in ``cache_root()/verilator-runtime/<key>``.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import subprocess
import time
from functools import cache
from pathlib import Path

from .cbuild import cache_root

__all__ = ["RUNTIME_OBJECTS", "reusing_runtime"]

#: The runtime's object files (those a build makes; the others are skipped).
RUNTIME_OBJECTS = ("verilated", "verilated_vpi", "verilated_threads", "verilated_dpi", "verilated_timing")


@cache
def _version(tool: str) -> str:
    return subprocess.run([tool, "--version"], capture_output=True, text=True).stdout.strip()


def _folder(tool: str, key_parts) -> Path:
    # The installation too, not only its version: the objects' dependency files name its headers
    # by absolute path (two venvs with the same Verilator share nothing; make would stop at a
    # header of the other's that is gone).
    where = os.path.realpath(shutil.which(tool) or tool)
    key = json.dumps([_version(tool), where, os.environ.get("CXX", "c++"), *map(str, key_parts)])
    return cache_root() / "verilator-runtime" / hashlib.sha256(key.encode()).hexdigest()[:20]


def _seed(cached: Path, obj_dir: Path) -> None:
    obj_dir.mkdir(parents=True, exist_ok=True)
    # verilated.mk makes the objects depend on the model's .mk, which every verilator run rewrites:
    # dated ahead, make keeps them.
    ahead = time.time() + 10 * 365 * 86400
    for src in cached.iterdir():
        shutil.copy2(src, obj_dir / src.name)
        os.utime(obj_dir / src.name, (ahead, ahead))


def _runtime_files(obj_dir: Path) -> list[Path]:
    files = [obj_dir / f"{name}{ext}" for name in RUNTIME_OBJECTS for ext in (".o", ".d")]
    return [path for path in files if path.is_file()]


def _keep(obj_dir: Path, cached: Path) -> None:
    made = _runtime_files(obj_dir)
    if not made:
        return
    tmp = cached.with_name(f"{cached.name}.tmp{os.getpid()}")
    tmp.mkdir(parents=True, exist_ok=True)
    for path in made:
        shutil.copy2(path, tmp / path.name)
    try:
        tmp.rename(cached)          # atomic: another process may have kept the same key first
    except OSError:
        shutil.rmtree(tmp, ignore_errors=True)


@contextlib.contextmanager
def reusing_runtime(tool: str, obj_dir: Path, key_parts):
    """Around a Verilator build into ``obj_dir``: its runtime objects from the cache when a build
    with the same ``key_parts`` (the flags that reach the runtime's compile: Verilator's options,
    CFLAGS, make variables) made them before, else kept from this build if it succeeds."""
    cached = _folder(tool, key_parts)
    if cached.is_dir():
        _seed(cached, obj_dir)
    else:       # none kept yet: whatever an earlier build left in obj_dir may be another key's
        for path in _runtime_files(obj_dir):
            path.unlink()
    yield
    if not cached.is_dir():
        _keep(obj_dir, cached)
