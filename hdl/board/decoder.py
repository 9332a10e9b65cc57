"""The board's frame decoder: bytes from the UART in, pose words to the IK core and replies out.

The frame format and its codes are :mod:`ik5r.core.link` (docs/protocol.md), which is also the
reference model of this decoder in the tests.
"""

from __future__ import annotations

from types import SimpleNamespace

from amaranth.hdl import Cat, Const, Module, Signal, Value
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from ik5r.core import link as L

__all__ = ["FrameDecoder", "REPLY_LAYOUT", "REPLY_ERROR", "REPLY_ID", "crc16_byte"]

#: A reply the encoder owes the host: an error frame (code, tag) or an ID frame (tag).
REPLY_ERROR, REPLY_ID = 0, 1
REPLY_LAYOUT = data.StructLayout({"kind": 1, "code": 8, "tag": 8})
#: Bits the flags word carries below the tag (has_roll, shoulder_back, elbow_down).
FLAG_BITS = 3


def _crc_terms() -> list[tuple[list[int], list[int]]]:
    """Per bit of the next CRC register: the bits of the CRC and of the byte XORed into it
    (the CRC is linear over GF(2); each bit a bit mask of the 24 inputs)."""
    state = [1 << (8 + i) for i in range(16)]          # crc bit i: input 8 + i
    for i in range(8):
        state[8 + i] ^= 1 << i                           # byte bit i: input i
    for _ in range(8):
        top = state[15]
        state = [0] + state[:15]
        for bit in range(16):
            if (0x1021 >> bit) & 1:
                state[bit] ^= top
    return [([j - 8 for j in range(8, 24) if mask >> j & 1], [j for j in range(8) if mask >> j & 1])
            for mask in state]


_CRC_TERMS = _crc_terms()


def crc16_byte(crc: Value, byte: Value) -> Value:
    """CRC-16/CCITT-FALSE register after one more byte, MSB first (an XOR per bit)."""
    crc, byte = Value.cast(crc), Value.cast(byte)
    bits = []
    for crc_bits, byte_bits in _CRC_TERMS:
        bits.append(Cat(*(crc[j] for j in crc_bits), *(byte[j] for j in byte_bits)).xor())
    return Cat(*bits)


class FrameDecoder(wiring.Component):
    """Frame decoder (CRC check, resynchronisation, timeout).

    Function: hunts for the sync byte, reads type, length, tag, payload and CRC. A pose frame
    (14 words) whose CRC checks is sent on ``o`` as 14 words, the flags word with the frame's tag
    in bits 3..10 (the IK core carries it to its result); an ID request (no payload) becomes an
    ID reply on ``reply``. A frame of another type or length (known after the tag byte), a CRC
    that fails, a frame whose next byte does not come within ``timeout`` clocks, or a receive
    overflow (``overflow`` pulse) becomes an error reply (:data:`ik5r.core.link.ERROR_NAMES`);
    the decoder then hunts for the next sync byte. Formats: ``i`` bytes, ``o`` 32-bit words,
    ``reply`` :data:`REPLY_LAYOUT`. Latency: the first word is on ``o`` 3 clocks after the last
    CRC byte is taken. Throughput: one byte a clock while receiving; the words leave at the
    pace ``o`` takes them, meanwhile ``i`` waits (the FIFO in front holds the next frames).
    """

    def __init__(self, *, timeout: int):
        if isinstance(timeout, bool) or not isinstance(timeout, int) or timeout < 16:
            raise ValueError(f"timeout must be an integer >= 16 clocks, got {timeout!r}")
        self.timeout = timeout
        super().__init__({"i": In(stream.Signature(8)), "o": Out(stream.Signature(32)),
                          "reply": Out(stream.Signature(REPLY_LAYOUT)), "overflow": In(1)})

    def elaborate(self, platform):
        m = Module()
        m.submodules.words = mem = Memory(shape=32, depth=16, init=[])
        wr, rd = mem.write_port(), mem.read_port()
        r = SimpleNamespace(
            kind=Signal(8), length=Signal(8), tag=Signal(8), code=Signal(8), crc=Signal(16),
            word=Signal(24),                     # the bytes of the current word before its last one
            count=Signal(range(4 * 256 + 1)),    # payload bytes received
            index=Signal(range(16)),             # words sent on o
            idle=Signal(range(self.timeout + 1)),
            lost=Signal(),                       # a receive overflow not yet reported
            crc_next=Signal(16),                 # one CRC network, used in every state that receives
            byte=self.i.payload, take=self.i.valid & self.i.ready, wr=wr)
        m.d.comb += r.crc_next.eq(crc16_byte(r.crc, r.byte))
        with m.If(self.overflow):
            m.d.sync += r.lost.eq(1)
        r.sent = self.o.valid & self.o.ready
        r.last_word = r.index == L.POSE_WORDS - 1
        m.d.comb += [rd.addr.eq(r.index + r.sent), wr.addr.eq(r.count[2:]), wr.data.eq(Cat(r.word, r.byte))]
        m.d.comb += self.o.payload.eq(rd.data)
        with m.If(r.last_word):
            m.d.comb += self.o.payload.eq(Cat(rd.data[:FLAG_BITS], r.tag))
        m.d.comb += [self.reply.payload.tag.eq(r.tag), self.reply.payload.code.eq(r.code)]
        with m.FSM():
            self._receive_states(m, r)
            self._answer_states(m, r)
        return m

    def _fail(self, m, r, error):
        m.d.sync += r.code.eq(error)
        m.next = "ERROR"

    def _receiving(self, m, r, state_next):
        """A byte of a frame: the timeout runs while none comes."""
        m.d.comb += self.i.ready.eq(1)
        with m.If(r.take):
            m.d.sync += [r.crc.eq(r.crc_next), r.idle.eq(0)]
            m.next = state_next
        with m.Elif(r.idle == self.timeout):
            self._fail(m, r, L.E_TIMEOUT)
        with m.Else():
            m.d.sync += r.idle.eq(r.idle + 1)

    def _receive_states(self, m, r):
        with m.State("HUNT"):
            m.d.sync += [r.crc.eq(0xFFFF), r.idle.eq(0), r.tag.eq(0), r.count.eq(0), r.index.eq(0)]
            with m.If(r.lost):
                m.d.sync += r.lost.eq(0)
                self._fail(m, r, L.E_OVERFLOW)
            with m.Else():
                m.d.comb += self.i.ready.eq(1)
                with m.If(r.take & (r.byte == L.SYNC)):
                    m.next = "TYPE"
        for state, state_next, field in (("TYPE", "LENGTH", r.kind), ("LENGTH", "TAG", r.length)):
            with m.State(state):
                self._receiving(m, r, state_next)
                with m.If(r.take):
                    m.d.sync += field.eq(r.byte)
        with m.State("TAG"):
            self._receiving(m, r, "TAG")
            with m.If(r.take):
                m.d.sync += r.tag.eq(r.byte)
                self._check_header(m, r.kind, r.length, lambda error: self._fail(m, r, error))
        with m.State("PAYLOAD"):
            self._receiving(m, r, "PAYLOAD")
            with m.If(r.take):
                m.d.sync += [r.count.eq(r.count + 1), r.word.eq(Cat(r.word[8:], r.byte))]
                m.d.comb += r.wr.en.eq(r.count[:2] == 3)
                with m.If(r.count == 4 * r.length - 1):
                    m.next = "CRC_HI"
        with m.State("CRC_HI"):
            self._receiving(m, r, "CRC_LO")
        with m.State("CRC_LO"):
            self._receiving(m, r, "CHECK")

    def _answer_states(self, m, r):
        with m.State("CHECK"):
            with m.If(r.crc != 0):
                self._fail(m, r, L.E_CRC)
            with m.Elif(r.kind == L.ID):
                m.d.sync += r.code.eq(0)
                m.next = "ID"
            with m.Else():
                m.next = "WORDS"
        with m.State("WORDS"):
            m.d.comb += self.o.valid.eq(1)
            with m.If(r.sent):
                m.d.sync += r.index.eq(r.index + 1)
                with m.If(r.last_word):
                    m.next = "HUNT"
        for state, kind in (("ERROR", REPLY_ERROR), ("ID", REPLY_ID)):
            with m.State(state):
                m.d.comb += [self.reply.valid.eq(1), self.reply.payload.kind.eq(kind)]
                with m.If(self.reply.ready):
                    m.next = "HUNT"

    @staticmethod
    def _check_header(m, kind, length, fail):
        """After the tag byte: a pose needs 14 words, an ID request none; other types are errors."""
        with m.If(kind == L.POSE):
            with m.If(length == L.POSE_WORDS):
                m.next = "PAYLOAD"
            with m.Else():
                fail(L.E_LENGTH)
        with m.Elif(kind == L.ID):
            with m.If(length == 0):
                m.next = "CRC_HI"
            with m.Else():
                fail(L.E_LENGTH)
        with m.Else():
            fail(L.E_TYPE)
