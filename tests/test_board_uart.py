"""The board's UART at a fractional clock/baud ratio (ULX3S: 25 MHz / 3 Mbaud = 8 1/3 clocks a
bit), against an ideal line: received bytes from exact bit times, sent bits within a clock of them."""

from __future__ import annotations

import random

from amaranth.sim import Simulator

from ik5r.hdl.board.uart import UartRx, UartTx

CLOCK, BAUD = 25_000_000, 3_000_000


def _line(data: bytes, clocks: int, start: int = 5):
    """The ideal rx level at each clock for ``data`` sent back to back from clock ``start``."""
    levels = [1] * clocks
    per_bit = CLOCK / BAUD
    for i, byte in enumerate(data):
        bits = [0] + [(byte >> b) & 1 for b in range(8)] + [1]
        for j, bit in enumerate(bits):
            lo = int(start + (10 * i + j) * per_bit + 0.999)
            hi = int(start + (10 * i + j + 1) * per_bit + 0.999)
            for c in range(lo, min(hi, clocks)):
                levels[c] = bit
    return levels


def test_receiver_at_a_fractional_ratio():
    data = bytes(random.Random(1).randrange(256) for _ in range(40)) + b"\x00\xff\xa5"
    clocks = int(len(data) * 10 * CLOCK / BAUD) + 40
    levels = _line(data, clocks)
    rx = UartRx(clock_hz=CLOCK, baud=BAUD)
    got = []

    async def bench(ctx):
        ctx.set(rx.o.ready, 1)
        for level in levels:
            ctx.set(rx.rx, level)
            await ctx.tick()
            if ctx.get(rx.o.valid):
                got.append(ctx.get(rx.o.payload))
            assert not ctx.get(rx.framing) and not ctx.get(rx.overrun)

    sim = Simulator(rx)
    sim.add_clock(1 / CLOCK)
    sim.add_testbench(bench)
    sim.run()
    assert bytes(got) == data


def test_transmitter_bit_edges_within_a_clock():
    data = bytes(random.Random(2).randrange(256) for _ in range(20))
    tx = UartTx(clock_hz=CLOCK, baud=BAUD)
    trace = []

    async def bench(ctx):
        ctx.set(tx.i.valid, 1)
        sent = 0
        for _ in range(int(len(data) * 10 * CLOCK / BAUD) + 60):
            ctx.set(tx.i.payload, data[min(sent, len(data) - 1)])
            ctx.set(tx.i.valid, sent < len(data))
            taken = ctx.get(tx.i.valid) and ctx.get(tx.i.ready)
            await ctx.tick()
            sent += taken
            trace.append(ctx.get(tx.tx))

    sim = Simulator(tx)
    sim.add_clock(1 / CLOCK)
    sim.add_testbench(bench)
    sim.run()
    start = trace.index(0)
    expected = _line(data, len(trace), start=start)
    edges = [c for c in range(1, len(trace)) if trace[c] != trace[c - 1]]
    ideal = [c for c in range(1, len(expected)) if expected[c] != expected[c - 1]]
    assert len(edges) == len(ideal) and max(abs(a - b) for a, b in zip(edges, ideal)) <= 1
