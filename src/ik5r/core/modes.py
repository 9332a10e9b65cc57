"""The names of the hardware's choices, defined once: blocks, architectures, DSP mappings, FPGA
families and the board link's cores, as string enums (a member equals its name:
``Arch.PIPELINED == "pipelined"``, so JSON records and CLI choices keep their strings).

No other module of ``src/``, ``hdl/`` or ``firmware_model/`` spells one of these names as a string
(``tests/test_layers.py`` scans for them). They live in the core layer because the register map
(:mod:`.regmap`) and the board link (:mod:`.link`) number the cores, and ``ik5r.core`` imports no
higher layer. The tuples (``ARCHS``, ``CORE_ARCHS``, ...) are the plain names, for argparse
choices, checks and messages. This module imports nothing (the CLI and the testbench load it
cheaply).
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["Block", "Arch", "CoreArch", "Dsp", "Target", "BoardCore", "BLOCKS", "ARCHS", "CORE_ARCHS",
           "ARCH_NAMES", "DSPS", "DSP_OUTPUT_REGS", "TARGETS", "BOARD_CORES"]


class Block(StrEnum):
    """What :mod:`ik5r.hdl.generate` builds: the arithmetic blocks and the IK core."""
    ATAN2 = "atan2"
    ROTATE = "rotate"
    SQRT = "sqrt"
    ACOS = "acos"
    IK = "ik"


class Arch(StrEnum):
    """The two architectures every arithmetic block comes in: one result per clock, or one unit
    stepped over the iterations."""
    PIPELINED = "pipelined"
    ITERATIVE = "iterative"


class CoreArch(StrEnum):
    """The IK core's architectures: one pose per clock (``hdl.pipelined``), or the sequenced
    engine running the IK's program on a few shared units (``hdl.sequenced``), the small one
    that ``iterative`` also names for the IK core."""
    PIPELINED = "pipelined"
    COMPACT = "compact"


class Dsp(StrEnum):
    """How a pipelined datapath maps to the FPGA: portable operators, or ECP5 ``MULT18X18D`` and
    ``CCU2C`` primitives (same latency, same bits)."""
    GENERIC = "generic"
    ECP5 = "ecp5"


class Target(StrEnum):
    """The FPGA families the synthesis flows place for (``ik5r synth --target``)."""
    ECP5 = "ecp5"
    ICE40 = "ice40"


class BoardCore(StrEnum):
    """The IK core behind a board's UART link (``ik5r board --core``, the ID frame's core code):
    the compact core (``CoreArch.COMPACT``, the sequenced engine) behind its word-serial wrapper
    or alone, or the pipelined core: the names ``ik5r synth``/``sim`` give them (the wrapper:
    ``--serial``)."""
    SERIAL = "serial"
    COMPACT = "compact"
    PIPELINED = "pipelined"


BLOCKS = tuple(b.value for b in Block)
ARCHS = tuple(a.value for a in Arch)
CORE_ARCHS = tuple(a.value for a in CoreArch)
#: Every architecture name a command accepts (``iterative`` and ``compact`` both name the small one).
ARCH_NAMES = tuple(dict.fromkeys(ARCHS + CORE_ARCHS))
DSPS = tuple(d.value for d in Dsp)
#: Fabric registers after each ECP5 DSP's output register that the pipelined IK core offers.
DSP_OUTPUT_REGS = (0, 1, 2)
TARGETS = tuple(t.value for t in Target)
BOARD_CORES = tuple(c.value for c in BoardCore)
