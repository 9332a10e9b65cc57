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
from .isa import IO_FLAGS, IO_IN, Program, pose_of
from .lower import Lower
from .hints import hint, modulo_hint
from .modulo import cyclic_code, two_pose_starts
from .schedule import blocks_of, schedule
from .shifts import acc_shifts_for
from ..graph.trace import trace

__all__ = ["ik_program"]


def ik_program(k: Constants, *, wide_product: bool = False, poses: int = 1) -> Program:
    """``ik.solve`` for format ``k`` as a program of the sequenced engine (bit-exact to
    ``model.ik_solve``; see the module docstring); ``wide_product``: for the engine whose product
    step multiplies a 16-bit limb by two limbs of MB (31 bits, two DSPs); ``poses``: poses per
    run of the program (:func:`interleave`). Compiled once per format (the schedule is a
    search: :func:`.seq_schedule.schedule`); each call returns its own copy."""
    if not isinstance(wide_product, bool):
        raise TypeError(f"wide_product must be a bool, got {wide_product!r}")
    if poses not in POSES:
        raise ValueError(f"poses must be one of {POSES}, got {poses!r}")
    return copy.deepcopy(_compile(k, wide_product, poses))


#: Poses per program: one, or two whose blocks share the units (more found no shorter program
#: per pose).
POSES = (1, 2)
#: Clocks between a pose's last input word (the flags) and the next pose's first: the core's
#: input register is refilled and its word register reads the new pose (SequencedIKCore).
INPUT_GAP = 2


def interleave(blocks: list, poses: int) -> tuple[list, tuple]:
    """The blocks of ``poses`` poses in one program, and their order (:func:`.schedule.schedule`'s
    ``after``): each pose's variables its own words, its instructions' pose fields set
    (:data:`.isa.POSE_FIELDS`: word ports, flag conditions, status events); the poses' inputs
    and outputs in pose order. The units are shared: a pose's products and glue run while
    another's CORDIC does (one pose alone leaves the ALU idle for most of the CORDIC's clocks)."""
    copies = [[[pose_of(ins, p) for ins in code] for code in blocks] for p in range(poses)]
    inputs, outputs = [c[0] for c in copies], [c[-1] for c in copies]
    middle = [code for c in copies for code in c[1:-1]]
    codes = inputs + middle + outputs
    first_out, per_pose = len(codes) - poses, len(blocks) - 2
    # A pose's outputs (its status word last) after all its blocks, as the last block is.
    after = [(p, p + 1, INPUT_GAP) for p in range(poses - 1)]
    after += [(first_out + p, first_out + p + 1, 0) for p in range(poses - 1)]
    after += [(poses + p * per_pose + i, first_out + p, 0) for p in range(poses - 1) for i in range(per_pose)]
    return codes, tuple(after)


def program_blocks(k: Constants, wide_product: bool = False, poses: int = 1) -> tuple:
    """The assembler (its constants and widths) and the blocks of a program of ``poses`` poses
    with their order constraints, to be scheduled: ``(asm, codes, after)``."""
    joints, events, _ = trace(k)
    # Lowered twice: first to learn the shifts the program asks for, then with the accumulator's
    # three shifts that do them in the fewest clocks.
    first = Asm(k, wide_product=wide_product)
    Lower(first, joints, events)
    a = Asm(k, wide_product=wide_product, acc_shifts=acc_shifts_for(first.shifted))
    return (a, *interleave(Lower(a, joints, events).blocks, poses))


@lru_cache(maxsize=None)
def _compile(k: Constants, wide_product: bool = False, poses: int = 1) -> Program:
    ki = k.internal
    if ki.check_shift != k.check_shift + k.cfg.internal_guard_bits:
        raise ValueError("the frame's check words (of the word format) must be the top bits of the "
                         f"internal words: check_shift {k.check_shift} + guard != {ki.check_shift}")
    a, codes, after = program_blocks(k, wide_product, poses)
    blocks = blocks_of(codes, after)
    # A kept modulo schedule of these blocks (.modulo), else a kept order (a longer search's,
    # .search), else the scheduler's climb.
    cyclic = modulo_hint(blocks) if poses == 2 else None
    if cyclic:
        period, starts = cyclic
        code = cyclic_code(codes, after, two_pose_starts(starts, period), 2 * period, poses)
    else:
        code = schedule(codes, after, *(hint(blocks) or ()))
    widths = widths_of(k)
    widths.limbs = limbs_of(a.operand_bits)
    widths.b_limbs = a.b_size
    widths.acc = max(widths.acc, a.product_bits + 3)
    prog = a.finish(code, widths, cyclic=bool(cyclic))
    prog.poses = poses
    _check_input_gaps(prog.code, poses)
    return prog


def _check_input_gaps(code: list, poses: int):
    """Each pose's flags word INPUT_GAP clocks or more before the next pose's first word (the
    last pose's: the next run's first pose's)."""
    flags = {ins.ip or 0: t for t, ins in enumerate(code) if ins.io == IO_FLAGS}
    first = {ins.ip or 0: t for t, ins in enumerate(code) if ins.io == IO_IN and not ins.iw}
    for p in range(poses):
        gap = (first[(p + 1) % poses] - flags[p] - 1) % len(code)
        if gap < INPUT_GAP:
            raise ValueError(f"pose {p}'s flags word at clock {flags[p]} of {len(code)}: "
                             f"{gap} clocks before the next pose's first word, fewer than {INPUT_GAP}")
