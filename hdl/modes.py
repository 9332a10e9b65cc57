"""The names of the hardware's choices, defined once: blocks, architectures, DSP mappings and
multiplier schedules, as string enums (a member equals its name: ``Arch.PIPELINED == "pipelined"``).

The tuples (``ARCHS``, ``CORE_ARCHS``, ...) are the plain names, for argparse choices, checks and
messages. This module imports nothing (the CLI and the testbench load it cheaply).
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["Block", "Arch", "CoreArch", "Dsp", "Products", "BLOCKS", "ARCHS", "CORE_ARCHS",
           "ARCH_NAMES", "DSPS", "PRODUCTS"]


class Block(StrEnum):
    """What ``ik5r.hdl.generate`` builds: the arithmetic blocks and the IK core."""
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


class Products(StrEnum):
    """How a datapath multiplies: all partial products at once, or one 18 x 18 partial product
    per clock into an accumulator."""
    PARALLEL = "parallel"
    SEQUENTIAL = "sequential"


BLOCKS = tuple(b.value for b in Block)
ARCHS = tuple(a.value for a in Arch)
CORE_ARCHS = tuple(a.value for a in CoreArch)
#: Every architecture name a command accepts (``iterative`` and ``compact`` both name the small one).
ARCH_NAMES = tuple(dict.fromkeys(ARCHS + CORE_ARCHS))
DSPS = tuple(d.value for d in Dsp)
PRODUCTS = tuple(p.value for p in Products)
