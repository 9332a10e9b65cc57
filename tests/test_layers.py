"""The layers of ik5r, asserted from the import graph (:mod:`ik5r.sources`: every ``import`` of
every module, also the ones inside functions, read with ``ast``; nothing is imported to find them).

    tools     ik5r.cli, commands, synth, sweep, bench, results, report, demo; the testbenches
              (ik5r.hdl.tb), which check the HDL against the firmware model
    firmware  ik5r.firmware (model, vector, C, codegen)  |  hdl  ik5r.hdl (Amaranth blocks)
    core      ik5r.fxconfig, arm, reference, status, csvio, errors, fixedpoint (+ _np), pose_fields,
              ik (the IK body, written once on the fixed-point vocabulary)

A layer imports only its own and the layers below it; firmware and hdl are two implementations
of the one IK, side by side: neither imports the other (the fixed-point words they share are
``ik5r.fixedpoint``). See docs/architecture.md.
"""

from __future__ import annotations

from pathlib import Path

from ik5r.sources import all_modules, closure, imports_of

CORE = {"ik5r", "ik5r.fxconfig", "ik5r.arm", "ik5r.reference", "ik5r.status", "ik5r.csvio",
        "ik5r.errors", "ik5r.fixedpoint", "ik5r.fixedpoint_np", "ik5r.reference_kernel",
        "ik5r.data", "ik5r.status_cases", "ik5r.pose_fields", "ik5r.ik"}
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


def violations(mods: dict[str, Path] | None = None) -> list[str]:
    mods = all_modules() if mods is None else mods
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
    mods = all_modules()
    assert {"ik5r.fxconfig", "ik5r.firmware.model", "ik5r.hdl.ik_core", "ik5r.hdl.tb.runner",
            "ik5r.commands.solve", "ik5r.fixedpoint"} <= set(mods)
    assert "ik5r.fixedpoint" in imports_of("ik5r.hdl.ik_steps", mods["ik5r.hdl.ik_steps"])
    assert "ik5r.hdl.datapath" in imports_of("ik5r.hdl.cordic", mods["ik5r.hdl.cordic"])
    assert layer_of("ik5r.hdl.tb.blocks") == "tools" and layer_of("ik5r.hdl.cordic") == "hdl"


def test_a_violation_is_found(tmp_path):
    core = tmp_path / "status.py"
    core.write_text("def f():\n    from .commands import solve\n")
    hdl = tmp_path / "ik_core.py"
    hdl.write_text("from ik5r.firmware import model\n")
    mods = {**all_modules(), "ik5r.status": core, "ik5r.hdl.ik_core": hdl}
    assert violations(mods) == [
        f"{hdl}: ik5r.hdl.ik_core (hdl) imports ik5r.firmware (firmware)",
        f"{hdl}: ik5r.hdl.ik_core (hdl) imports ik5r.firmware.model (firmware)",
        f"{core}: ik5r.status (core) imports ik5r.commands (tools)",
        f"{core}: ik5r.status (core) imports ik5r.commands.solve (tools)"]


def test_lower_layers_never_import_higher_ones():
    assert violations() == []


def test_cache_key_closures_follow_the_imports():
    """The sweep's cache keys hash these closures: what the Verilog and the error figures come from."""
    mods = all_modules()
    verilog = set(closure(["ik5r.hdl.generate", "ik5r.synth"]))
    assert {mods[m] for m in ("ik5r.hdl.ik_core", "ik5r.hdl.cordic", "ik5r.hdl.datapath", "ik5r.hdl.build",
                              "ik5r.hdl.products", "ik5r.hdl.expr", "ik5r.status",
                              "ik5r.fixedpoint", "ik5r.fxconfig", "ik5r.arm", "ik5r.hdl")} <= verilog
    assert mods["ik5r.firmware.model"] not in verilog and mods["ik5r.hdl.tb.runner"] not in verilog
    errors = set(closure(["ik5r.report.quantisation"]))
    assert {mods[m] for m in ("ik5r.firmware.vector", "ik5r.reference", "ik5r.status")} <= errors


def test_hardware_choices_are_named_once():
    """No module but ``ik5r.hdl.modes`` spells out a list of architectures, DSP mappings or blocks."""
    import ast

    from ik5r.hdl import modes

    lists = {frozenset(names) for names in (modes.ARCHS, modes.CORE_ARCHS, modes.ARCH_NAMES,
                                            modes.DSPS, modes.PRODUCTS, modes.BLOCKS)}
    found = []
    for module, path in all_modules().items():
        if module == "ik5r.hdl.modes":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Tuple, ast.List, ast.Set)) and len(node.elts) > 1 and all(
                    isinstance(e, ast.Constant) and isinstance(e.value, str) for e in node.elts):
                if frozenset(e.value for e in node.elts) in lists:
                    found.append(f"{path}:{node.lineno}")
    assert found == []
