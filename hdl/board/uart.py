"""UART receiver and transmitter (8 data bits, no parity, 1 stop bit) at any clock/baud ratio.

The bit clock is a fractional divider: an accumulator adds ``baud / g`` every clock and a bit
boundary falls where it passes ``clock / g`` (g their gcd), so 25 MHz / 3 Mbaud (8 1/3 clocks a
bit) is exact on average and never more than one clock off.
"""

from __future__ import annotations

from math import gcd

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

__all__ = ["UartRx", "UartTx", "divider"]

#: The fewest clocks a bit the receiver is made for (it samples mid-bit, +-1 clock).
MIN_CLOCKS_PER_BIT = 4


def divider(clock_hz, baud) -> tuple[int, int]:
    """(step, modulus) of the bit clock; ValueError for a ratio the receiver is not made for."""
    for name, value in (("clock_hz", clock_hz), ("baud", baud)):
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    if clock_hz < MIN_CLOCKS_PER_BIT * baud:
        raise ValueError(f"clock {clock_hz} Hz is under {MIN_CLOCKS_PER_BIT} clocks a bit at {baud} baud")
    g = gcd(clock_hz, baud)
    return baud // g, clock_hz // g


class UartTx(wiring.Component):
    """UART transmitter.

    Function: each byte of ``i`` leaves on ``tx`` as a start bit, 8 data bits LSB first and a
    stop bit; ``tx`` idles high. Formats: ``i.payload`` 8 bits. Latency: the start bit begins the
    clock after the transfer. Throughput: one byte per 10 bit times, back to back
    (``i.ready`` is high in the last clock of a stop bit). ``busy``: a byte is on the line.
    """

    def __init__(self, *, clock_hz: int, baud: int):
        self.step, self.modulus = divider(clock_hz, baud)
        super().__init__({"i": In(stream.Signature(8)), "tx": Out(1, init=1), "busy": Out(1)})

    def elaborate(self, platform):
        m = Module()
        acc = Signal(range(self.modulus + self.step))
        shift = Signal(10, init=0x3FF)
        left = Signal(range(11))
        boundary = acc + self.step >= self.modulus
        m.d.comb += [self.busy.eq(left != 0), self.i.ready.eq((left == 0) | ((left == 1) & boundary))]
        m.d.sync += self.tx.eq(shift[0])
        with m.If(self.i.valid & self.i.ready):
            # Loaded on the last boundary of the previous byte, the divider keeps its phase.
            m.d.sync += [shift.eq(Cat(0, self.i.payload, 1)), left.eq(10),
                         acc.eq(Mux(left != 0, acc + self.step - self.modulus, 0))]
        with m.Elif(left != 0):
            with m.If(boundary):
                m.d.sync += [acc.eq(acc + self.step - self.modulus), shift.eq(Cat(shift[1:], 1)),
                             left.eq(left - 1)]
            with m.Else():
                m.d.sync += acc.eq(acc + self.step)
        return m


class UartRx(wiring.Component):
    """UART receiver.

    Function: ``rx`` (two flip-flops of synchroniser) is sampled in the middle of each bit after a
    falling edge; a byte whose start bit reads high is ignored (a glitch), one whose stop bit
    reads low is dropped with a ``framing`` pulse. Formats: ``o.payload`` 8 bits. Latency: the
    byte is on ``o`` about half a bit after its stop bit began. Throughput: one byte per 10 bit
    times; the receiver cannot wait, so a byte not taken before the next one arrives is lost
    with an ``overrun`` pulse (put a FIFO behind it).
    """

    def __init__(self, *, clock_hz: int, baud: int):
        self.step, self.modulus = divider(clock_hz, baud)
        super().__init__({"rx": In(1, init=1), "o": Out(stream.Signature(8)), "framing": Out(1),
                          "overrun": Out(1), "busy": Out(1)})

    def elaborate(self, platform):
        m = Module()
        sync = Signal(2, init=0b11)
        last = Signal(init=1)
        m.d.sync += [sync.eq(Cat(self.rx, sync[0])), last.eq(sync[1])]
        line = sync[1]
        acc = Signal(range(self.modulus + self.step))
        bits = Signal(10)
        count = Signal(range(11))
        m.d.comb += self.busy.eq(count != 0)
        m.d.sync += [self.framing.eq(0), self.overrun.eq(0)]
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += self.o.valid.eq(0)
        with m.If(count == 0):
            with m.If(last & ~line):  # falling edge: the first sample half a bit later
                m.d.sync += [count.eq(10), acc.eq(self.modulus // 2)]
        with m.Elif(acc + self.step >= self.modulus):
            m.d.sync += [acc.eq(acc + self.step - self.modulus), bits.eq(Cat(bits[1:], line)),
                         count.eq(count - 1)]
            with m.If((count == 10) & line):
                m.d.sync += count.eq(0)      # the start bit reads high: a glitch
            with m.If(count == 1):
                with m.If(line):
                    m.d.sync += [self.o.payload.eq(bits[2:10]), self.o.valid.eq(1),
                                 self.overrun.eq(self.o.valid & ~self.o.ready)]
                with m.Else():
                    m.d.sync += self.framing.eq(1)
        with m.Else():
            m.d.sync += acc.eq(acc + self.step)
        return m
