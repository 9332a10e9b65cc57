"""The IK as a program of the sequenced engine: :func:`ik_program`, compiled from the one
description of the algorithm, :func:`ik5r.core.ik.solve` (the body the firmware models run).

Three passes: :mod:`.seq_trace` runs ``ik.solve`` on symbolic values and records its dataflow
graph; :mod:`.seq_lower` turns the graph into blocks of :mod:`.seq_isa` instructions (one way to do
each word of the vocabulary, from :mod:`.seq_asm`'s recipes); :mod:`.seq_schedule` places the
blocks on the units side by side (products, checks and glue while the CORDIC or the square root
runs) and shares the memory words. :meth:`.seq_asm.Asm.finish` resolves the addresses. (The
pipelined core is generated from the same graph, :mod:`.ik_graph`.)
"""

from __future__ import annotations

import copy
from functools import lru_cache

from ik5r.core.fxconfig import Constants

from .asm import Asm, limbs_of, widths_of
from .isa import Program
from .lower import Lower
from .schedule import schedule
from ..graph.trace import trace

__all__ = ["ik_program"]


def ik_program(k: Constants, *, wide_product: bool = False) -> Program:
    """``ik.solve`` for format ``k`` as a program of the sequenced engine (bit-exact to
    ``model.ik_solve``; see the module docstring); ``wide_product``: for the engine whose product
    step multiplies a 16-bit limb by two limbs of MB (31 bits, two DSPs). Compiled once per
    format (the schedule is a search: :func:`.seq_schedule.schedule`); each call returns its
    own copy."""
    if not isinstance(wide_product, bool):
        raise TypeError(f"wide_product must be a bool, got {wide_product!r}")
    return copy.deepcopy(_compile(k, wide_product))


@lru_cache(maxsize=None)
def _compile(k: Constants, wide_product: bool = False) -> Program:
    ki = k.internal
    if ki.check_shift != k.check_shift + k.cfg.internal_guard_bits:
        raise ValueError("the frame's check words (of the word format) must be the top bits of the "
                         f"internal words: check_shift {k.check_shift} + guard != {ki.check_shift}")
    a = Asm(k, wide_product=wide_product)
    joints, events, _ = trace(k)
    code = schedule(Lower(a, joints, events).blocks)
    widths = widths_of(k)
    widths.limbs = limbs_of(a.operand_bits)
    widths.b_limbs = a.b_size
    widths.acc = max(widths.acc, a.product_bits + 3)
    return a.finish(code, widths)
