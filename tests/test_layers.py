"""The layers of ik5r, asserted from the import graph (every ``import`` of every module, also the
ones inside functions, read with ``ast``; nothing is imported to find them).

    tools     ik5r.cli, commands, synth, sweep, bench, results, report, demo; the testbenches
              (ik5r.hdl.tb), which check the HDL against the firmware model
    firmware  ik5r.firmware (model, vector, C, codegen)  |  hdl  ik5r.hdl (Amaranth blocks)
    core      ik5r.fxconfig, arm, reference, status, csvio, errors, fixedpoint

A layer imports only its own and the layers below it; firmware and hdl are two implementations
of the one IK, side by side: neither imports the other (the fixed-point words they share are
``ik5r.fixedpoint``). See docs/architecture.md.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Import name -> source folder (pyproject.toml's package-dir).
PACKAGES = {"ik5r": ROOT / "src" / "ik5r", "ik5r.firmware": ROOT / "firmware_model", "ik5r.hdl": ROOT / "hdl"}
CORE = {"ik5r", "ik5r.fxconfig", "ik5r.arm", "ik5r.reference", "ik5r.status", "ik5r.csvio",
        "ik5r.errors", "ik5r.fixedpoint", "ik5r.data"}
#: What each layer may import (besides third-party packages).
ALLOWED = {"core": {"core"}, "firmware": {"core", "firmware"}, "hdl": {"core", "hdl"},
           "tools": {"core", "firmware", "hdl", "tools"}}


def layer_of(module: str) -> str:
    if module in CORE:
        return "core"
    if module.startswith("ik5r.hdl.tb"):
        return "tools"
    for package, layer in (("ik5r.firmware", "firmware"), ("ik5r.hdl", "hdl")):
        if module == package or module.startswith(package + "."):
            return layer
    return "tools"


def modules() -> dict[str, Path]:
    """Every module of the installed packages, by import name."""
    found = {}
    for package, folder in PACKAGES.items():
        for path in folder.rglob("*.py"):
            parts = path.relative_to(folder).with_suffix("").parts
            found[".".join((package, *parts)).removesuffix(".__init__")] = path
    return found


def imports_of(module: str, path: Path) -> set[str]:
    """The ik5r modules ``module`` imports (absolute and relative, at any depth of the file)."""
    is_package = path.name == "__init__.py"
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")[: len(module.split(".")) - node.level + is_package]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            out.add(target)
            # ``from ik5r import status``: the submodule, when it is one.
            out.update(f"{target}.{alias.name}" for alias in node.names)
    return {name for name in out if name == "ik5r" or name.startswith("ik5r.")}


def violations(mods: dict[str, Path] | None = None) -> list[str]:
    mods = modules() if mods is None else mods
    bad = []
    for module, path in sorted(mods.items()):
        for target in sorted(imports_of(module, path)):
            if target not in mods:
                continue            # a name imported from a module, not a module
            if layer_of(target) not in ALLOWED[layer_of(module)]:
                bad.append(f"{path}: {module} ({layer_of(module)}) imports "
                           f"{target} ({layer_of(target)})")
    return bad


def test_the_graph_is_read():
    mods = modules()
    assert {"ik5r.fxconfig", "ik5r.firmware.model", "ik5r.hdl.ik_core", "ik5r.hdl.tb.runner",
            "ik5r.commands.solve", "ik5r.fixedpoint"} <= set(mods)
    assert "ik5r.fixedpoint" in imports_of("ik5r.hdl.ik_core", mods["ik5r.hdl.ik_core"])
    assert "ik5r.hdl.common" in imports_of("ik5r.hdl.cordic", mods["ik5r.hdl.cordic"])
    assert layer_of("ik5r.hdl.tb.blocks") == "tools" and layer_of("ik5r.hdl.cordic") == "hdl"


def test_a_violation_is_found(tmp_path):
    core = tmp_path / "status.py"
    core.write_text("def f():\n    from .commands import solve\n")
    hdl = tmp_path / "ik_core.py"
    hdl.write_text("from ik5r.firmware import model\n")
    mods = {**modules(), "ik5r.status": core, "ik5r.hdl.ik_core": hdl}
    assert violations(mods) == [
        f"{hdl}: ik5r.hdl.ik_core (hdl) imports ik5r.firmware (firmware)",
        f"{hdl}: ik5r.hdl.ik_core (hdl) imports ik5r.firmware.model (firmware)",
        f"{core}: ik5r.status (core) imports ik5r.commands (tools)",
        f"{core}: ik5r.status (core) imports ik5r.commands.solve (tools)"]


def test_lower_layers_never_import_higher_ones():
    assert violations() == []
