"""List scheduling of the lowered IK blocks (:mod:`.lower`) onto the sequenced engine's units.

Each block keeps its own clock-by-clock shape (a product's pick and its accumulate two clocks
later, a CORDIC's load, micro-rotations and read-out); what moves is where it starts. A block
claims, clock by clock, the instruction fields it sets, the B bus and the memory ports, and the
unit state it must keep: the accumulator and the F flag while a value in them is still to be read
(a liveness scan), the CORDIC, the multiplier's operand registers and the square root from their
first to their last use. Blocks are placed in order of their longest path to the end of the
program (the CORDIC chain first; a search's order if kept), each at the first clock where its
claims are free and its words are stored (READ_AHEAD + 1 clocks before the read): products, checks
and glue fill the clocks the CORDIC and the square root run alone. Values whose lifetimes do not
overlap then share a memory word. (The same claims as a constraint model: :mod:`.cpsat`.)
"""

from __future__ import annotations

import itertools
from dataclasses import replace

from .asm import fold, hazards
from .isa import (A_ADD, A_CMPGT, A_CMPLT, A_LD, A_MACC, A_MLD, A_NEG, A_SATI, A_SATW, A_SETF,
                  A_SUB, B_ACC, B_CX, B_CY, B_CZ, B_MEM, B_REM, B_ROOT,
                  C_F, C_ZERO, IO_OUT, K_LDX, K_LDXG, K_LDY, K_LDYG, K_LDZA, Q_LOAD, READ_AHEAD,
                  SHIFTS, Ins, Var, nonzero)

COND_FIELDS = ("ca", "cai", "cb", "cbi", "cp")
ACC_WRITE = {A_LD, A_ADD, A_SUB, A_NEG, *SHIFTS, A_SATI, A_SATW, A_MLD, A_MACC}
ACC_READ = {A_ADD, A_SUB, A_NEG, *SHIFTS, A_SATI, A_SATW, A_MACC, A_CMPGT, A_CMPLT}
BUS_ALU = {A_LD, A_ADD, A_SUB, A_CMPGT, A_CMPLT}
LOADS = {K_LDX, K_LDY, K_LDXG, K_LDYG, K_LDZA}


def _cond(ins: Ins) -> tuple:
    """The condition fields' values (absent: 0, as encoded)."""
    values = (getattr(ins, f) for f in COND_FIELDS)
    return tuple(v if nonzero(v) else 0 for v in values)


def _conditional(ins: Ins) -> bool:
    return any(nonzero(getattr(ins, f)) for f in COND_FIELDS)


def _bus(ins: Ins) -> bool:
    return ins.alu in BUS_ALU or nonzero(ins.mld) or ins.cop in LOADS


def _sensitive(ins: Ins) -> bool:
    """The instruction's conditions gate something (an ALU op or event, a CORDIC load)."""
    return ins.alu is not None or ins.cop in LOADS


def _var_read(ins: Ins) -> str | None:
    """The variable ``ins`` reads from the memory onto the B bus, if any."""
    if _bus(ins) and (ins.bsel or B_MEM) == B_MEM and isinstance(ins.rd, Var):
        return ins.rd.name
    return None


def _occupancy(code, reads, writes, kills) -> list:
    """Clocks during which a register (accumulator, F) holds a value of this block: ``held[t]``
    for the value instruction ``t`` sees, one entry past the code. A read at ``t`` needs
    ``held[t]``; a write at ``t`` takes ``held[t + 1]`` (the register changes at the clock's end,
    whether or not the value is read), so a block loading the register may share the clock of
    another block's last read of it (a store, a compare, an output)."""
    held, live = [False] * (len(code) + 1), False
    for t in range(len(code) - 1, -1, -1):
        r, w, k = reads(code[t]), writes(code[t]), kills(code[t])
        held[t + 1] = held[t + 1] or live or w
        live = r or (live and not k)
        held[t] = live
    return held


def _span(code, touches) -> list:
    hits = [t for t, ins in enumerate(code) if touches(ins)]
    return [bool(hits) and hits[0] <= t <= hits[-1] for t in range(len(code))]


def _acc_reads(ins: Ins) -> bool:
    op = ins.alu
    return bool(op in ACC_READ or (op in (A_LD, A_MLD) and _conditional(ins)) or ins.wr
                or ins.sq == Q_LOAD or ins.io == IO_OUT
                or (_bus(ins) and ins.bsel == B_ACC))


def _f_reads(ins: Ins) -> bool:
    return C_F in (ins.ca, ins.cb)


def _f_writes(ins: Ins) -> bool:
    return ins.alu in (A_CMPGT, A_CMPLT, A_SETF)


#: One bit per claim (a unit, a register, an instruction field), given at first sight: the
#: table tests a block's claims as integer masks (a hill climb places tens of thousands of blocks).
_BITS: dict[str, int] = {}


def _mask(keys) -> int:
    mask = 0
    for key in keys:
        mask |= _BITS.setdefault(key, 1 << len(_BITS))
    return mask


def _offsets(masks) -> dict[int, list[int]]:
    """Per claim bit, the clocks (offsets in the block) that claim it."""
    offsets: dict[int, list[int]] = {}
    for t, mask in enumerate(masks):
        while mask:
            bit = mask & -mask
            offsets.setdefault(bit, []).append(t)
            mask ^= bit
    return offsets


class Block:
    """One block's code and, per clock, what it claims (``claims``: names) under which condition
    (``conds``); the same per claim bit of :data:`_BITS` and per condition (``offsets``: the
    clocks, ``clocks``: as bits); its memory reads and writes."""

    def __init__(self, code: list):
        self.code = code = hazards(fold(code))
        acc = _occupancy(code, _acc_reads, lambda i: i.alu in ACC_WRITE,
                        lambda i: i.alu in (A_LD, A_MLD) and not _conditional(i))
        flag = _occupancy(code, _f_reads, _f_writes, lambda i: _f_writes(i) and not _conditional(i))
        cordic = _span(code, lambda i: nonzero(i.cop) or C_ZERO in (i.ca, i.cb)
                       or (_bus(i) and i.bsel in (B_CX, B_CY, B_CZ)))
        mop = _span(code, lambda i: nonzero(i.mld) or i.pick)
        sqrt = _span(code, lambda i: nonzero(i.sq) or (_bus(i) and i.bsel in (B_ROOT, B_REM)))
        self.claims, self.conds = [], []
        for t, ins in enumerate(code):
            keys = set(ins.present()) - set(COND_FIELDS)
            keys |= {name for name, held in (("acc", acc), ("F", flag), ("cordic", cordic),
                                             ("mop", mop), ("sqrt", sqrt)) if held[t]}
            if _bus(ins):
                keys.add("bus")
            self.claims.append(keys)
            self.conds.append(_cond(ins) if _sensitive(ins) else None)
        # A write in the last clock holds its register one clock past the code.
        past = {name for name, held in (("acc", acc), ("F", flag)) if held[len(code)]}
        if past:
            self.claims.append(past)
            self.conds.append(None)
        self.offsets, self.cond_offsets = _offsets(map(_mask, self.claims)), {}
        for t, cond in enumerate(self.conds):
            if cond is not None:
                self.cond_offsets.setdefault(cond, []).append(t)
        self.clocks = {bit: sum(1 << t for t in ts) for bit, ts in self.offsets.items()}
        self.cond_clocks = {cond: sum(1 << t for t in ts) for cond, ts in self.cond_offsets.items()}
        self.reads = [(t, _var_read(ins)) for t, ins in enumerate(code) if _var_read(ins)]
        self.writes = [(t, ins.wa.name) for t, ins in enumerate(code) if ins.wr]


class Table:
    """The program being scheduled: per claim (a bit of :data:`_BITS`) and per condition, the
    clocks taken, as integers (bit t: clock t), so that a block's first free start is found at
    once (:meth:`first_fit`) rather than tried clock by clock."""

    def __init__(self):
        self.busy: dict[int, int] = {}        # claim bit -> clocks it is taken
        self.under: dict = {}                 # condition -> clocks placed under it
        self.conditional = 0                  # clocks placed under any condition
        # The placements; their words are merged once, for the schedule kept (not per trial).
        self.placed: list[tuple[Block, int]] = []
        self.end = 0

    def _taken(self, b: Block) -> int:
        """The starts at which ``b`` does not fit (bit s: start s): a claim of b at offset t
        meets a clock taken at s + t, or a condition of b another one placed there."""
        taken = 0
        for bit, offsets in b.offsets.items():
            busy = self.busy.get(bit, 0)
            if busy:
                for t in offsets:
                    taken |= busy >> t
        for cond, offsets in b.cond_offsets.items():
            other = self.conditional & ~self.under.get(cond, 0)
            if other:
                for t in offsets:
                    taken |= other >> t
        return taken

    def fits(self, b: Block, start: int) -> bool:
        return not (self._taken(b) >> start) & 1

    def first_fit(self, b: Block, start: int) -> int:
        """The first clock from ``start`` at which ``b`` fits."""
        taken = self._taken(b) >> start
        return start + (~taken & (taken + 1)).bit_length() - 1

    def place(self, b: Block, start: int):
        for bit, clocks in b.clocks.items():
            self.busy[bit] = self.busy.get(bit, 0) | clocks << start
        for cond, clocks in b.cond_clocks.items():
            self.under[cond] = self.under.get(cond, 0) | clocks << start
            self.conditional |= clocks << start
        self.placed.append((b, start))
        self.end = max(self.end, start + len(b.code))

    def __len__(self) -> int:
        """The program's clocks (a claim may reach one clock past them)."""
        return self.end

    def code(self) -> list[Ins]:
        """The program: per clock, the instructions placed there merged in placement order."""
        code = [Ins() for _ in range(self.end)]
        for b, start in self.placed:
            for t, ins in enumerate(b.code):
                code[start + t] = code[start + t].merge(ins)
        return code


def _priorities(blocks: list, producer: dict) -> list:
    """Each block's longest path (clocks) from its start to the end of the program."""
    prio = [len(b.code) for b in blocks]
    for i in range(len(blocks) - 1, -1, -1):          # consumers come after their producers
        b = blocks[i]
        for t_read, name in b.reads:
            p, t_write = producer[name]
            if p != i:
                prio[p] = max(prio[p], t_write + READ_AHEAD + 1 - t_read + prio[i])
    return prio


def schedule(codes: list, after: tuple = (), priorities: list | None = None,
             releases: list | None = None) -> list:
    """Place the blocks (``codes[0]`` the inputs, ``codes[-1]`` the outputs) and share the
    memory words of the program (:func:`share_words`). ``after``: (i, j, gap) triples, block j
    starts ``gap`` clocks or more after block i ends (the word ports' order between poses of one
    program, :func:`.program.ik_program`). ``priorities``, ``releases``: a search's placing
    order and earliest starts, kept (:mod:`.search`), else the order :func:`climbed` finds. Any
    order is a valid program (each block at its first free clock); it decides how short."""
    blocks = blocks_of(codes, after)
    table = climbed(blocks)[0] if priorities is None else placed(blocks, priorities, releases)
    return share_words(table.code())


def blocks_of(codes: list, after: tuple = ()) -> "_Blocks":
    """The blocks of ``codes`` with their order constraints ``after`` (see :func:`schedule`)."""
    blocks = _Blocks(Block(c) for c in codes)
    blocks.after = {j: [(i, gap) for i, jj, gap in after if jj == j] for _, j, _ in after}
    return blocks


def climbed(blocks: "_Blocks", prio: list | None = None) -> tuple:
    """The shortest program the hill climb finds from ``prio`` (default: the longest paths), and
    its priorities.

    The longest-path priorities are a start: a block off the critical path placed late may find
    its unit taken where it had room (the roll's atan2 behind the elbow's). So each block's
    priority is moved by a few steps in turn (lowered too: a block placed early may take a unit a
    more urgent one needs a little later), a change kept when the program gets shorter, until a
    pass keeps none (a hill climb); then the priorities of every two blocks are swapped in turn
    (a climb's steps move one block past its neighbours; a swap trades two places at once), the
    climb resumed after a shorter program, until no swap shortens it. Deterministic."""
    prio = _priorities(blocks, _Placer(blocks).producer) if prio is None else prio
    best, prio = _climb(blocks, prio, _Placer(blocks, prio).run())
    while True:
        shorter, swapped = _swap(blocks, prio, best)
        if shorter is best:
            return best, prio
        best, prio = _climb(blocks, swapped, shorter)


def placed(blocks: "_Blocks", priorities: list, releases: list | None = None):
    """The blocks list-scheduled in order of ``priorities``, none before its ``releases`` clock
    (the program's :class:`Table`). Releases that are a valid placement (:func:`.cpsat.solve`)
    give back that placement, whatever the order: each block's own clock is then its first fit."""
    return _Placer(blocks, priorities, releases).run()


class _Blocks(list):
    """The blocks to place, with ``after``: per block, the (block, gap) it must follow."""
    after: dict = {}


def _dependencies(blocks: list) -> tuple[dict, list, list]:
    """(producer: variable -> (block, clock of its store); per block, the other blocks it waits
    for, producers and ``after``; per block, the blocks waiting for it). Once per block list: a
    climb places the same blocks tens of thousands of times."""
    cached = getattr(blocks, "_dependencies", None)
    if cached is not None:
        return cached
    producer = {name: (i, t) for i, b in enumerate(blocks) for t, name in b.writes}
    after = getattr(blocks, "after", {})
    waits = [{producer[name][0] for _, name in b.reads} - {i} | {before for before, _ in after.get(i, ())}
             for i, b in enumerate(blocks)]
    waiting_for = [[j for j, w in enumerate(waits) if i in w] for i in range(len(blocks))]
    result = (producer, waits, waiting_for)
    if isinstance(blocks, _Blocks):
        blocks._dependencies = result
    return result


#: Hill-climbing passes over the priorities (each schedules the program once per block and step).
PASSES = 8
#: The priority steps tried per block.
STEPS = (-200, -100, -40, -10, 10, 40, 100, 200, 400, 800)


def _climb(blocks: list, prio: list, best):
    """The hill climb on single priorities from ``prio`` (its program ``best``)."""
    for _ in range(PASSES):
        improved = False
        for i in range(1, len(blocks) - 1):
            for step in STEPS:
                trial = prio[:i] + [prio[i] + step] + prio[i + 1:]
                table = _Placer(blocks, trial).run()
                if len(table) < len(best):
                    best, prio, improved = table, trial, True
        if not improved:
            break
    return best, prio


def _swap(blocks: list, prio: list, best):
    """The program made shorter by swapping two blocks' priorities (the first such swap, in
    order), and its priorities; ``best`` itself if none is."""
    for i, j in itertools.combinations(range(1, len(blocks) - 1), 2):
        trial = list(prio)
        trial[i], trial[j] = prio[j], prio[i]
        table = _Placer(blocks, trial).run()
        if len(table) < len(best):
            return table, trial
    return best, prio


class _Placer:
    """List scheduling in order of priority: each block, the most urgent ready one first, at its
    first clock where its claims are free (later blocks fill earlier gaps)."""

    def __init__(self, blocks: list, prio: list | None = None, releases: list | None = None):
        self.blocks, self.releases = blocks, releases
        self.producer, waits, self.waiting_for = _dependencies(blocks)
        # Per block, the blocks it waits for that are not placed yet.
        self.unplaced = [len(w) for w in waits]
        self.prio = prio
        self.table, self.start, self.written = Table(), {}, {}

    def ready(self, i: int):
        """The first clock block ``i`` may start at (None while a producer is not placed)."""
        if self.unplaced[i]:
            return None
        b = self.blocks[i]
        t = len(self.blocks[0].code) if i else 0
        t = max(t, self.releases[i]) if self.releases else t
        for t_read, name in b.reads:
            if name in self.written:
                t = max(t, self.written[name] + READ_AHEAD + 1 - t_read)
        for before, gap in getattr(self.blocks, "after", {}).get(i, ()):
            t = max(t, self.start[before] + len(self.blocks[before].code) + gap)
        return t

    def place(self, i: int, t: int):
        self.table.place(self.blocks[i], t)
        self.start[i] = t
        for j in self.waiting_for[i]:
            self.unplaced[j] -= 1
        for t_write, name in self.blocks[i].writes:
            self.written[name] = t + t_write

    def first_fit(self, i: int, t: int) -> int:
        return self.table.first_fit(self.blocks[i], t)

    def run(self) -> list:
        last = len(self.blocks) - 1
        self.place(0, 0)
        todo = sorted(range(1, last), key=lambda i: -self.prio[i])
        while todo:
            i = next(i for i in todo if not self.unplaced[i])
            todo.remove(i)
            self.place(i, self.first_fit(i, self.ready(i)))
        self.place(last, self.first_fit(last, max(self.ready(last), len(self.table))))
        return self.table


def share_words(code: list[Ins]) -> list[Ins]:
    """Values whose lifetimes (store to last read) do not overlap share a memory word."""
    first, last = {}, {}
    for t, ins in enumerate(code):
        if ins.wr:
            first.setdefault(ins.wa.name, t)
        if _var_read(ins):
            last[_var_read(ins)] = t
    free_at: list[int] = []          # per word: the clock of its last read
    word = {}
    for name in sorted(first, key=first.get):
        s = first[name]
        slot = next((w for w, f in enumerate(free_at) if f < s), None)
        if slot is None:
            slot = len(free_at)
            free_at.append(0)
        free_at[slot] = last.get(name, s)
        word[name] = f"w{slot}"

    def shared(ref):
        return Var(word[ref.name]) if isinstance(ref, Var) and ref.name in word else ref

    return [replace(ins, rd=shared(ins.rd), wa=shared(ins.wa)) for ins in code]
