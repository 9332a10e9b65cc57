"""The board's frame encoder: joints from the IK core, replies from the decoder, bytes out.

The frame format is :mod:`ik5r.core.link` (docs/protocol.md), the reference model of this
encoder in the tests.
"""

from __future__ import annotations

from types import SimpleNamespace

from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from ik5r.core import link as L

from ..datapath.expr import select
from .decoder import REPLY_ID, REPLY_LAYOUT, crc16_byte

__all__ = ["FrameEncoder", "STATUS_BITS"]

#: Status bits of the core's last result word (below the tag).
STATUS_BITS = 6


class FrameEncoder(wiring.Component):
    """Frame encoder.

    Function: collects the IK core's 6 result words of a pose from ``results`` (q1..q5: the low
    ``word_bits`` bits, signed; then status | tag << ``status_bits``) and sends a joints frame (q words sign-
    extended to 32 bits, status word, the tag in the header); sends an ID frame (payload
    ``id_words``) after reset and for each ID reply on ``reply``, an error frame (the code as its
    one word) for each error reply. Priority: ID after reset, replies, then joints. Formats:
    ``results`` 32-bit words, ``reply`` :data:`~.decoder.REPLY_LAYOUT`, ``o`` bytes.
    Latency: the sync byte is on ``o`` the clock after the sixth result word. Throughput: one byte
    a clock when ``o`` takes them; ``results`` waits while a joints frame is held.
    ``sent_error``: a pulse per error frame sent.
    """

    def __init__(self, *, word_bits: int, id_words, status_bits: int = STATUS_BITS):
        if isinstance(word_bits, bool) or not isinstance(word_bits, int) or not 8 <= word_bits <= 32:
            raise ValueError(f"word_bits must be an integer in [8, 32], got {word_bits!r}")
        id_words = [int(w) for w in id_words]
        if len(id_words) != len(L.ID_FIELDS) or not all(0 <= w < 1 << 32 for w in id_words):
            raise ValueError(f"id_words: need {len(L.ID_FIELDS)} unsigned 32-bit words, got {id_words!r}")
        self.word_bits, self.id_words = word_bits, id_words
        # 7 for an arm with limits (OUT_OF_LIMITS, ik5r.core.fxconfig.Constants.status_width)
        self.status_bits = status_bits
        super().__init__({"results": In(stream.Signature(32)), "reply": In(stream.Signature(REPLY_LAYOUT)),
                          "o": Out(stream.Signature(8)), "sent_error": Out(1)})

    def _collect(self, m, joints, tag, full, done):
        """The result words into ``joints`` (a memory: block RAM, not 192 flip-flops)."""
        count = Signal(range(L.JOINT_WORDS))
        word = self.results.payload
        last = count == L.JOINT_WORDS - 1
        extended = Cat(word[:self.word_bits], word[self.word_bits - 1].replicate(32 - self.word_bits))
        write = joints.write_port()
        m.d.comb += [self.results.ready.eq(~full), write.addr.eq(count),
                     write.data.eq(Mux(last, word[:self.status_bits], extended)),
                     write.en.eq(self.results.valid & ~full)]
        with m.If(self.results.valid & ~full):
            m.d.sync += count.eq(Mux(last, 0, count + 1))
            with m.If(last):
                m.d.sync += [full.eq(1), tag.eq(word[self.status_bits:self.status_bits + 8])]
        with m.If(done):
            m.d.sync += full.eq(0)

    def elaborate(self, platform):
        m = Module()
        m.submodules.joints = joints = Memory(shape=32, depth=8, init=[])
        r = SimpleNamespace(joint_tag=Signal(8), full=Signal(), done=Signal(), boot=Signal(init=1),
                            kind=Signal(8), tag=Signal(8), length=Signal(8), code=Signal(8), crc=Signal(16),
                            index=Signal(range(4 * 256)),   # payload byte
                            out=Signal(8), crc_next=Signal(16), advance=Signal())
        self._collect(m, joints, r.joint_tag, r.full, r.done)
        r.joint_word = joints.read_port()
        r.sending = self.o.valid & self.o.ready
        m.d.comb += self.o.payload.eq(r.out)
        # Read a clock ahead: the word of the payload byte after this clock's transfer
        # (``advance``: a payload byte leaves this clock).
        m.d.comb += r.joint_word.addr.eq((r.index + r.advance)[2:])
        # One CRC network on the byte going out, whatever the state.
        m.d.comb += r.crc_next.eq(crc16_byte(r.crc, r.out))
        with m.FSM():
            with m.State("IDLE"):
                self._start(m, r)
            for state, value, state_next, add_crc in (("SYNC", L.SYNC, "TYPE", False), ("TYPE", r.kind, "LENGTH", True),
                                                      ("LENGTH", r.length, "TAG", True), ("TAG", r.tag, "PAYLOAD", True)):
                with m.State(state):
                    self._emit(m, r, value, state_next, add_crc)
            with m.State("PAYLOAD"):
                self._payload(m, r)
            with m.State("CRC_HI"):
                self._emit(m, r, r.crc[8:], "CRC_LO", False)
            with m.State("CRC_LO"):
                self._emit(m, r, r.crc[:8], "IDLE", False)
                with m.If(r.sending & (r.kind == L.JOINTS)):
                    m.d.comb += r.done.eq(1)
        return m

    def _emit(self, m, r, value, state_next, add_crc):
        m.d.comb += [self.o.valid.eq(1), r.out.eq(value)]
        with m.If(r.sending):
            if add_crc:
                m.d.sync += r.crc.eq(r.crc_next)
            m.next = state_next

    def _start(self, m, r):
        """Which frame next: the ID after reset, a reply, or the joints of a result."""
        m.d.sync += [r.crc.eq(0xFFFF), r.index.eq(0)]
        with m.If(r.boot):
            m.d.sync += [r.boot.eq(0), r.kind.eq(L.ID), r.tag.eq(0), r.length.eq(len(self.id_words))]
            m.next = "SYNC"
        with m.Elif(self.reply.valid):
            m.d.comb += self.reply.ready.eq(1)
            is_id = self.reply.payload.kind == REPLY_ID
            m.d.sync += [r.kind.eq(Mux(is_id, L.ID, L.ERROR)), r.tag.eq(self.reply.payload.tag),
                         r.code.eq(self.reply.payload.code), r.length.eq(Mux(is_id, len(self.id_words), 1))]
            m.d.comb += self.sent_error.eq(~is_id)
            m.next = "SYNC"
        with m.Elif(r.full):
            m.d.sync += [r.kind.eq(L.JOINTS), r.tag.eq(r.joint_tag), r.length.eq(L.JOINT_WORDS)]
            m.next = "SYNC"

    def _payload(self, m, r):
        id_bytes = [Const((w >> (8 * b)) & 0xFF, 8) for w in self.id_words for b in range(4)]
        value = Signal(8)
        with m.Switch(r.kind):
            with m.Case(L.ID):
                m.d.comb += value.eq(select(id_bytes, r.index))
            with m.Case(L.ERROR):
                m.d.comb += value.eq(Mux(r.index == 0, r.code, 0))
            with m.Default():
                m.d.comb += value.eq(r.joint_word.data.word_select(r.index[:2], 8))
        self._emit(m, r, value, "PAYLOAD", True)
        m.d.comb += r.advance.eq(r.sending)
        with m.If(r.sending):
            m.d.sync += r.index.eq(r.index + 1)
            with m.If(r.index == 4 * r.length - 1):
                m.next = "CRC_HI"
