"""The layers of ik5r, asserted from the import graph (:mod:`ik5r.tools.sources`: every ``import`` of
every module, also the ones inside functions, read with ``ast``; nothing is imported to find them).
A layer is a folder whose name is its import name, so a module's layer is its package:

    tools     ik5r.tools (src/ik5r/tools/): cli, commands, synth, sweep, bench, results, report,
              demo, softcpu; the testbenches (ik5r.tools.testbench), which check the HDL against
              the firmware model
    firmware  ik5r.firmware_model (firmware_model/)  |  hdl  ik5r.hdl (hdl/)  |  numeric  ik5r.numeric
              (src/ik5r/numeric/)
    core      ik5r.core (src/ik5r/core/): fxconfig, arm, chain, reference, status, csvio, errors,
              fixedpoint (+ _np), pose_fields, cbuild, ik (the IK body, written once on the
              fixed-point words); with the data ik5r.data and ik5r.configs

A layer imports only its own and the layers below it; firmware, hdl and numeric sit side by side:
none imports another (the fixed-point words firmware and hdl share are ``ik5r.core.fixedpoint``).
See docs/architecture.md.
"""

from __future__ import annotations

from pathlib import Path

from ik5r.tools.sources import all_modules, closure, imports_of

#: Layer of each package (a module's layer is that of its longest matching package).
LAYERS = {"ik5r": "core", "ik5r.core": "core", "ik5r.data": "core", "ik5r.configs": "core",
          "ik5r.firmware_model": "firmware", "ik5r.hdl": "hdl", "ik5r.numeric": "numeric",
          "ik5r.tools": "tools", "ik5r.__main__": "tools"}
#: What each layer may import (besides third-party packages).
ALLOWED = {"core": {"core"}, "firmware": {"core", "firmware"}, "hdl": {"core", "hdl"},
           "numeric": {"core", "numeric"}, "tools": {"core", "firmware", "hdl", "numeric", "tools"}}


def layer_of(module: str) -> str:
    packages = [p for p in LAYERS if module == p or module.startswith(p + ".")]
    return LAYERS[max(packages, key=len)]


def test_every_module_sits_in_a_layer_folder():
    """Nothing at the top of the ik5r package but its __init__ and __main__: each module's folder
    is its layer's."""
    loose = [m for m in all_modules() if m.count(".") == 1 and m not in LAYERS]
    assert loose == []
    assert all(layer_of(m) != "core" or m == "ik5r" or m.split(".")[1] in ("core", "data", "configs")
               for m in all_modules())


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
    assert {"ik5r.core.fxconfig", "ik5r.firmware_model.model", "ik5r.hdl.pipelined.core", "ik5r.tools.testbench.runner",
            "ik5r.tools.commands.solve", "ik5r.core.fixedpoint"} <= set(mods)
    assert "ik5r.core.fixedpoint" in imports_of("ik5r.hdl.pipelined.units", mods["ik5r.hdl.pipelined.units"])
    assert "ik5r.hdl.datapath.stages" in imports_of("ik5r.hdl.blocks.cordic", mods["ik5r.hdl.blocks.cordic"])
    assert layer_of("ik5r.tools.testbench.blocks") == "tools" and layer_of("ik5r.hdl.blocks.cordic") == "hdl"
    assert layer_of("ik5r.numeric.solver") == "numeric" and layer_of("ik5r.core.cbuild") == "core"


def test_a_violation_is_found(tmp_path):
    core = tmp_path / "status.py"
    core.write_text("def f():\n    from ..tools.commands import solve\n")
    hdl = tmp_path / "ik_core.py"
    hdl.write_text("from ik5r.firmware_model import model\n")
    mods = {**all_modules(), "ik5r.core.status": core, "ik5r.hdl.pipelined.core": hdl}
    assert violations(mods) == [
        f"{core}: ik5r.core.status (core) imports ik5r.tools.commands (tools)",
        f"{core}: ik5r.core.status (core) imports ik5r.tools.commands.solve (tools)",
        f"{hdl}: ik5r.hdl.pipelined.core (hdl) imports ik5r.firmware_model (firmware)",
        f"{hdl}: ik5r.hdl.pipelined.core (hdl) imports ik5r.firmware_model.model (firmware)"]


def test_lower_layers_never_import_higher_ones():
    assert violations() == []


def test_cache_key_closures_follow_the_imports():
    """The sweep's cache keys hash these closures: what the Verilog and the error figures come from."""
    mods = all_modules()
    verilog = set(closure(["ik5r.hdl.generate", "ik5r.tools.synth"]))
    assert {mods[m] for m in ("ik5r.hdl.pipelined.core", "ik5r.hdl.blocks.cordic", "ik5r.hdl.datapath.stages", "ik5r.hdl.datapath.build",
                              "ik5r.hdl.datapath.products", "ik5r.hdl.datapath.expr", "ik5r.core.status",
                              "ik5r.core.fixedpoint", "ik5r.core.fxconfig", "ik5r.core.arm", "ik5r.hdl")} <= verilog
    assert mods["ik5r.firmware_model.model"] not in verilog and mods["ik5r.tools.testbench.runner"] not in verilog
    errors = set(closure(["ik5r.tools.report.quantisation"]))
    assert {mods[m] for m in ("ik5r.firmware_model.vector", "ik5r.core.reference", "ik5r.core.status")} <= errors


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
