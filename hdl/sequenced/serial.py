"""The sequenced IK engine (:class:`.engine.SeqEngine`) with a narrow word-serial stream on each
side: :class:`SerialIK`, for small FPGAs with few pins (the iCE40 UP5K's SG48 package)."""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Module, Mux, Signal, unsigned
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import CoreArch, Dsp

from ..datapath.expr import select
from ..graph.inputs import INPUT_WORDS
from .engine import SeqEngine, check_tag, check_wide

__all__ = ["SerialIK"]


class SerialIK(wiring.Component):
    """The sequenced IK engine with a narrow word-serial stream on each side, for small FPGAs.

    ``i``: per pose 14 words, each sent as ``ceil(max(W, 3 + tag_width) / beat_bits)`` beats of
    ``beat_bits`` bits, least significant beat first: px, py, pz, ax, ay, az, nx, ny, nz, ox, oy,
    oz, q5_default (signed words as in ``IKCore``), then the flags word has_roll |
    shoulder_back << 1 | elbow_down << 2 | tag << 3. ``o``: per pose 6 words,
    ``ceil(max(W, 6 + tag_width) / beat_bits)`` beats each: q1..q5, then status | tag << 6.
    Function: ``model.ik_solve`` bit for bit. Throughput: one pose per
    ``cycles_per_result`` clocks when beats come and go every clock; one pose in flight.
    """

    def __init__(self, *, constants: Constants, tag_width: int = 0, beat_bits: int = 16,
                 wide_product: bool = False, dsp: str = Dsp.GENERIC):
        check_tag(tag_width, 26)
        check_wide(wide_product)
        if isinstance(beat_bits, bool) or not isinstance(beat_bits, int) or not 1 <= beat_bits <= 32:
            raise ValueError(f"beat_bits must be an integer in [1, 32], got {beat_bits!r}")
        self._engine = e = SeqEngine(constants=constants, tag_width=tag_width, wide_product=wide_product, dsp=dsp)
        self.constants, self.tag_width, self.beat_bits = constants, tag_width, beat_bits
        self.arch = CoreArch.COMPACT
        self.in_beats = -(-e.in_bits // beat_bits)
        self.out_beats = -(-e.out_bits // beat_bits)
        # Each input word waits for its beats, except the first: its beats arrive while the
        # previous pose is computed. Each output word holds the engine for its beats.
        self.latency = e.cycles + (len(INPUT_WORDS) + 1) * (self.in_beats - 1) + 6 * (self.out_beats - 1)
        self.cycles_per_result = self.latency - (self.in_beats - 1)
        self.capacity = 1
        self.options = {"serial": beat_bits} | ({"wide_product": True} if wide_product else {}) \
            | ({"dsp": e.dsp} if e.dsp != Dsp.GENERIC else {})
        self.in_fields = {"beat": (unsigned(beat_bits), None, "input word beat, LSB first")}
        self.out_fields = {"beat": (unsigned(beat_bits), None, "output word beat, LSB first")}
        super().__init__({
            "i": In(stream.Signature(unsigned(beat_bits))),
            "o": Out(stream.Signature(unsigned(beat_bits))),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.engine = e = self._engine
        b = self.beat_bits
        # Input: beats into a shift register; the word is offered to the engine once complete,
        # and the next word's first beat may arrive in the clock the engine takes it.
        word = Signal(self.in_beats * b)
        count = Signal(range(self.in_beats))
        have = Signal()
        m.d.comb += [self.i.ready.eq(~have | e.in_take), e.in_valid.eq(have),
                     e.in_data.eq(word[:e.in_bits])]
        with m.If(e.in_take):
            m.d.sync += have.eq(0)
        with m.If(self.i.valid & self.i.ready):
            m.d.sync += word.eq(Cat(word[b:], self.i.payload))
            with m.If(count == self.in_beats - 1):
                m.d.sync += [count.eq(0), have.eq(1)]
            with m.Else():
                m.d.sync += count.eq(count + 1)
        # Output: the engine holds its word while the beats leave; it moves on after the last.
        out_count = Signal(range(self.out_beats))
        padded = Cat(e.out_data, Const(0, self.out_beats * b - e.out_bits))
        last = out_count == self.out_beats - 1
        m.d.comb += [self.o.valid.eq(e.out_valid), e.out_ready.eq(self.o.ready & last),
                     self.o.payload.eq(select([padded[j * b:(j + 1) * b] for j in range(self.out_beats)],
                                              out_count))]
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += out_count.eq(Mux(last, 0, out_count + 1))
        return m
