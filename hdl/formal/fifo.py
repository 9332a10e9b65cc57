"""The output FIFO keeps the marks' order: a lemma, so that a pipelined build's order job need
not follow the marks through the FIFO's RAM entry by entry.

The output FIFO of a pipelined build (:class:`~ik5r.hdl.datapath.output_fifo.CreditFifo`: a
RAM between the ``consume`` and ``produce`` pointers, then the output register) once was followed in the order job with a
shadow of every RAM entry's tag: ~2 solver minutes for the pipelined acos's 64 entries, no
verdict for the IK core's 256 (behind 187 stages). So the FIFO gets a proof of its own, for
each build's payload layout and FIFO depth (:func:`.run.prove` runs it before the build's
order job):

**Ghosts** (:func:`fifo_ghosts`, from the FIFO's ports and pointers only): mark X is *written*
when ``w_en & w_rdy`` with tag X; it is then *in the RAM* at entry ``slot`` (``produce`` then)
until the FIFO reads that entry into its output register, where it is *out* until popped
(``r_rdy & r_en``); ``rank`` = ``slot - consume`` (entries ahead of it). An entry is *live*
while it is between the pointers (``address - consume < inner_level``, modulo the RAM's 2 ** n
entries).

**The lemma** (:class:`FifoLemma`: k-induction, depth 2, on the real ``CreditFifo`` of
the build's payload width and FIFO depth): if the writer never writes tag 3 and never writes
mark X while X is in the RAM or out, and never writes while the FIFO is full (``w_rdy`` low:
the FIFO does not refuse such a write; :func:`fifo_environment`), then
(:func:`fifo_contract`) the output shows mark X exactly while X is out, a mark in the RAM is
between the pointers (``rank < inner_level``), never both in the RAM and out, and the output
never shows tag 3.

**How, without a shadow of every entry** (a tracked-entry proof): the RAM is cut (its read data
are free values) and

* the *read assumption* (``Assume``, :func:`_read_assumption`): the tag the FIFO reads from entry
  ``consume`` into its output register is mark X iff that entry is X's ``slot`` while X is in
  the RAM, and never tag 3 (latched at the read in ``fifo_read_mark``, assumed of the output
  register while ``r_rdy``);
* the *tracked entry* (:meth:`FifoLemma._entry`): one arbitrary address (``AnyConst``, fixed in
  a trace) and a shadow of its tag, written as the RAM is (on a write at ``produce`` equal to
  it). Asserted: a live tracked entry never holds tag 3; it holds mark X iff it is X's slot
  while X is in the RAM; A and B never share a slot; a mark out means ``r_rdy``; and when the
  FIFO reads the tracked entry, the read assumption's tag agrees with its shadow
  (``fifo_read_entry``).

Every invariant is about the pointers, the ghosts and one entry, none per entry, so the
induction does not grow with the depth (depth 257, 98 bits: seconds; the shadow of all 256
entries had no verdict after 49 CPU minutes).

*Why the read assumption is sound* (the cut RAM plus this ``Assume`` has every behaviour of the
real one). A live entry's shadow is the real RAM's tag at that address: the write that made it
live wrote both, the FIFO writes only at ``produce`` and never a live entry (never a write
while full: a premise) and reads only live entries. Take a real trace (the RAM not cut, the environment
kept) and suppose some assertion of the lemma fails in it, first at cycle t, for the tracked
address a. At every read before t the read address was live and ``fifo_read_entry`` held for
it (no assertion failed before t, for any address), so the tag assumed there is the real RAM's.
So the real trace up to t satisfies every assumption (the one at t is about registers loaded
before t; no assertion reads the cut RAM's data at t) and, with the tracked address a, fails an
assertion at t: a trace the proof excludes. So no assertion fails in a real trace.

**Its use** (:func:`.pipelined.track_marks`, every pipelined build's order job): the build's
job cuts the FIFO's RAM (as in the control group), keeps the same ghosts, assumes (``Assume``)
the contract and asserts the environment. Sound by induction over time: the contract at cycle
t depends only on the FIFO's inputs before t (its output register, pointers and ghosts are
registers), the environment at cycle t is asserted by the build's job at t, so in a real trace
the first cycle where an assertion of the build's job or the contract failed cannot exist (at that cycle
the environment held before it, so the contract holds, so the job's assertions hold). This
composition step is argued, the two proofs are machine-checked.
"""

from __future__ import annotations

import os

from amaranth.hdl import Assert, Assume, Const, Elaboratable, Module, Mux, Signal
from amaranth.hdl._ast import AnyConst
from amaranth.lib import data

from ik5r.hdl.datapath.output_fifo import CreditFifo

__all__ = ["FifoLemma", "fifo_contract", "fifo_environment", "fifo_ghosts"]

#: The marks (A, B) and the unused tag (see :meth:`.contract.StreamContract._marks`).
MARKS, UNUSED = (1, 2), 3


def _pointers(fifo_module, find):
    produce, consume = find(fifo_module, "produce"), find(fifo_module, "consume")
    inner_level, inner_r_rdy = find(fifo_module, "inner_level"), find(fifo_module, "inner_r_rdy")
    return produce, consume, inner_level, inner_r_rdy


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


def fifo_contract(fifo, r_tag, ghosts, check) -> list:
    """What the FIFO guarantees (the lemma's conclusion): ``check(test, name)`` of each (one
    line each: a failed assertion is named by its line)."""
    inner_level = ghosts["inner_level"]
    checks = [check(~fifo.r_rdy | (r_tag != UNUSED), "fifo_invented")]
    for mark in MARKS:
        _, _, in_ram, out, rank = ghosts[mark]
        checks.append(check((fifo.r_rdy & (r_tag == mark)) == out, "fifo_out"))
        checks.append(check(~in_ram | (rank < inner_level), "fifo_ram"))
        checks.append(check(~(in_ram & out), "fifo_once"))
    return checks


def fifo_environment(fifo, w_tag, ghosts, check) -> list:
    """What the FIFO's writer must do (the lemma's assumptions): ``check(test, name)`` of each."""
    # Never a write while full: the FIFO does not refuse it (the credits' invariant, in a build).
    checks = [check(~fifo.w_en | (w_tag != UNUSED), "mark_invented"),
              check(~fifo.w_en | fifo.w_rdy, "fifo_write_full")]
    for mark in MARKS:
        written, _, in_ram, out, _ = ghosts[mark]
        checks.append(check(~written | ~(in_ram | out), "fifo_mark_once"))
    return checks


class FifoLemma(Elaboratable):
    """The output FIFO of a pipelined build (``CreditFifo(width=, depth=)``, the tag at
    ``layout``'s ``tag`` field) keeps the marks' order (module docstring)."""

    def __init__(self, layout, depth: int, without: str | None = None, skew: int = 0):
        if depth < 2 or (depth - 1) & (depth - 2):
            # The ranks are pointer differences modulo 2 ** bits: a RAM of 2 ** n entries.
            raise ValueError(f"FIFO depth {depth}: the lemma needs a depth of 2 ** n + 1")
        self.layout, self.depth = layout, depth
        #: The self-test: one of the environment's assumptions (by name), or the assumption on
        #: the RAM's read data (``"fifo_read"``), left out.
        self.without = without
        #: The self-test: the read assumption taken at ``consume + skew`` (a wrong RAM model).
        self.skew = skew
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
        fifo = CreditFifo(width=self.layout.size, depth=self.depth)
        inner = fifo.elaborate(platform)
        fifo._MustUse__silence = True
        m.submodules.fifo = inner
        m.d.comb += [fifo.w_en.eq(self.w_en), fifo.w_data.eq(self.w_data), fifo.r_en.eq(self.r_en)]

        def find(module, name):
            return next(s for s in module._driving if s.name == name)

        w_tag = self.w_data.tag
        r_tag = data.View(self.layout, fifo.r_data).tag
        ghosts = fifo_ghosts(m, fifo, inner, find, w_tag)
        environment = fifo_environment(fifo, w_tag, ghosts, lambda test, name: (test, name))
        m.d.comb += [Assume(test) for test, name in environment if name != self.without]
        m.d.comb += fifo_contract(fifo, r_tag, ghosts, self._assert)
        pointers = _pointers(inner, find)
        tracked = _read_assumption(m, fifo, pointers, r_tag, ghosts, self.skew,
                                   assume=self.without != "fifo_read")
        self._entry(m, fifo, pointers, w_tag, ghosts, tracked)
        return m

    def _entry(self, m, fifo, pointers, w_tag, ghosts, tracked):
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
        # The read assumption at the tracked entry is its shadow: so at every address read.
        reading = _pointers_reading(fifo, pointers) & (consume == address)
        for mark in MARKS:
            m.d.comb += self._assert(~reading | ((held == mark) == (tracked == mark)),
                                     "fifo_read_entry")


def _pointers_reading(fifo, pointers):
    """The FIFO reads its RAM (entry ``consume``) into its output register this cycle."""
    return pointers[3] & (~fifo.r_rdy | fifo.r_en)


def _read_assumption(m, fifo, pointers, r_tag, ghosts, skew: int = 0, assume: bool = True):
    """The RAM's read data (cut: free values) carry the tag of the entry read: mark X iff that
    entry is X's slot while X is in the RAM, and never tag 3 (module docstring: why this is
    sound); returns the mark expected at ``consume`` (0: none). ``skew``, ``assume``: the
    self-test's wrong RAM model, or none."""
    consume = pointers[1]
    tracked = Const(0, 2)
    for mark in reversed(MARKS):
        _, slot, in_ram, _, _ = ghosts[mark]
        tracked = Mux(in_ram & (slot == (consume + skew)[:len(consume)]), mark, tracked)
    read = Signal(2, name="fifo_read_mark", reset_less=True)
    with m.If(_pointers_reading(fifo, pointers)):
        m.d.sync += read.eq(tracked)
    if assume:
        with m.If(fifo.r_rdy):
            m.d.comb += [Assume((r_tag == mark) == (read == mark)) for mark in MARKS]
            m.d.comb += Assume(r_tag != UNUSED)
    return tracked
