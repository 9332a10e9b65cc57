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
              fixed-point words), modes (the hardware's choices as enums); with the data
              ik5r.data and ik5r.configs

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
    """No module but ``ik5r.core.modes`` spells out a list of architectures, DSP mappings or blocks."""
    import ast

    from ik5r.core import modes

    lists = {frozenset(names) for names in (modes.ARCHS, modes.CORE_ARCHS, modes.ARCH_NAMES,
                                            modes.DSPS, modes.BLOCKS, modes.TARGETS,
                                            modes.BOARD_CORES)}
    found = []
    for module, path in all_modules().items():
        if module == "ik5r.core.modes":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Tuple, ast.List, ast.Set)) and len(node.elts) > 1 and all(
                    isinstance(e, ast.Constant) and isinstance(e.value, str) for e in node.elts):
                if frozenset(e.value for e in node.elts) in lists:
                    found.append(f"{path}:{node.lineno}")
    assert found == []


#: The subpackages (and top modules) of ``ik5r.hdl`` and what each may import of the others. The
#: IR (``graph``) imports none: both cores build from it, neither from the other.
HDL_ALLOWED = {
    "provenance": set(), "graph": set(),
    "datapath": set(),
    "blocks": {"datapath"},
    "pipelined": {"graph", "blocks", "datapath"},
    "sequenced": {"graph", "blocks", "datapath"},
    "generate": {"blocks", "datapath", "pipelined", "provenance", "sequenced"},
    "soc": {"pipelined", "provenance", "sequenced"},               # the IK peripheral wraps a core
    "board": {"datapath", "pipelined", "sequenced"},               # a core behind the UART link
    "formal": {"blocks", "datapath", "generate", "pipelined", "sequenced", "soc"},
}


def hdl_part(module: str) -> str:
    """The subpackage or top module of ``ik5r.hdl`` a module belongs to."""
    return module.split(".")[2]


def hdl_violations(mods: dict[str, Path]) -> list[str]:
    bad = []
    for module, path in sorted(mods.items()):
        if not module.startswith("ik5r.hdl."):
            continue
        for target in sorted(imports_of(module, path)):
            if target in mods and target.startswith("ik5r.hdl.") and \
                    hdl_part(target) not in HDL_ALLOWED[hdl_part(module)] | {hdl_part(module)}:
                bad.append(f"{path}: {module} ({hdl_part(module)}) imports {target}")
    return bad


def import_cycles(mods: dict[str, Path]) -> list[list[str]]:
    """Every strongly connected set of more than one module in the import graph (imports inside
    functions count: a circle is a circle whenever it closes)."""
    graph = {m: sorted(t for t in imports_of(m, p) if t in mods and t != m) for m, p in mods.items()}
    index, low, stack, on, cycles = {}, {}, [], set(), []

    def visit(v):                               # Tarjan; the graph is small and shallow
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while not part or part[-1] != v:
                part.append(stack.pop())
                on.discard(part[-1])
            if len(part) > 1:
                cycles.append(sorted(part))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


def test_hdl_subpackages_import_only_what_the_table_allows():
    mods = all_modules()
    assert {hdl_part(m) for m in mods if m.startswith("ik5r.hdl.")} == set(HDL_ALLOWED)
    assert hdl_violations(mods) == []


def test_the_hdl_table_is_a_hierarchy():
    done: set[str] = set()
    while len(done) < len(HDL_ALLOWED):
        ready = {p for p, uses in HDL_ALLOWED.items() if p not in done and uses <= done}
        assert ready, f"a circle among {set(HDL_ALLOWED) - done}"
        done |= ready


def test_an_hdl_violation_and_a_circle_are_found(tmp_path):
    trace = tmp_path / "trace.py"
    trace.write_text("def f():\n    from ..sequenced import isa\n")
    isa = tmp_path / "isa.py"
    isa.write_text("from ..graph import trace\n")
    mods = {**all_modules(), "ik5r.hdl.graph.trace": trace, "ik5r.hdl.sequenced.isa": isa}
    assert hdl_violations(mods) == [f"{trace}: ik5r.hdl.graph.trace (graph) imports ik5r.hdl.sequenced",
                                    f"{trace}: ik5r.hdl.graph.trace (graph) imports ik5r.hdl.sequenced.isa"]
    assert ["ik5r.hdl.graph.trace", "ik5r.hdl.sequenced.isa"] in import_cycles(mods)


def test_no_import_circle_in_hdl():
    hdl = {m: p for m, p in all_modules().items() if m.startswith("ik5r.hdl")}
    assert len(hdl) > 40 and import_cycles(hdl) == []


#: Words that spell an operation of the IR but mean something else where they appear, by module
#: (what they are there). Everything else spells an operation only in ``ik5r.hdl.graph.ops``.
OP_HOMONYMS = {
    # a block of ik5r.core.modes.Block (its value); the acos chain's split point before its atan2
    "atan2": {"ik5r.core.modes", "ik5r.hdl.blocks.acos"},
    # the same block; the sequenced engine's square-root unit; a port name the sqrt testbench accepts
    "sqrt": {"ik5r.core.modes", "ik5r.hdl.sequenced.schedule",
             "ik5r.hdl.sequenced.units", "ik5r.tools.testbench.blocks"},
    # the engine's ALU decode lines; a rotation block's port name
    "sub": {"ik5r.hdl.sequenced.engine", "ik5r.hdl.sequenced.units"},
    "sat": {"ik5r.hdl.sequenced.engine", "ik5r.hdl.sequenced.units", "ik5r.tools.testbench.blocks"},
    "in": {"ik5r.tools.testbench.harness", "ik5r.tools.testbench.portmap",      # a port's direction
           "ik5r.tools.testbench.runner"},
    "sel": {"ik5r.hdl.formal.wishbone", "ik5r.hdl.soc.periph"},                 # Wishbone's byte select
    "word": {"ik5r.hdl.formal.stash", "ik5r.tools.litex"},     # a stash link's name; Wishbone addressing
    "check": {"ik5r.tools.report.build"},                       # a report table's column
    "clip": {"ik5r.core.fixedpoint"},                           # the vocabulary's own word (__all__)
    "rot": {"ik5r.numeric.solver"},                             # a solver trace field
}


def _op_strings(mods) -> dict:
    """{(module, word)}: lines of every string constant naming an operation (docstrings too)."""
    import ast

    from ik5r.hdl.graph.ops import Op

    found: dict = {}
    for module, path in sorted(mods.items()):
        for n in ast.walk(ast.parse(path.read_text())):
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value in set(Op):
                found.setdefault((module, n.value), []).append(n.lineno)
    return found


def test_an_operation_is_spelled_in_one_module():
    """The IR's operations are named once, in ``ik5r.hdl.graph.ops.Op``: no string constant of
    ``src/``, ``hdl/`` or ``firmware_model/`` spells one elsewhere, but the homonyms above; and
    every homonym listed is still there (the table cannot outlive its reason)."""
    found = _op_strings(all_modules())
    allowed = {(m, word) for word, modules in OP_HOMONYMS.items() for m in modules}
    assert {key for key in found if key[0] != "ik5r.hdl.graph.ops"} - allowed == set()
    assert allowed - set(found) == set()
    assert len({word for module, word in found if module == "ik5r.hdl.graph.ops"}) == 18


def test_a_stray_operation_string_is_found(tmp_path):
    lower = tmp_path / "lower.py"
    lower.write_text('def f(n):\n    return n.op == "mulc"\n')
    found = _op_strings({"ik5r.hdl.sequenced.lower": lower})
    assert found == {("ik5r.hdl.sequenced.lower", "mulc"): [2]}


#: Words that spell a mode of ``ik5r.core.modes`` (a value of one of its enums) but mean something
#: else where they appear, by module. Everything else names a mode through the enums.
MODE_HOMONYMS = {
    # the config TOML's [ik] table
    "ik": {"ik5r.core.fxconfig", "ik5r.tools.sweep"},
    # the IR's operations (ik5r.hdl.graph.ops.Op), and the homonyms of OP_HOMONYMS above
    "atan2": {"ik5r.hdl.graph.ops", "ik5r.hdl.blocks.acos"},
    "sqrt": {"ik5r.hdl.graph.ops", "ik5r.hdl.sequenced.schedule",
             "ik5r.hdl.sequenced.units", "ik5r.tools.testbench.blocks"},
    # the design option of the word-serial wrapper (its beat bits) and the result keys it leaves
    "serial": {"ik5r.hdl.generate", "ik5r.hdl.sequenced.serial", "ik5r.tools.commands.sim",
               "ik5r.tools.design", "ik5r.tools.results", "ik5r.tools.synth", "ik5r.tools.testbench.job",
               "ik5r.tools.testbench.runner", "ik5r.tools.testbench.serial"},
}


def _mode_strings(mods) -> dict:
    """{(module, word): lines} of every string constant that is a value of an enum of
    ``ik5r.core.modes``, outside that module."""
    import ast
    from enum import StrEnum

    from ik5r.core import modes

    words = {str(member) for enum in vars(modes).values()
             if isinstance(enum, type) and issubclass(enum, StrEnum) and enum is not StrEnum for member in enum}
    found: dict = {}
    for module, path in sorted(mods.items()):
        if module == "ik5r.core.modes":
            continue
        for n in ast.walk(ast.parse(path.read_text())):
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value in words:
                found.setdefault((module, n.value), []).append(n.lineno)
    return found


def test_a_mode_is_spelled_in_one_module():
    """Blocks, architectures, DSP mappings, FPGA families and board cores are named once, in
    ``ik5r.core.modes``: no string constant of ``src/``, ``hdl/`` or ``firmware_model/`` spells
    one elsewhere (the CLI's choices are built from its tuples), but the homonyms above; and
    every homonym listed is still there."""
    found = _mode_strings(all_modules())
    allowed = {(m, word) for word, modules in MODE_HOMONYMS.items() for m in modules}
    assert set(found) - allowed == set()
    assert allowed - set(found) == set()


def test_a_stray_mode_string_is_found(tmp_path):
    synth = tmp_path / "synth.py"
    synth.write_text('def f(design):\n    return design.arch == "pipelined" and design.dsp != "ecp5"\n')
    found = _mode_strings({"ik5r.tools.synth": synth})
    assert found == {("ik5r.tools.synth", "pipelined"): [2], ("ik5r.tools.synth", "ecp5"): [2]}
