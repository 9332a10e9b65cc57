"""The ``order`` group of a pipelined block by k-induction: where the two marked items are.

A pipelined block (:func:`~ik5r.hdl.build.build_pipelined`) is a delay line that steps
every clock (stage ``s`` holds an item ``s + 1`` cycles after its input transfer: its
``<stage>_valid`` bit and ``<stage>_tag`` register), then the FIFO's write register
(``<name>_fifo_write``, ``<name>_fifo_data``), then the output FIFO (``SyncFIFOBuffered``: a RAM of
``capacity - 1`` entries between the ``consume`` and ``produce`` pointers, and its output
register, ``r_rdy``). So a marked item X (A = 1, B = 2, see :meth:`.contract.StreamContract._marks`)
is, ``age`` cycles after it was accepted: in stage ``age - 1`` (``age`` <= latency of the stages
``L``), in the write register (``age`` = L + 1), in the FIFO (``age`` = L + 2): in its RAM at the
entry it was written to (``slot``, a ghost register) while that entry is between the pointers,
else in the output register.

:func:`track_marks` asserts exactly that, both ways (a stage, the write register, a live RAM
entry, the output register holds mark X iff X is inside and there, so it is nowhere else and
never duplicated), A ahead of B, and bounds on the marks' ``waiting`` counter: with the
``conservation`` and ``credits`` invariants (the FIFO never overflows) these make the marks'
assertions inductive.

**The RAM.** An assertion cannot read an Amaranth memory's contents, so the job's Yosys script
cuts the FIFO's RAM (its read data become free values, as in the ``control`` group) and
:func:`track_marks` keeps a *shadow* of its tag bits: written on the FIFO's write enable at
``produce`` with the written tag, read on its read enable at ``consume`` into a register, and
assumes (``Assume``) that the RAM's registered read data carry that tag while ``r_rdy``. This is
the RAM's own semantics (a read returns the last write to its address; the FIFO never reads and
writes one entry in the same cycle; the RAM and the shadow start from zeros and neither is
reset), so every behaviour of the real block is one of the cut model's: the proof holds for it.

**Long pipelines.** The pipelined IK core's tag skips 184 stages in a stash RAM: the stages
there take their tags from a ghost delay line tied to the stash's output by the stash lemma
(:func:`.stash.stash_tags`). Its 256-entry FIFO behind 187 stages is out of reach entry by
entry: with ``fifo_lemma`` the FIFO's RAM is not shadowed; the FIFO's lemma (:mod:`.fifo`,
proved on its own) says where the marks are in it, and this job asserts the lemma's premises.
"""

from __future__ import annotations

from amaranth.hdl import Assume, Module, Signal
from amaranth.lib import data

from .fifo import fifo_contract, fifo_environment, fifo_ghosts, shadow
from .stash import stash_tags

__all__ = ["elaborate_fifo", "track_marks"]


def elaborate_fifo(inner: Module, name: str, platform):
    """Elaborate the output FIFO ``name`` of ``inner`` in place (its pointers then are signals
    the harness can read); returns (the FIFO, its module)."""
    fifo, src_loc = inner._named_submodules[name]
    module = fifo.elaborate(platform)
    fifo._MustUse__silence = True
    inner._named_submodules[name] = (module, src_loc)
    return fifo, module


def _stage_places(m, dut, inner: Module, find):
    """(valid bit, tag) of every register stage, in pipeline order: its tag register, or where
    the tag is in a stash RAM (the IK core) the ghost delay line of :func:`.stash.stash_tags`."""
    places = []
    for name, _, count, iterated in dut._dp.stages:
        for step in range(count):
            prefix = f"{name}{step}" if iterated else name
            try:
                tag = find(inner, f"{prefix}_tag")
            except LookupError:
                tag = None
            places.append((find(inner, f"{prefix}_valid"), tag))
    return stash_tags(m, dut, inner, places, find)


def track_marks(m, dut, inner, fifo, fifo_module, find, marks, o_valid, o_payload, check,
                fifo_lemma: bool = False):
    """Assert (``check(test, name)``) where the marks are (module docstring). ``marks``:
    {mark: (sent, got)} and ``"waiting"``: the counter of cycles without ``o.valid`` while A
    is inside; ``o_payload``: the output payload (a View). ``fifo_lemma``: the FIFO by its
    lemma (:mod:`.fifo`) instead of the shadow of its RAM's entries."""
    name = dut._dp.name
    stages = _stage_places(m, dut, inner, find)
    latency = len(stages)
    write = find(inner, f"{name}_fifo_write")
    write_tag = data.View(dut.o.payload.shape(), find(inner, f"{name}_fifo_data")).tag
    # Only the marks 0, 1, 2 are inside: an item tagged 3 would come out as an invented mark.
    unused = (1 << len(o_payload.tag)) - 1
    m.d.comb += [check(~valid | (tag != unused), "mark_invented") for valid, tag in stages]
    m.d.comb += check(~write | (write_tag != unused), "mark_invented")
    if fifo_lemma:
        ghosts = fifo_ghosts(m, fifo, fifo_module, find, write_tag)
        # The FIFO's own output tag (o_payload is what the environment sees, a fault between).
        r_tag = data.View(dut.o.payload.shape(), fifo.r_data).tag
        m.d.comb += fifo_contract(fifo, r_tag, ghosts, lambda test, name: Assume(test))
        m.d.comb += fifo_environment(fifo, write_tag, ghosts, check)
        entries = None
    else:
        entries, produce, consume, inner_level, reading = shadow(
            m, fifo, fifo_module, find, data.View(dut.o.payload.shape(), fifo.w_data).tag, o_payload.tag)
        bits = len(consume)
        lives = [((j - consume)[:bits] < inner_level) if bits else (inner_level != 0)
                 for j in range(len(entries))]
        m.d.comb += [check(~live | (entries[j] != unused), "mark_invented") for j, live in enumerate(lives)]
    where = {}
    for mark in (1, 2):
        sent, got = marks[mark]
        inside = Signal(name=f"mark{mark}_inside")
        age = Signal(range(latency + 3), name=f"mark{mark}_age")
        in_fifo = Signal(name=f"mark{mark}_in_fifo")
        m.d.comb += [inside.eq(sent & ~got), in_fifo.eq(inside & (age == latency + 2))]
        with m.If(marks["taken_in"] & (marks["i_tag"] == mark)):
            m.d.sync += age.eq(1)
        with m.Elif((age != 0) & (age <= latency + 1)):
            m.d.sync += age.eq(age + 1)
        if fifo_lemma:
            _, _, in_ram, out, rank = ghosts[mark]
            m.d.comb += check(in_fifo == (in_ram | out), "mark_fifo")
            m.d.comb += check(~in_ram | (rank < ghosts["inner_level"]), "mark_ram")
        else:
            in_ram, rank, slot = _in_ram(m, mark, inside, age, latency, produce, consume, reading)
            m.d.comb += check(~in_ram | (in_fifo & (rank < inner_level)), "mark_ram")
            for j, live in enumerate(lives):
                m.d.comb += check((live & (entries[j] == mark)) == (in_ram & (slot == j)), "mark_ram")
        m.d.comb += check(~got | sent, "mark_got_sent")
        m.d.comb += check(~inside | ((age != 0) & (age <= latency + 2)), "mark_age")
        for s, (valid, tag) in enumerate(stages):
            m.d.comb += check((valid & (tag == mark)) == (inside & (age == s + 1)), "mark_stage")
        m.d.comb += check((write & (write_tag == mark)) == (inside & (age == latency + 1)), "mark_write")
        m.d.comb += check((o_valid & (o_payload.tag == mark)) == (in_fifo & ~in_ram), "mark_output")
        where[mark] = (inside, age, rank, in_fifo, in_ram)
    _order_invariants(m, marks, where, latency, o_valid, check)


def _in_ram(m, mark, inside, age, latency, produce, consume, reading):
    """The mark's RAM entry (``slot``): written to the RAM and not yet read from it (the entry
    is reused after); returns (in_ram, rank: entries ahead of it, slot)."""
    slot = Signal(len(consume), name=f"mark{mark}_slot")
    rank = Signal(len(consume), name=f"mark{mark}_rank")
    in_ram = Signal(name=f"mark{mark}_in_ram")
    m.d.comb += rank.eq(slot - consume)
    with m.If(inside & (age == latency + 1)):
        m.d.sync += [slot.eq(produce), in_ram.eq(1)]
    with m.Elif(reading & (consume == slot)):
        m.d.sync += in_ram.eq(0)
    return in_ram, rank, slot


def _order_invariants(m, marks, where, latency, o_valid, check):
    """A ahead of B, and the cycles A has waited without an output."""
    (sent_a, got_a), (sent_b, got_b) = marks[1], marks[2]
    in_a, age_a, rank_a, fifo_a, ram_a = where[1]
    in_b, age_b, rank_b, fifo_b, ram_b = where[2]
    m.d.comb += [
        check(~sent_b | sent_a, "mark_sent_order"),
        check(~got_b | got_a, "mark_got_order"),
    ]
    with m.If(in_a & in_b):
        m.d.comb += check((age_a > age_b) | (fifo_a & fifo_b & (~ram_a | (ram_b & (rank_a < rank_b)))),
                          "mark_a_ahead")
    waiting = marks["waiting"]
    with m.If(in_a & ~fifo_a):
        m.d.comb += check(waiting < age_a, "mark_waiting")
    with m.If(fifo_a):
        m.d.comb += check(waiting <= latency + 1 + o_valid, "mark_waiting")
