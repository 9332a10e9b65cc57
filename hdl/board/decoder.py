"""The board's frame decoder: bytes from the UART in, pose words to the IK core and replies out.

The frame format and its codes are :mod:`ik5r.core.link` (docs/protocol.md), which is also the
reference model of this decoder in the tests.
"""

from __future__ import annotations

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
        kind, length, tag = Signal(8), Signal(8), Signal(8)
        crc = Signal(16)
        word = Signal(24)             # the bytes of the current word before its last one
        count = Signal(range(4 * 256 + 1))   # payload bytes received
        index = Signal(range(16))     # words sent on o
        idle = Signal(range(self.timeout + 1))
        lost = Signal()               # a receive overflow not yet reported
        code = Signal(8)
        byte = self.i.payload
        take = self.i.valid & self.i.ready
        crc_next = Signal(16)      # one CRC network, used in every state that receives
        m.d.comb += crc_next.eq(crc16_byte(crc, byte))
        with m.If(self.overflow):
            m.d.sync += lost.eq(1)
        last_word = index == L.POSE_WORDS - 1
        sent = self.o.valid & self.o.ready
        m.d.comb += [rd.addr.eq(index + sent), wr.addr.eq(count[2:]), wr.data.eq(Cat(word, byte))]
        flags = Cat(rd.data[:FLAG_BITS], tag)
        m.d.comb += self.o.payload.eq(rd.data)
        with m.If(last_word):
            m.d.comb += self.o.payload.eq(flags)
        m.d.comb += [self.reply.payload.tag.eq(tag), self.reply.payload.code.eq(code)]

        def fail(error):
            m.d.sync += code.eq(error)
            m.next = "ERROR"

        def receiving(state_next):
            """A byte of a frame: the timeout runs while none comes."""
            m.d.comb += self.i.ready.eq(1)
            with m.If(take):
                m.d.sync += [crc.eq(crc_next), idle.eq(0)]
                m.next = state_next
            with m.Elif(idle == self.timeout):
                fail(L.E_TIMEOUT)
            with m.Else():
                m.d.sync += idle.eq(idle + 1)

        with m.FSM():
            with m.State("HUNT"):
                m.d.sync += [crc.eq(0xFFFF), idle.eq(0), tag.eq(0), count.eq(0), index.eq(0)]
                with m.If(lost):
                    m.d.sync += lost.eq(0)
                    fail(L.E_OVERFLOW)
                with m.Else():
                    m.d.comb += self.i.ready.eq(1)
                    with m.If(take & (byte == L.SYNC)):
                        m.next = "TYPE"
            with m.State("TYPE"):
                receiving("LENGTH")
                with m.If(take):
                    m.d.sync += kind.eq(byte)
            with m.State("LENGTH"):
                receiving("TAG")
                with m.If(take):
                    m.d.sync += length.eq(byte)
            with m.State("TAG"):
                receiving("TAG")
                with m.If(take):
                    m.d.sync += tag.eq(byte)
                    self._check_header(m, kind, length, fail)
            with m.State("PAYLOAD"):
                receiving("PAYLOAD")
                with m.If(take):
                    m.d.sync += [count.eq(count + 1), word.eq(Cat(word[8:], byte))]
                    m.d.comb += wr.en.eq(count[:2] == 3)
                    with m.If(count == 4 * length - 1):
                        m.next = "CRC_HI"
            with m.State("CRC_HI"):
                receiving("CRC_LO")
            with m.State("CRC_LO"):
                receiving("CHECK")
            with m.State("CHECK"):
                with m.If(crc != 0):
                    fail(L.E_CRC)
                with m.Elif(kind == L.ID):
                    m.d.sync += code.eq(0)
                    m.next = "ID"
                with m.Else():
                    m.next = "WORDS"
            with m.State("WORDS"):
                m.d.comb += self.o.valid.eq(1)
                with m.If(sent):
                    m.d.sync += index.eq(index + 1)
                    with m.If(last_word):
                        m.next = "HUNT"
            with m.State("ERROR"):
                m.d.comb += [self.reply.valid.eq(1), self.reply.payload.kind.eq(REPLY_ERROR)]
                with m.If(self.reply.ready):
                    m.next = "HUNT"
            with m.State("ID"):
                m.d.comb += [self.reply.valid.eq(1), self.reply.payload.kind.eq(REPLY_ID)]
                with m.If(self.reply.ready):
                    m.next = "HUNT"
        return m

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
