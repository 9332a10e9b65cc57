"""The operations of the traced IK graph (:mod:`.trace`), named once.

A node's ``op`` is an :class:`Op`; the cores switch on the members, never on their spelling. The
members are string enums whose values are the names the Verilog's signals are built from (a
pipelined unit of a node is named ``<op><n>``), so the generated text does not change with them.
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["Op"]


class Op(StrEnum):
    """What a node computes (arguments, then parameters)."""
    WORD = "word"       # an input word (its name)
    INPUT = "in"        # a word as the pipelined core reads it (its name)
    NEG = "neg"         # -a
    CHECK = "check"     # a in the check-word format
    ADD = "add"         # a + b
    SUB = "sub"         # a - b
    SAT = "sat"         # a saturated to (bits)
    RSR = "rsr"         # a >> (shift), rounded
    MULC = "mulc"       # a * (constant), rounded
    WRAP = "wrap"       # a wrapped to [-pi, pi]
    OPP = "opp"         # the opposite angle of a
    SEL = "sel"         # a if (cond) else b
    CLIP = "clip"       # a clipped to (low, high)
    ATAN2 = "atan2"     # CORDIC vectoring of (y, x)
    ROT = "rot"         # CORDIC rotation of (x, y) by angle
    ROTX = "rotx"       # its x
    ROTY = "roty"       # its y
    SQRT = "sqrt"       # integer square root of a (bits)
