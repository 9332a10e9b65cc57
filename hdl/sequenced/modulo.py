"""Modulo schedules: a pose every ``period`` clocks, its blocks running on into the next poses'.

A program of two poses placed as a straight line (:func:`.schedule.schedule`) starts both poses
at its first clocks and ends them at its last: the units idle at both ends, while the first
blocks wait for the inputs and the last for the outputs. Here one pose's blocks are placed once
(its *template*) so that a copy of it every ``period`` clocks never claims what another copy
claims in the same clock (the claims taken modulo the period); the poses take the two register
sets of a two-pose engine in turn, so a pose may span up to two periods. The engine's program
is then two periods long, pose 1 the template a period after pose 0, and the blocks reaching
past its end run in the next run's first clocks: a *cyclic* program (:attr:`.isa.Program.cyclic`,
the engine's pose 0 skipped like pose 1 when no input is there but a pose is in flight).

The template is found offline by the constraint solver (:func:`.cpsat.solve` with
``modulo=True``, ``python -m ik5r.hdl.sequenced.search --modulo SECONDS``) and kept
(:func:`.hints.modulo_hint`); :func:`cyclic_code` builds the cyclic program from the two
poses' starts, checking every claim, condition, store-to-read distance and span again, and
:func:`share_words` shares memory words between values whose lifetimes do not meet on the
circle of the program's clocks.
"""

from __future__ import annotations

from dataclasses import replace

from .isa import READ_AHEAD, Ins, Var
from .schedule import _dependencies, _var_read, blocks_of

__all__ = ["two_pose_starts", "cyclic_code", "share_words"]


def two_pose_starts(starts: list, period: int) -> list:
    """The starts of the two-pose program's blocks (:func:`.program.interleave`: the inputs, the
    poses' inner blocks, the outputs) from a template's: pose 1 a period after pose 0."""
    inner = starts[1:-1]
    return ([starts[0], starts[0] + period] + inner + [s + period for s in inner]
            + [starts[-1], starts[-1] + period])


def _check_span(blocks, starts, clocks: int, poses: int):
    last = len(blocks) - 1
    for p in range(poses):
        i, o = p, last - poses + 1 + p
        span = starts[o] + len(blocks[o].code) - starts[i]
        if span > clocks:
            raise ValueError(f"pose {p} spans {span} clocks, more than the program's {clocks}")


def cyclic_code(codes: list, after: tuple, starts: list, clocks: int, poses: int) -> list[Ins]:
    """The cyclic program of ``clocks`` clocks with each block of ``codes`` at its start, an
    instruction at clock t at t mod ``clocks``; every claim, condition, store-to-read distance
    and pose span checked; the memory words shared (:func:`share_words`)."""
    blocks = blocks_of(codes, after)
    producer, _, _ = _dependencies(blocks)
    claims = [set() for _ in range(clocks)]
    conds: list = [None] * clocks
    code = [Ins() for _ in range(clocks)]
    for b, s in zip(blocks, starts):
        for t, keys in enumerate(b.claims):
            slot = (s + t) % clocks
            if claims[slot] & keys:
                raise ValueError(f"clock {slot}: {sorted(claims[slot] & keys)} claimed twice")
            claims[slot] |= keys
        for t, cond in enumerate(b.conds):
            slot = (s + t) % clocks
            if cond is not None and conds[slot] not in (None, cond):
                raise ValueError(f"clock {slot}: two conditions, {conds[slot]} and {cond}")
            conds[slot] = cond if cond is not None else conds[slot]
        for t, ins in enumerate(b.code):
            code[(s + t) % clocks] = code[(s + t) % clocks].merge(ins)
        for t_read, name in b.reads:
            i, t_write = producer[name]
            if starts[i] + t_write + READ_AHEAD + 1 > s + t_read:
                raise ValueError(f"{name} read {s + t_read - starts[i] - t_write} clocks after its store")
    _check_span(blocks, starts, clocks, poses)
    return share_words(code, [(b.code, s) for b, s in zip(blocks, starts)])


def share_words(code: list[Ins], blocks_starts: list) -> list[Ins]:
    """Values whose lifetimes, store to last read, do not meet modulo the program's length share
    a memory word (``blocks_starts``: (block code, start) per block, for the lifetimes)."""
    clocks = len(code)
    first, last = {}, {}
    for b_code, s in blocks_starts:
        for t, ins in enumerate(b_code):
            if ins.wr:
                first[ins.wa.name] = min(first.get(ins.wa.name, s + t), s + t)
            if _var_read(ins):
                last[_var_read(ins)] = max(last.get(_var_read(ins), s + t), s + t)
    arcs = {name: (first[name] % clocks, last.get(name, first[name]) - first[name]) for name in first}
    if any(length >= clocks for _, length in arcs.values()):
        raise ValueError("a value lives longer than the program")

    def meet(a, b):
        return (b[0] - a[0]) % clocks <= a[1] or (a[0] - b[0]) % clocks <= b[1]

    words: list[list] = []
    word = {}
    for name in sorted(arcs, key=lambda n: (-arcs[n][1], n)):
        slot = next((w for w, held in enumerate(words) if not any(meet(arcs[name], h) for h in held)), None)
        if slot is None:
            slot = len(words)
            words.append([])
        words[slot].append(arcs[name])
        word[name] = f"w{slot}"

    def shared(ref):
        return Var(word[ref.name]) if isinstance(ref, Var) and ref.name in word else ref

    return [replace(ins, rd=shared(ins.rd), wa=shared(ins.wa)) for ins in code]

