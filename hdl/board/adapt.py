"""Word streams around the struct-payload IK cores (``SequencedIKCore``, the pipelined ``IKCore``).

The board's frame decoder and encoder speak 32-bit words in the order of the pose and joints
frames (docs/protocol.md), as ``SerialIK`` with 32-bit beats does; :class:`WordCore` gives a
struct core the same ports.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Module, Mux, Signal, Value
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from ik5r.core import link as L

from ..datapath.expr import select

__all__ = ["WordCore", "POSE_WORD_FIELDS"]

#: The pose frame's words by IK core payload field (the flags word last).
POSE_WORD_FIELDS = ("px", "py", "pz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz", "q5_default")


class WordCore(wiring.Component):
    """A struct-payload IK core behind word streams.

    Function: 14 words on ``i`` (px..oz, q5_default, flags = has_roll | shoulder_back << 1 |
    elbow_down << 2 | tag << 3) fill the core's input payload, which is offered once complete;
    each result leaves on ``o`` as 6 words: q1..q5 (the core's words, zero-extended to 32 bits),
    then status | tag << S (S status bits: 6, 7 for an arm with limits). Formats: 32-bit words. Latency: the core's plus 2 clocks in and
    one per word out. Throughput: one pose per 14 clocks in and 6 out at most, and the core's.
    """

    def __init__(self, *, core):
        if not hasattr(core, "i") or not hasattr(core, "o") or getattr(core, "tag_width", 0) < 8:
            raise ValueError("core must be an IK core component with tag_width >= 8")
        self.core = core
        super().__init__({"i": In(stream.Signature(32)), "o": Out(stream.Signature(32))})

    def elaborate(self, platform):
        m = Module()
        m.submodules.core = core = self.core
        pose = Signal(core.i.payload.shape())
        count = Signal(range(L.POSE_WORDS))
        full = Signal()
        word = self.i.payload
        m.d.comb += [self.i.ready.eq(~full), core.i.payload.eq(pose), core.i.valid.eq(full)]
        with m.If(self.i.valid & ~full):
            for j, name in enumerate(POSE_WORD_FIELDS):
                field = getattr(pose, name)
                with m.If(count == j):
                    m.d.sync += field.eq(word[:len(Value.cast(field))])
            with m.If(count == L.POSE_WORDS - 1):
                m.d.sync += [pose.has_roll.eq(word[0]), pose.shoulder_back.eq(word[1]),
                             pose.elbow_down.eq(word[2]), pose.tag.eq(word[3:11]), full.eq(1)]
            m.d.sync += count.eq(Mux(count == L.POSE_WORDS - 1, 0, count + 1))
        with m.If(core.i.valid & core.i.ready):
            m.d.sync += full.eq(0)
        out = core.o.payload
        words = [Value.cast(getattr(out, f"q{j + 1}")).as_unsigned() for j in range(5)]
        words.append(Cat(Value.cast(out.status), Value.cast(out.tag)[:8]))
        index = Signal(range(L.JOINT_WORDS))
        last = index == L.JOINT_WORDS - 1
        m.d.comb += [self.o.valid.eq(core.o.valid), self.o.payload.eq(select(words, index)),
                     core.o.ready.eq(self.o.ready & last)]
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += index.eq(Mux(last, 0, index + 1))
        return m
