"""The output FIFO keeps the marks' order: a lemma, so that a long pipeline's order job need not
follow the marks through the FIFO's RAM entry by entry.

:func:`.pipelined.track_marks` follows the marks into the output FIFO (``SyncFIFOBuffered``:
a RAM between the ``consume`` and ``produce`` pointers, then the output register) with a shadow
of every RAM entry's tag. For the pipelined IK core (a 256-entry RAM behind 187 stages) that
job is beyond reach, so the FIFO gets a proof of its own:

**Ghosts** (:func:`fifo_ghosts`, from the FIFO's ports and pointers only): mark X is *written*
when ``w_en & w_rdy`` with tag X; it is then *in the RAM* at entry ``slot`` (``produce`` then)
until the FIFO reads that entry into its output register, where it is *out* until popped
(``r_rdy & r_en``); ``rank`` = ``slot - consume`` (entries ahead of it).

**The lemma** (:class:`FifoLemma`: k-induction on the real ``SyncFIFOBuffered`` of the core's
width and depth, its RAM read through the tag shadow of :mod:`.pipelined`, whose ``Assume`` is
the RAM's own semantics): if the writer never writes tag 3 and never writes mark X while X is
in the RAM or out (:func:`fifo_environment`; a write while full is refused, and is no write),
then (:func:`fifo_contract`) the output shows mark X exactly while X is out, a mark in the RAM
is between the pointers (``rank < inner_level``), never both in the RAM and out, and the output
never shows tag 3.

**Its use** (``fifo_lemma=True`` in :func:`.pipelined.track_marks`): the core's job cuts the
FIFO's RAM (as in the control group), keeps the same ghosts, assumes (``Assume``) the contract
and asserts the environment. Sound by induction over time: the contract at cycle t depends
only on the FIFO's inputs before t (its output register, pointers and ghosts are registers),
the environment at cycle t is asserted by the core's job at t, so in a real trace the first
cycle where an assertion of the core's job or the contract failed cannot exist (at that cycle
the environment held before it, so the contract holds, so the job's assertions hold). This
composition step is argued, the two proofs are machine-checked.
"""

from __future__ import annotations

import os

from amaranth.hdl import Array, Assert, Assume, Const, Elaboratable, Module, Mux, Signal
from amaranth.hdl._ast import AnyConst
from amaranth.lib import data
from amaranth.lib.fifo import SyncFIFOBuffered

__all__ = ["FifoLemma", "fifo_contract", "fifo_environment", "fifo_ghosts", "shadow"]

#: The marks (A, B) and the unused tag (see :meth:`.contract.StreamContract._marks`).
MARKS, UNUSED = (1, 2), 3


def _pointers(fifo_module, find):
    produce, consume = find(fifo_module, "produce"), find(fifo_module, "consume")
    inner_level, inner_r_rdy = find(fifo_module, "inner_level"), find(fifo_module, "inner_r_rdy")
    return produce, consume, inner_level, inner_r_rdy


def shadow(m, fifo, fifo_module, find, w_tag, r_tag):
    """The shadow of the RAM's tag bits and the assumption tying the read data to it (the RAM's
    semantics, see :mod:`.pipelined`); returns (shadow, produce, consume, inner_level, reading)."""
    produce, consume, inner_level, inner_r_rdy = _pointers(fifo_module, find)
    depth = fifo.depth - 1
    entries = Array(Signal(len(r_tag), name=f"shadow_{j}", reset_less=True) for j in range(depth))
    read = Signal(len(r_tag), name="shadow_read", reset_less=True)
    with m.If(fifo.w_en & fifo.w_rdy):
        m.d.sync += entries[produce].eq(w_tag)
    reading = inner_r_rdy & (~fifo.r_rdy | fifo.r_en)
    with m.If(reading):
        m.d.sync += read.eq(entries[consume])
    with m.If(fifo.r_rdy):
        m.d.comb += Assume(r_tag == read)
    return entries, produce, consume, inner_level, reading


def fifo_ghosts(m, fifo, fifo_module, find, w_tag) -> dict:
    """{mark: (written, slot, in_ram, out, rank)} and ``"inner_level"`` (module docstring)."""
    produce, consume, inner_level, inner_r_rdy = _pointers(fifo_module, find)
    bits = len(consume)
    reading = inner_r_rdy & (~fifo.r_rdy | fifo.r_en)
    popping = fifo.r_rdy & fifo.r_en
    ghosts = {"inner_level": inner_level}
    for mark in MARKS:
        written = Signal(name=f"fifo{mark}_written")
        slot = Signal(bits, name=f"fifo{mark}_slot")
        in_ram, out = Signal(name=f"fifo{mark}_in_ram"), Signal(name=f"fifo{mark}_out")
        rank = Signal(bits, name=f"fifo{mark}_rank")
        m.d.comb += [written.eq(fifo.w_en & fifo.w_rdy & (w_tag == mark)), rank.eq(slot - consume)]
        read_out = reading & (consume == slot) & in_ram
        with m.If(written):
            m.d.sync += [slot.eq(produce), in_ram.eq(1)]
        with m.Elif(read_out):
            m.d.sync += in_ram.eq(0)
        with m.If(read_out):
            m.d.sync += out.eq(1)
        with m.Elif(popping):
            m.d.sync += out.eq(0)
        ghosts[mark] = (written, slot, in_ram, out, rank)
    return ghosts


def fifo_contract(fifo, r_tag, ghosts) -> list:
    """What the FIFO guarantees (the lemma's conclusion): [(test, name)]."""
    inner_level = ghosts["inner_level"]
    tests = [(~fifo.r_rdy | (r_tag != UNUSED), "fifo_invented")]
    for mark in MARKS:
        _, _, in_ram, out, rank = ghosts[mark]
        tests += [((fifo.r_rdy & (r_tag == mark)) == out, "fifo_out"),
                  (~in_ram | (rank < inner_level), "fifo_ram"),
                  (~(in_ram & out), "fifo_once")]
    return tests


def fifo_environment(fifo, w_tag, ghosts) -> list:
    """What the FIFO's writer must do (the lemma's assumptions): [(test, name)]."""
    # (Not that it never writes while full: a write the FIFO refuses is no write of the ghosts.)
    tests = [(~fifo.w_en | (w_tag != UNUSED), "mark_invented")]
    for mark in MARKS:
        written, _, in_ram, out, _ = ghosts[mark]
        tests.append((~written | ~(in_ram | out), "fifo_mark_once"))
    return tests


class FifoLemma(Elaboratable):
    """The output FIFO of a pipelined build (``SyncFIFOBuffered(width, depth)``, the tag at
    ``layout``'s ``tag`` field) keeps the marks' order (module docstring)."""

    def __init__(self, layout, depth: int, without: str | None = None):
        if depth < 2 or (depth - 1) & (depth - 2):
            # The ranks are pointer differences modulo 2 ** bits: a RAM of 2 ** n entries.
            raise ValueError(f"FIFO depth {depth}: the lemma needs a depth of 2 ** n + 1")
        self.layout, self.depth = layout, depth
        #: The self-test: one of the environment's assumptions (by name) left out.
        self.without = without
        self.w_en, self.r_en = Signal(name="env_w_en"), Signal(name="env_r_en")
        self.w_data = Signal(layout, name="env_w_data")
        #: (file name, line) of each assertion -> its name (how SymbiYosys names a failed one).
        self.assert_names = {}

    def _assert(self, test, name: str):
        check = Assert(test, name, src_loc_at=1)
        self.assert_names[(os.path.basename(check.src_loc[0]), check.src_loc[1])] = name
        return check

    @property
    def ports(self):
        return [self.w_en, self.r_en, self.w_data.as_value()]

    def elaborate(self, platform):
        m = Module()
        fifo = SyncFIFOBuffered(width=self.layout.size, depth=self.depth)
        inner = fifo.elaborate(platform)
        fifo._MustUse__silence = True
        m.submodules.fifo = inner
        m.d.comb += [fifo.w_en.eq(self.w_en), fifo.w_data.eq(self.w_data), fifo.r_en.eq(self.r_en)]

        def find(module, name):
            return next(s for s in module._driving if s.name == name)

        w_tag = self.w_data.tag
        r_tag = data.View(self.layout, fifo.r_data).tag
        ghosts = fifo_ghosts(m, fifo, inner, find, w_tag)
        for test, name in fifo_environment(fifo, w_tag, ghosts):
            if name != self.without:
                m.d.comb += Assume(test)
        for test, name in fifo_contract(fifo, r_tag, ghosts):
            m.d.comb += self._assert(test, name)
        pointers = _pointers(inner, find)
        _read_assumption(m, fifo, pointers, r_tag, ghosts)
        self._entry(m, fifo, pointers, w_tag, ghosts)
        return m

    def _entry(self, m, fifo, pointers, w_tag, ghosts):
        """The invariants that make the contract inductive: of the entry at one arbitrary
        address (its tag shadowed) and of the marks' slots; none per entry."""
        produce, consume, inner_level, _ = pointers
        bits = len(consume)
        address = Signal(bits, name="fifo_address")
        m.d.comb += address.eq(AnyConst(bits))
        held = Signal(len(w_tag), name="fifo_address_tag", reset_less=True)
        with m.If(fifo.w_en & fifo.w_rdy & (produce == address)):
            m.d.sync += held.eq(w_tag)
        live = Signal(name="fifo_address_live")
        m.d.comb += live.eq((address - consume)[:bits] < inner_level)
        m.d.comb += self._assert(~live | (held != UNUSED), "fifo_entry_invented")
        for mark in MARKS:
            _, slot, in_ram, out, _ = ghosts[mark]
            m.d.comb += self._assert((live & (held == mark)) == (in_ram & (slot == address)),
                                     "fifo_entry")
            m.d.comb += self._assert(~out | fifo.r_rdy, "fifo_out_valid")
        (_, slot_a, in_ram_a, _, _), (_, slot_b, in_ram_b, _, _) = (ghosts[mark] for mark in MARKS)
        m.d.comb += self._assert(~(in_ram_a & in_ram_b) | (slot_a != slot_b), "fifo_slots")


def _read_assumption(m, fifo, pointers, r_tag, ghosts):
    """The RAM's read data (cut: free values) carry the tag of the entry read: mark X if it is
    X's slot while X is in the RAM, else an unmarked tag (0) -- the ``fifo_entry`` invariants
    at the address read (module docstring: why this is sound)."""
    _, consume, _, inner_r_rdy = pointers
    expected = Const(0, len(r_tag))
    for mark in reversed(MARKS):
        _, slot, in_ram, _, _ = ghosts[mark]
        expected = Mux(in_ram & (slot == consume), mark, expected)
    read = Signal(len(r_tag), name="fifo_read_tag", reset_less=True)
    with m.If(inner_r_rdy & (~fifo.r_rdy | fifo.r_en)):
        m.d.sync += read.eq(expected)
    with m.If(fifo.r_rdy):
        m.d.comb += Assume(r_tag == read)
