"""The import graph of ik5r, read from the source files with ``ast`` (nothing is imported).

``closure(["ik5r.hdl.generate"])`` is every ik5r module file a module reaches through its imports
(also the ones inside functions, and the ``__init__`` of every package on the way): what a result
made from it depends on. The cache keys of the sweep are hashes of such closures
(:func:`closure_hash`), so a change anywhere the Verilog or the error figures come from, and only
there, makes a cached result stale. ``tests/test_layers.py`` checks the layers on the same graph.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
from functools import cache
from pathlib import Path

__all__ = ["package_dirs", "all_modules", "imports_of", "closure", "closure_hash"]

#: The installed packages whose folder is not ``ik5r``'s subfolder (pyproject.toml's package-dir).
TOP_PACKAGES = ("ik5r", "ik5r.firmware_model", "ik5r.hdl")


@cache
def package_dirs() -> dict[str, Path]:
    """Import name -> source folder of each top package."""
    dirs = {}
    for name in TOP_PACKAGES:
        spec = importlib.util.find_spec(name)
        dirs[name] = Path(next(iter(spec.submodule_search_locations))).resolve()
    return dirs


@cache
def all_modules() -> dict[str, Path]:
    """Every ik5r module by import name (a package by its ``__init__.py``)."""
    dirs = package_dirs()
    found = {}
    for package, folder in dirs.items():
        for path in sorted(folder.rglob("*.py")):
            if any(path.is_relative_to(other) for other in dirs.values()
                   if other != folder and other.is_relative_to(folder)):
                continue
            parts = path.relative_to(folder).with_suffix("").parts
            found[".".join((package, *parts)).removesuffix(".__init__")] = path
    return found


def imports_of(module: str, path: Path) -> set[str]:
    """The ik5r names ``module`` (at ``path``) imports, absolute or relative, at any depth of the
    file; ``from ik5r import status`` gives ``ik5r`` and ``ik5r.core.status`` (a name that is not a
    module is harmless: :func:`all_modules` does not know it)."""
    is_package = path.name == "__init__.py"
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            target = node.module
            if node.level:
                parts = module.split(".")
                base = parts[: len(parts) - node.level + is_package]
                target = ".".join(base + ([node.module] if node.module else []))
            out.add(target)
            out.update(f"{target}.{alias.name}" for alias in node.names)
    return {name for name in out if name == "ik5r" or name.startswith("ik5r.")}


def closure(roots) -> list[Path]:
    """The files of ``roots`` and of every ik5r module they import, directly or not, with the
    ``__init__`` of each package on the way; sorted."""
    mods = all_modules()
    seen, todo = set(), list(roots)
    while todo:
        name = todo.pop()
        if name in seen or name not in mods:
            continue
        seen.add(name)
        todo.extend(imports_of(name, mods[name]))
        todo.extend(".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 1))
    return sorted(mods[name] for name in seen)


def closure_hash(roots, extra=()) -> str:
    """16 hex digits of SHA-256 over the files of :func:`closure` (by path inside their package)
    and the ``extra`` files (data the code reads)."""
    dirs = package_dirs()
    h = hashlib.sha256()
    for path in [*closure(roots), *sorted(extra)]:
        package = next((name for name, folder in dirs.items() if path.is_relative_to(folder)), "")
        folder = dirs.get(package, path.parent)
        h.update(f"{package}/{path.relative_to(folder)}".encode() + b"\0")
        h.update(path.read_bytes())
    return h.hexdigest()[:16]
