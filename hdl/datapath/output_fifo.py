"""The output FIFO of a pipelined build: a buffered synchronous FIFO for a writer that never
overflows it (the build's credits bound its fill, a proved invariant), so that no write waits on
the FIFO's fill level."""

from __future__ import annotations

from amaranth.hdl import Assert, Assume, Elaboratable, Module, Signal
from amaranth.hdl._ast import Initial
from amaranth.lib.fifo import FIFOInterface
from amaranth.lib.memory import Memory

__all__ = ["CreditFifo"]


class CreditFifo(Elaboratable, FIFOInterface):
    """A first-in first-out queue of ``depth`` items of ``width`` bits (``2 ** n + 1``: a RAM of
    ``2 ** n`` entries, whose pointers wrap for free, and an output register), for a writer that
    holds credits: it writes only while ``w_rdy`` (not full), and the FIFO does not check.

    Why not ``SyncFIFOBuffered``: it gates every write with ``w_rdy`` (its fill level compared
    with its depth), so the level counter fed itself through the write enable of every block RAM
    of a wide FIFO, a loop spread over the RAMs' rows: the slowest path of the pipelined IK
    core. Here the write enable is the writer's own, the RAM's read enable comes from a
    registered "RAM not empty" flag, and the level counter only feeds that flag.

    Interface: :class:`~amaranth.lib.fifo.FIFOInterface` (``w_rdy`` is a status the writer must
    respect; ``level`` counts the items in the RAM and the output register). Latency: an item
    written to an empty FIFO is on ``r_data`` (``r_rdy``) two cycles later, as in
    ``SyncFIFOBuffered``; one item per cycle in and out. On the ``"formal"`` platform the
    pointers' invariants are asserted (as ``SyncFIFOBuffered`` asserts its own), for the
    inductions of :mod:`ik5r.hdl.formal`.
    """

    def __init__(self, *, width: int, depth: int):
        if not isinstance(depth, int) or depth < 2 or (depth - 1) & (depth - 2):
            self._MustUse__silence = True   # never built: no "created but never used" warning
            raise ValueError(f"depth must be 2 ** n + 1 (n >= 0), got {depth!r}")
        super().__init__(width=width, depth=depth)
        self.level = Signal(range(depth + 1))

    def elaborate(self, platform):
        m = Module()
        inner_depth = self.depth - 1
        inner_level = Signal(range(inner_depth + 1))
        # Registered (inner_level != 0): the RAM's read enable leaves a flip-flop.
        inner_r_rdy = Signal()
        do_write = self.w_en
        do_inner_read = inner_r_rdy & (~self.r_rdy | self.r_en)
        storage = m.submodules.storage = Memory(shape=self.width, depth=inner_depth, init=[])
        w_port, r_port = storage.write_port(), storage.read_port(domain="sync")
        produce = Signal(range(inner_depth))
        consume = Signal(range(inner_depth))
        m.d.comb += [
            self.w_rdy.eq(inner_level != inner_depth),
            self.level.eq(inner_level + self.r_rdy),
            self.w_level.eq(self.level),
            self.r_level.eq(self.level),
            w_port.addr.eq(produce), w_port.data.eq(self.w_data), w_port.en.eq(do_write),
            r_port.addr.eq(consume), r_port.en.eq(do_inner_read), self.r_data.eq(r_port.data),
        ]
        with m.If(do_write):
            m.d.sync += [produce.eq(produce + 1), inner_r_rdy.eq(1)]
        with m.Elif(do_inner_read):
            m.d.sync += inner_r_rdy.eq(inner_level != 1)
        with m.If(do_inner_read):
            m.d.sync += consume.eq(consume + 1)
        with m.If(do_write & ~do_inner_read):
            m.d.sync += inner_level.eq(inner_level + 1)
        with m.Elif(do_inner_read & ~do_write):
            m.d.sync += inner_level.eq(inner_level - 1)
        with m.If(do_inner_read):
            m.d.sync += self.r_rdy.eq(1)
        with m.Elif(self.r_en):
            m.d.sync += self.r_rdy.eq(0)
        if platform == "formal":
            self._invariants(m, inner_level, inner_r_rdy, produce, consume)
        return m

    def _invariants(self, m, inner_level, inner_r_rdy, produce, consume):
        """The pointers' distance is the RAM's level (full or empty when they meet), and the
        registered flag is ``inner_level != 0``: assumed in the initial state, asserted after."""
        bits = len(produce)
        tests = [inner_level <= self.depth - 1,
                 (produce - consume)[:bits] == inner_level[:bits],
                 inner_r_rdy == (inner_level != 0)]
        with m.If(Initial()):
            m.d.comb += [Assume(test) for test in tests]
        with m.Else():
            m.d.comb += [Assert(test) for test in tests]
