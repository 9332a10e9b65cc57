"""The pipelined builds' output FIFO (``CreditFifo``) against Amaranth's ``SyncFIFOBuffered``:
cycle for cycle the same ports while its writer respects ``w_rdy`` (its one difference: it does
not refuse a write while full)."""

import random

import pytest
from amaranth.hdl import Module
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.sim import Simulator

from ik5r.hdl.datapath.output_fifo import CreditFifo


@pytest.mark.parametrize("depth", [2, 3, 5, 17])
def test_credit_fifo_is_sync_fifo_buffered_for_a_writer_with_credits(depth):
    m = Module()
    ours = m.submodules.ours = CreditFifo(width=12, depth=depth)
    theirs = m.submodules.theirs = SyncFIFOBuffered(width=12, depth=depth)
    rng = random.Random(depth)
    seen = {"items": 0, "full": 0}

    async def bench(ctx):
        for cycle in range(3000):
            # Phases of a busy writer and a slow reader (the FIFO fills), and the reverse.
            busy = (cycle // 200) % 2 == 0
            w_rdy = ctx.get(theirs.w_rdy)
            assert ctx.get(ours.w_rdy) == w_rdy, cycle
            w_en = w_rdy and rng.random() < (0.9 if busy else 0.3)
            r_en = rng.random() < (0.3 if busy else 0.9)
            data = rng.getrandbits(12)
            for fifo in (ours, theirs):
                ctx.set(fifo.w_en, w_en)
                ctx.set(fifo.w_data, data)
                ctx.set(fifo.r_en, r_en)
            for port in ("r_rdy", "level"):
                assert ctx.get(getattr(ours, port)) == ctx.get(getattr(theirs, port)), (cycle, port)
            if ctx.get(theirs.r_rdy):
                assert ctx.get(ours.r_data) == ctx.get(theirs.r_data), cycle
                seen["items"] += r_en
            seen["full"] += not w_rdy
            await ctx.tick()

    sim = Simulator(m)
    sim.add_clock(1e-6)
    sim.add_testbench(bench)
    sim.run()
    # Not vacuous: items went through, and the FIFO was full at times.
    assert seen["items"] > 500 and seen["full"] > 10, seen


@pytest.mark.parametrize("depth", [0, 1, 4, 6, 2.0])
def test_credit_fifo_wants_a_depth_of_a_power_of_two_plus_one(depth):
    with pytest.raises(ValueError, match="2 \\*\\* n \\+ 1"):
        CreditFifo(width=8, depth=depth)
