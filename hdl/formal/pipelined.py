"""The ``order`` group of a pipelined block by k-induction: where the two marked items are.

A pipelined block (:func:`~ik5r.hdl.datapath.build.build_pipelined`) is a delay line that steps
every clock (stage ``s`` holds an item ``s + 1`` cycles after its input transfer: its
``<stage>_valid`` bit and ``<stage>_tag`` register), then the FIFO's write register
(``<name>_fifo_write``, ``<name>_fifo_data``), then the output FIFO (``CreditFifo``: a RAM of
``capacity - 1`` entries between the ``consume`` and ``produce`` pointers, and its output
register, ``r_rdy``). So a marked item X (A = 1, B = 2, see :meth:`.contract.StreamContract._marks`)
is, ``age`` cycles after it was accepted: in stage ``age - 1`` (``age`` <= latency of the stages
``L``), in the write register (``age`` = L + 1), in the FIFO (``age`` = L + 2): in its RAM at the
entry it was written to (``slot``, a ghost register) while that entry is between the pointers,
else in the output register.

:func:`track_marks` asserts exactly that, both ways (a stage, the write register, the output
register holds mark X iff X is inside and there, so it is nowhere else and never duplicated; in
the RAM it is between the pointers), A ahead of B, and bounds on the marks' ``waiting``
counter: with the ``conservation`` and ``credits`` invariants (the FIFO never overflows) these
make the marks' assertions inductive.

**The FIFO, by its lemma.** An assertion cannot read an Amaranth memory's contents, so the job's
Yosys script cuts the FIFO's RAM (its read data become free values, as in the ``control``
group), and the FIFO is taken by its lemma (:mod:`.fifo`, proved on its own for the block's
payload layout and FIFO depth, a job of its own run first: :func:`.run.prove`): the FIFO's
ghosts (where each mark was written, whether it is in the RAM or in the output register) are
kept here from the FIFO's ports and pointers, the lemma's conclusion (the output shows mark X
exactly while X is out; a mark in the RAM is between the pointers) is assumed (``Assume``) and
its premises (never tag 3 written, never a mark written while it is in the FIFO) are asserted.
The composition is sound by induction over time (:mod:`.fifo`, "Its use"). So no invariant is per
RAM entry and the job does not grow with the FIFO's depth (the pipelined acos's 64 entries,
the IK core's 256). (Earlier the job shadowed the tag of every RAM entry: acos's order job
took ~2 solver minutes, the IK core's had no verdict.)

**Long pipelines.** The pipelined IK core's tag skips 184 stages in a stash RAM: the stages
there take their tags from a ghost delay line tied to the stash's output by the stash lemma
(:func:`.stash.stash_tags`).
"""

from __future__ import annotations

from amaranth.hdl import Assume, Module, Signal
from amaranth.lib import data

from .fifo import fifo_contract, fifo_environment, fifo_ghosts
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


def track_marks(m, dut, inner, fifo, fifo_module, find, marks, o_valid, o_payload, check):
    """Assert (``check(test, name)``) where the marks are (module docstring). ``marks``:
    {mark: (sent, got)} and ``"waiting"``: the counter of cycles without ``o.valid`` while A
    is inside; ``o_payload``: the output payload (a View). The output FIFO by its lemma
    (:mod:`.fifo`): its conclusion assumed, its premises asserted."""
    name = dut._dp.name
    stages = _stage_places(m, dut, inner, find)
    latency = len(stages)
    write = find(inner, f"{name}_fifo_write")
    write_tag = data.View(dut.o.payload.shape(), find(inner, f"{name}_fifo_data")).tag
    # Only the marks 0, 1, 2 are inside: an item tagged 3 would come out as an invented mark.
    unused = (1 << len(o_payload.tag)) - 1
    m.d.comb += [check(~valid | (tag != unused), "mark_invented") for valid, tag in stages]
    m.d.comb += check(~write | (write_tag != unused), "mark_invented")
    ghosts = fifo_ghosts(m, fifo, fifo_module, find, write_tag)
    # The FIFO's own output tag (o_payload is what the environment sees, a fault between).
    r_tag = data.View(dut.o.payload.shape(), fifo.r_data).tag
    m.d.comb += fifo_contract(fifo, r_tag, ghosts, lambda test, name: Assume(test))
    m.d.comb += fifo_environment(fifo, write_tag, ghosts, check)
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
        _, _, in_ram, out, rank = ghosts[mark]
        m.d.comb += check(in_fifo == (in_ram | out), "mark_fifo")
        m.d.comb += check(~in_ram | (rank < ghosts["inner_level"]), "mark_ram")
        m.d.comb += check(~got | sent, "mark_got_sent")
        m.d.comb += check(~inside | ((age != 0) & (age <= latency + 2)), "mark_age")
        for s, (valid, tag) in enumerate(stages):
            m.d.comb += check((valid & (tag == mark)) == (inside & (age == s + 1)), "mark_stage")
        m.d.comb += check((write & (write_tag == mark)) == (inside & (age == latency + 1)), "mark_write")
        m.d.comb += check((o_valid & (o_payload.tag == mark)) == (in_fifo & ~in_ram), "mark_output")
        where[mark] = (inside, age, rank, in_fifo, in_ram)
    _order_invariants(m, marks, where, latency, o_valid, check)


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
