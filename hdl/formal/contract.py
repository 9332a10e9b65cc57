"""The stream contract of an ik5r block or IK core as Amaranth ``Assert``/``Assume`` properties.

:class:`StreamContract` wraps a REAL component (:class:`~ik5r.hdl.blocks.stream_block.StreamBlock`: the four
blocks in both architectures and the IK core: pipelined, and the compact arch's
sequenced engine, :class:`~ik5r.hdl.sequenced.engine.SequencedIKCore`, see :mod:`.sequenced`) for SymbiYosys.

**Data abstraction.** The contract is about control, and the datapaths (dozens of adders and
multipliers a stage, up to 190 stages) would drown a solver. :func:`abstract_datapath` keeps the
component's own :class:`~ik5r.hdl.datapath.stages.Datapath`: the same stages, counts, iterated
stages, stashes and the same ``Datapath.build`` (valid chain, credits, output FIFO, step
counters), but every value a stage computes, except the ``tag``, is a free value
(``$anyseq``) of the register's shape. So the registers, their enables and the tag path are the
component's, the data they load is arbitrary (the sequenced core: its data memory, step-angle ROM
and data registers, cut by the job's Yosys script): a property proved here holds for any data, in
particular for the real arithmetic (the control never reads a data value). Only the generic
mapping is checked (``dsp="ecp5"`` changes the data cells, not the control).

**Reset.** ``rst`` is the synchronous, active-high reset. A cycle with ``rst`` high is not a
transfer on either stream (as in the cocotb benches), and a reset empties the block: the items
accepted before it and not yet taken are discarded, none of them comes out after it, and every
item accepted after it comes out, once, in order. The upstream's hold obligation ends with a
reset.

**The contract**, in two groups (:data:`CHECKS`), each one SymbiYosys job:

``control`` (proved by k-induction: for every reachable state, not only to a depth):

* environment (``Assume``): the upstream holds ``i.valid`` and ``i.payload`` while
  ``i.valid & ~i.ready``;
* *hold*: ``o.valid & ~o.ready`` in a cycle without reset -> next cycle ``o.valid`` and the same
  ``o.payload`` (every bit, tag included): valid never dropped, payload never changed before
  taken;
* *conservation*: the items inside (accepted and not taken, counted at the ports) are exactly
  the component's occupied stages (stage valid bits), plus in the pipelined build the output
  FIFO's level and its write register: no item is lost, duplicated or invented; at most
  ``capacity`` items inside; no ``o.valid`` without an item inside; in the cycle after a reset
  ``o.valid`` is low and nothing is inside;
* *room* (sequenced IK core, :mod:`.sequenced`): ``i.ready`` only while fewer than ``capacity``
  items are inside; its engine's control invariants (program counter, instruction registers);
* *credits* (pipelined): the credit counter is ``capacity`` minus the items inside, ``i.ready``
  is exactly ``credits != 0``, and the output FIFO is never written while full (its
  ``CreditFifo`` does not check: it would overwrite an item). With the FIFO's own invariant
  (its output register is empty only while at most one item is queued) these are inductive.

``order`` (the sequenced IK core: k-induction against a ghost queue of the tags accepted and not
yet taken, :mod:`.sequenced`; the pipelined blocks and IK core (``inductive_order``): k-induction
with the marks' places tracked, :mod:`.pipelined` (the output FIFO by the FIFO's lemma,
:mod:`.fifo`; the IK core's tag through its stash RAM, :mod:`.stash`); the iterative blocks and
(``inductive_order``): k-induction with their one item's place tracked,
:mod:`.iterative`; Wolper's
data-independence argument: a component that never reads its tags keeps order for all data iff
it does for two marked items): the
upstream marks at most one item A (tag 1) and, after it, at most one item B (tag 2) per reset,
others 0, at free times:

* an output marked 1 (2) only if A (B) was sent since the last reset and not yet taken: none
  invented, duplicated, or left over from before a reset;
* B never comes out before A: order;
* while A is inside, ``o.valid`` is never low for ``latency`` cycles in a row: A is not lost
  (with *conservation*, every item comes out).

``mutation`` injects a fault for the self-test: ``"ready_glitch"`` (the component sees
``o.ready`` high when a free input says so: a broken hold), ``"drop_input"`` (an item the
upstream handed over never reaches the component: a lost tag), ``"payload_flip"`` (a held
output's LSB flips), ``"tag_flip"`` (the output tag's LSB is inverted on its way out: an item
comes out with another's mark; the order group must fail).
"""

from __future__ import annotations

import copy
import os

from amaranth.hdl import Assert, Assume, Elaboratable, Module, ResetSignal, Signal, Value

# Amaranth 0.5 keeps its formal free values in _ast (no public alias yet); they become $anyseq.
from amaranth.hdl._ast import AnySeq

from ik5r.core.modes import Arch

from ..datapath.stages import Datapath, Stage
from ..sequenced.engine import SequencedIKCore
from ..blocks.stream_block import StreamBlock
from .iterative import track_item
from .pipelined import elaborate_fifo, track_marks
from .sequenced import elaborate_engine, sequencer, tag_queue

__all__ = ["CHECKS", "MUTATIONS", "OUTSIDE", "TAG_WIDTH", "StreamContract", "abstract_datapath", "find_signal"]

#: Faults the self-test injects (see the module docstring).
MUTATIONS = ("ready_glitch", "drop_input", "payload_flip", "tag_flip")

#: Faults outside the component (between it and the environment): the control group's
#: invariants, about the component, still hold, so an order job may assume them.
OUTSIDE = ("tag_flip",)

#: The property groups (module docstring), one SymbiYosys job each.
CHECKS = ("control", "order")

#: Stages per ghost prefix counter of the occupancy of a pipelined build
#: (:meth:`StreamContract._segment_counts`). The pipelined IK core's control job (190 stages), in
#: SymbiYosys process seconds: 68 with segments of 16, 43 of 8, 37 of 4, 37 of 2.
SEGMENT = 4

#: Tag width of the component under check: the marks 0 (unmarked), 1 (A) and 2 (B).
TAG_WIDTH = 2


def _free(values: dict, shapes: dict, keep) -> dict:
    return {key: value if key in keep else
            AnySeq(shapes.get(key, Value.cast(value).shape()))
            for key, value in values.items()}


def abstract_datapath(dp: Datapath, keep=("tag",)) -> Datapath:
    """A copy of ``dp`` with the same stages whose computed values (all but ``keep``) are free.

    Wiring stages are kept as they are (the IK core's stashes register their links there)."""
    out = copy.copy(dp)
    out.stages = []
    shapes = dp.shapes
    for stage in map(Stage.of, dp.stages):
        name, fn, count, iterated = stage
        if count == 0:
            out.stages.append(stage)
            continue
        if iterated:
            def run(s, i, fn=fn):
                return _free(fn(s, i), shapes, keep)
        else:
            def run(s, fn=fn):
                return _free(fn(s), shapes, keep)
        out.stages.append((name, run, count, iterated))
    return out


def find_signal(module: Module, name: str) -> Signal:
    for signal in module._driving:
        if signal.name == name:
            return signal
    raise LookupError(f"no signal {name!r} in the component's module")


def _occupied_stages(module: Module, exclude) -> list:
    """The stage valid bits of a built datapath (``<stage>_valid``, one bit, driven in the
    component's module), without ``exclude`` (the ``o.valid`` port)."""
    return [signal for signal in module._driving
            if signal.name.endswith("_valid") and len(signal) == 1
            and not any(signal is other for other in exclude)]


class StreamContract(Elaboratable):
    """The ``checks`` of the contract (module docstring) around ``dut``, a component built with
    ``tag_width=TAG_WIDTH``. Its free inputs are :attr:`ports`."""

    def __init__(self, dut: StreamBlock, *, checks=CHECKS, mutation: str | None = None,
                 inductive_order: bool = False, control_assumed: bool = False):
        if not checks or not set(checks) <= set(CHECKS):
            raise ValueError(f"checks must be a non-empty subset of {CHECKS}, got {checks!r}")
        if mutation is not None and mutation not in MUTATIONS:
            raise ValueError(f"mutation must be one of {MUTATIONS}, got {mutation!r}")
        if dut.tag_width != TAG_WIDTH:
            raise ValueError(f"dut.tag_width must be {TAG_WIDTH}, got {dut.tag_width}")
        self.checks = tuple(checks)
        #: The ``order`` group with the invariants that make it inductive: :mod:`.pipelined`
        #: (a pipelined build; the IK core's tag stash through :mod:`.stash`), :mod:`.iterative`
        #: (an iterative build).
        self.inductive_order = inductive_order
        #: In an ``order`` job without ``control``: the control group's assertions (conservation,
        #: credits, the FIFO's) as ``Assume`` s, sound only where the ``control`` job of the same
        #: component (same harness, data abstraction and memory cuts, no fault) proves them: they
        #: then hold in every reachable state of this job's model, which is that model plus ghost
        #: registers and ``Assume`` s (which only remove behaviours).
        if control_assumed and ("control" in checks or mutation not in (None, *OUTSIDE)):
            raise ValueError("control_assumed: only for an order job of a fault-free component")
        self.control_assumed = control_assumed
        self.dut = dut
        #: The component's elaborated module, once :meth:`elaborate` has run (the stash lemma's
        #: links are read from it, :func:`.run.stash_lemma_links`).
        self.inner = None
        self.mutation = mutation
        # The sequenced IK core has no Datapath: its engine is kept whole (:mod:`.sequenced`).
        self.sequenced = isinstance(dut, SequencedIKCore)
        self.pipelined = not self.sequenced and dut._datapath_arch == Arch.PIPELINED
        if not self.sequenced:
            dut._dp = abstract_datapath(dut._dp)
        # The harness elaborates ``dut`` itself (to reach its FIFO and credits), so Amaranth never
        # sees it used: silence its UnusedElaboratable warning.
        dut._MustUse__silence = True
        self.i_valid = Signal(name="env_i_valid")
        self.i_payload = Signal(dut.i.payload.shape(), name="env_i_payload")
        self.o_ready = Signal(name="env_o_ready")
        self.glitch = Signal(name="env_glitch")
        #: (file name, line) of each assertion -> its name (how SymbiYosys names a failed one).
        self.assert_names = {}

    def _assert(self, test, name: str):
        check = Assert(test, name, src_loc_at=1)
        self.assert_names[(os.path.basename(check.src_loc[0]), check.src_loc[1])] = name
        return check

    def _invariant(self, test, name: str):
        """A control assertion, or its ``Assume`` where :attr:`control_assumed`."""
        if self.control_assumed:
            return Assume(test, name, src_loc_at=1)
        check = Assert(test, name, src_loc_at=1)
        self.assert_names[(os.path.basename(check.src_loc[0]), check.src_loc[1])] = name
        return check

    @property
    def ports(self):
        return [self.i_valid, self.i_payload.as_value(), self.o_ready, self.glitch]

    def elaborate(self, platform):
        m = Module()
        dut = self.dut
        self.inner = inner = dut.elaborate(platform)
        m.submodules.dut = inner
        self.places = None
        if self.pipelined:
            fifo_name = f"{dut._dp.name}_output_fifo"
            self.fifo, self.fifo_module = inner._named_submodules[fifo_name][0], None
            if "order" in self.checks and self.inductive_order:
                self.fifo, self.fifo_module = elaborate_fifo(inner, fifo_name, platform)
        if self.sequenced:
            engine = elaborate_engine(inner, dut._engine, platform)
            self.places = sequencer(m, dut, inner, engine, find_signal, self._assert)
        rst = ResetSignal()
        past_rst = Signal(reset_less=True, init=1)
        m.d.sync += past_rst.eq(rst)
        # The streams as the environment sees them, and as the component does (a fault between).
        i_valid, o_ready, o_valid = self.i_valid, self.o_ready, dut.o.valid
        m.d.comb += [
            dut.i.payload.eq(self.i_payload),
            dut.i.valid.eq(i_valid & ~self.glitch if self.mutation == "drop_input" else i_valid),
            dut.o.ready.eq(o_ready | self.glitch if self.mutation == "ready_glitch" else o_ready),
        ]
        o_payload = Signal.like(dut.o.payload)
        m.d.comb += o_payload.eq(dut.o.payload)
        if self.mutation == "tag_flip":
            m.d.comb += o_payload.tag.eq(dut.o.payload.tag ^ 1)
        taken_in = ~rst & i_valid & dut.i.ready
        taken_out = ~rst & o_valid & o_ready
        self._environment(m, rst)
        inside = None
        if "control" in self.checks:
            self._hold(m, rst, o_valid, o_ready, o_payload)
            inside = self._conservation(m, inner, taken_in, taken_out, past_rst)
            if self.pipelined:
                self._credits(m, inner, inside)
        if "order" in self.checks and self.sequenced:
            # Proved by k-induction against a ghost queue of the tags inside (:mod:`.sequenced`).
            if inside is None:
                inside = self._conservation(m, inner, taken_in, taken_out, past_rst)
            tag_queue(m, dut.capacity, inside, taken_in, taken_out, self.i_payload.tag,
                      self.places, self._assert)
        elif "order" in self.checks:
            marks = self._marks(m, rst, taken_in, taken_out, o_valid, o_payload.tag)
            if self.pipelined and self.inductive_order:
                # By k-induction: where the marks are (:mod:`.pipelined`), with the control
                # invariants that keep the FIFO from overflowing.
                if inside is None:
                    inside = self._conservation(m, inner, taken_in, taken_out, past_rst)
                    self._credits(m, inner, inside)
                track_marks(m, dut, inner, self.fifo, self.fifo_module, find_signal, marks,
                            o_valid, o_payload, self._assert)
            elif self.inductive_order:
                # By k-induction: where the one item inside is (:mod:`.iterative`).
                if inside is None:
                    self._conservation(m, inner, taken_in, taken_out, past_rst)
                track_item(m, dut, inner, find_signal, marks, o_valid, self._assert)
        return m

    def _environment(self, m, rst):
        """The upstream's side of the stream rule (Assume)."""
        stalled = Signal(reset_less=True)
        held = Signal.like(self.i_payload, reset_less=True)
        m.d.sync += [stalled.eq(~rst & self.i_valid & ~self.dut.i.ready), held.eq(self.i_payload)]
        with m.If(stalled):
            m.d.comb += Assume(self.i_valid & (self.i_payload.as_value() == held.as_value()))

    def _hold(self, m, rst, o_valid, o_ready, o_payload):
        """Valid never dropped and payload never changed before the output is taken."""
        stalled = Signal(reset_less=True)
        held = Signal.like(o_payload, reset_less=True)
        m.d.sync += [stalled.eq(~rst & o_valid & ~o_ready), held.eq(o_payload)]
        if self.mutation == "payload_flip":
            flipped = Signal.like(o_payload)
            m.d.comb += flipped.eq(o_payload.as_value() ^ stalled)
            o_payload = flipped
        with m.If(stalled):
            m.d.comb += self._assert(o_valid, "hold_valid")
            m.d.comb += self._assert(o_payload.as_value() == held.as_value(), "hold_payload")

    def _conservation(self, m, inner, taken_in, taken_out, past_rst):
        """Items inside, counted at the ports, against the component's occupancy."""
        capacity = self.dut.capacity
        inside = Signal(range(capacity + 2))
        with m.If(taken_in & ~taken_out):
            m.d.sync += inside.eq(inside + 1)
        with m.Elif(taken_out & ~taken_in):
            m.d.sync += inside.eq(inside - 1)
        if self.sequenced:
            occupancy = self.places.occupancy
        else:
            stages = _occupied_stages(inner, [self.dut.o.valid])
            occupancy = self._segment_counts(m, stages, taken_in) if self.pipelined else sum(stages)
        if self.pipelined:
            name = self.dut._dp.name
            occupancy = occupancy + self.fifo.level + find_signal(inner, f"{name}_fifo_write")
        m.d.comb += [
            self._invariant(inside <= capacity, "capacity"),
            self._invariant(inside == occupancy, "conservation"),
            self._invariant(~self.dut.o.valid | (inside != 0), "no_output_without_input"),
        ]
        if self.sequenced:
            # No credits: i.ready is the input register's being free, so it must mean room.
            m.d.comb += self._invariant(~self.dut.i.ready | (inside < capacity), "ready_has_room")
        with m.If(past_rst):
            m.d.comb += self._invariant(~self.dut.o.valid & (inside == 0), "reset_empties")
        return inside

    def _segment_counts(self, m, stages, taken_in):
        """The occupied stages of a pipelined build, by ghost prefix counters.

        One population count over the whole valid chain (190 stages in the IK core) is beyond
        a SAT solver once the chain shifts (the counts before and after are different adder
        trees). So the chain is cut in segments of :data:`SEGMENT` stages, and a ghost counter
        per segment counts the items in the stages up to the segment's end, stepped by the
        item entering the chain and the item leaving the segment; it is asserted equal to the
        previous segment's counter plus the segment's own small count, and the last counter is
        the occupancy. Each invariant relates two counters and one segment, so the induction
        step stays local. (A sum of per-segment counters of 16 stages, as before, made the step
        prove the sum's telescoping over all the segments at once: the IK core's control job
        took 426 CPU s, now 37.) Sound: the counters are ghost registers, every one of them is
        tied to the real valid bits by an assertion, the occupancy is the same sum."""
        before = 0
        for first in range(0, len(stages), SEGMENT):
            part = stages[first:first + SEGMENT]
            count = Signal(range(first + len(part) + 1), name=f"segment_{first}")
            with m.If(taken_in & ~part[-1]):
                m.d.sync += count.eq(count + 1)
            with m.Elif(part[-1] & ~taken_in):
                m.d.sync += count.eq(count - 1)
            m.d.comb += self._invariant(count == before + sum(part), "segment_count")
            before = count
        return before

    def _credits(self, m, inner, inside):
        """The credit counter of the pipelined build never lets the output FIFO overflow."""
        name = self.dut._dp.name
        credits = find_signal(inner, f"{name}_credits")
        fifo = self.fifo
        capacity = self.dut.capacity
        m.d.comb += [
            self._invariant(credits + inside == capacity, "credits"),
            self._invariant(self.dut.i.ready == (credits != 0), "ready_is_credit"),
            self._invariant(~fifo.w_en | fifo.w_rdy, "fifo_no_overflow"),
            # The FIFO's own invariant: its output register is empty only while at
            # most one item is queued behind it (it is refilled the cycle after).
            self._invariant(fifo.r_rdy | (fifo.level <= 1), "fifo_refill"),
        ]

    def _marks(self, m, rst, taken_in, taken_out, o_valid, o_tag):
        """Two marked items A (1) and B (2): none invented, B not before A, A not lost."""
        i_tag = self.i_payload.tag
        sent_a, sent_b, got_a, got_b = (Signal(name=name) for name in ("sent_a", "sent_b", "got_a", "got_b"))
        with m.If(self.i_valid & ~rst):
            m.d.comb += Assume(i_tag != 3)
            m.d.comb += Assume((i_tag != 1) | ~sent_a)
            m.d.comb += Assume((i_tag != 2) | (sent_a & ~sent_b))
        with m.If(taken_in):
            m.d.sync += [sent_a.eq(sent_a | (i_tag == 1)), sent_b.eq(sent_b | (i_tag == 2))]
        with m.If(taken_out):
            m.d.sync += [got_a.eq(got_a | (o_tag == 1)), got_b.eq(got_b | (o_tag == 2))]
        with m.If(o_valid):
            m.d.comb += [
                self._assert(o_tag != 3, "mark_invented"),
                self._assert((o_tag != 1) | (sent_a & ~got_a), "mark_a_once"),
                self._assert((o_tag != 2) | (sent_b & ~got_b), "mark_b_once"),
                self._assert((o_tag != 2) | got_a, "order"),
            ]
        waiting = Signal(range(self.dut.latency + 1))
        with m.If(sent_a & ~got_a & ~o_valid & ~rst):
            m.d.sync += waiting.eq(waiting + 1)
        with m.Else():
            m.d.sync += waiting.eq(0)
        m.d.comb += self._assert(waiting < self.dut.latency, "a_not_lost")
        return {1: (sent_a, got_a), 2: (sent_b, got_b), "waiting": waiting, "taken_in": taken_in,
                "i_tag": i_tag}
