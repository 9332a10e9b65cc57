"""Issue 29's size floors, read with ``ast`` from every module of ``src/``, ``hdl/`` and
``firmware_model/``: no module over 400 lines, no function (a ``def`` from its first line to its
last, nested ones inside it counted) over 60. A long function or module is where a reader loses
the thread, and the split that fixes it usually names a step the code had left unnamed."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TREES = ("src", "hdl", "firmware_model")
MODULE_LINES = 400
FUNCTION_LINES = 60


def oversized(paths) -> list[str]:
    """``path: N lines`` for each module over :data:`MODULE_LINES`, ``path:line name(): N lines``
    for each function over :data:`FUNCTION_LINES`."""
    found = []
    for path in paths:
        text = path.read_text()
        lines = len(text.splitlines())
        if lines > MODULE_LINES:
            found.append(f"{path}: {lines} lines")
        for node in ast.walk(ast.parse(text, str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > FUNCTION_LINES:
                    found.append(f"{path}:{node.lineno} {node.name}(): {length} lines")
    return found


def sources() -> list[Path]:
    return sorted(path for tree in TREES for path in (ROOT / tree).rglob("*.py"))


def test_the_scan_reads_every_tree():
    names = {path.relative_to(ROOT).parts[0] for path in sources()}
    assert names == set(TREES)
    assert len(sources()) > 100


def test_an_oversized_module_and_function_are_found(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(FUNCTION_LINES))      # def line + 60 = 61
    long_def = tmp_path / "long_def.py"
    long_def.write_text(f"def f():\n{body}\n\n\ndef g():\n{body[:-len(body.splitlines()[-1]) - 1]}\n")
    long_module = tmp_path / "long_module.py"
    long_module.write_text("x = 0\n" * (MODULE_LINES + 1))
    at_limit = tmp_path / "at_limit.py"
    at_limit.write_text("x = 0\n" * MODULE_LINES)
    assert oversized([long_def, long_module, at_limit]) == [
        f"{long_def}:1 f(): {FUNCTION_LINES + 1} lines", f"{long_module}: {MODULE_LINES + 1} lines"]


def test_no_module_or_function_over_the_limits():
    assert oversized(sources()) == []
