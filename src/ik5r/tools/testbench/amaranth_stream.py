"""Drive a stream block (``i``/``o`` valid/ready, ``in_fields``/``out_fields``) in Amaranth's own
simulator: the fast unit checks of the blocks (tests/test_hdl_blocks.py) and of the IK core
(tests/test_ik_core.py). The cocotb benches of the generated Verilog are :mod:`.stream_tb`.
"""

from __future__ import annotations

import random

from amaranth.sim import Simulator

from ik5r.core.modes import Arch


def run_stream(dut, inputs, **options):
    """Send ``inputs`` (dicts of field values) through ``dut``; returns
    ``(outputs, accept_cycles, output_cycles)``. The options: see :func:`run_phases`."""
    return run_phases(dut, [(inputs, options)])[0]


def run_phases(dut, phases):
    """Each ``(inputs, options)`` of ``phases`` through ONE simulation of ``dut`` (one elaboration
    for all), one after the other: a phase ends with the block empty (nothing more comes out
    within ``latency`` cycles of its last result). Returns one ``(outputs, accept_cycles,
    output_cycles)`` per phase, cycles counted from the phase's start.

    Options: ``stall_seed``: random input gaps and output back-pressure (and with ``long_stall``
    one stall of 3 * latency cycles half way); ``hold_output``: ``o.ready`` low in the first that
    many cycles; ``max_cycles``. Also checks the stream rule (a held output does not change)."""
    results = []

    async def bench(ctx):
        for inputs, options in phases:
            results.append(await _phase(ctx, dut, inputs, **options))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return results


def _max_cycles(dut, inputs, stall_seed, long_stall, hold_output):
    stalled = 4 if stall_seed is not None else 1
    return (len(inputs) + 4) * dut.cycles_per_result * stalled \
        + (7 if long_stall else 4) * dut.latency + hold_output + 100


async def _phase(ctx, dut, inputs, *, stall_seed=None, long_stall=False, hold_output=0, max_cycles=None):
    """One phase of :func:`run_phases`."""
    fields = list(dut.out_fields)
    outputs, accepted, produced = [], [], []
    if max_cycles is None:
        max_cycles = _max_cycles(dut, inputs, stall_seed, long_stall, hold_output)
    rng = random.Random(stall_seed)
    index, cycle, held = 0, 0, None
    stall_at = len(inputs) // 2 if long_stall else -1
    stall_left = 0
    while len(outputs) < len(inputs):
        assert cycle < max_cycles, f"timeout: {len(outputs)} of {len(inputs)} results"
        offer = index < len(inputs) and (stall_seed is None or rng.random() >= 0.3)
        if offer:
            ctx.set(dut.i.payload, inputs[index])
        ctx.set(dut.i.valid, offer)
        if len(outputs) == stall_at and stall_left == 0:
            stall_left, stall_at = 3 * dut.latency, -1
        take = stall_left == 0 and cycle >= hold_output and (stall_seed is None or rng.random() >= 0.4)
        stall_left = max(0, stall_left - 1)
        ctx.set(dut.o.ready, take)
        _, _, i_ready, o_valid, payload = await ctx.tick().sample(dut.i.ready, dut.o.valid, dut.o.payload)
        values = {name: int(getattr(payload, name)) for name in fields} if o_valid else None
        if held is not None:
            assert o_valid and values == held, "output changed while held"
        held = values if o_valid and not take else None
        if offer and i_ready:
            accepted.append(cycle)
            index += 1
        if o_valid and take:
            outputs.append(values)
            produced.append(cycle)
        cycle += 1
    # Nothing more comes out.
    ctx.set(dut.i.valid, 0)
    ctx.set(dut.o.ready, 1)
    for _ in range(dut.latency + 2):
        _, _, o_valid = await ctx.tick().sample(dut.o.valid)
        assert not o_valid, "extra output"
    return outputs, accepted, produced


def compare(inputs, expected, outputs):
    """Every output equal to its expected dict (tag included where there is one)."""
    assert len(outputs) == len(expected)
    bad = [(i, inp, exp, out) for i, (inp, exp, out) in enumerate(zip(inputs, expected, outputs))
           if exp != out]
    assert not bad, f"{len(bad)} of {len(inputs)} mismatch, first: item {bad[0][0]} in {bad[0][1]} " \
                    f"model {bad[0][2]} hdl {bad[0][3]}"


def output_held_phase(dut, inputs):
    """A phase of :func:`run_phases` for :func:`check_output_held`: the input offered every
    cycle, the output held for 2 x capacity + latency cycles (long after the block is full), then
    taken every cycle."""
    assert len(inputs) > dut.capacity
    return inputs, {"hold_output": 2 * dut.capacity + dut.latency}


def check_output_held(dut, inputs, expected, result):
    """The ``result`` of :func:`output_held_phase`: exactly ``capacity`` items are accepted, back
    to back from cycle 0 (``i.ready`` drops only when the credits are used up), and none is lost,
    duplicated or reordered (pipelined: the output FIFO, ``capacity`` deep, never overflows).
    Pipelined, from the release on: one result per clock with no bubble, and the input accepted
    every cycle again from the next one (the credit given back is registered)."""
    hold = output_held_phase(dut, inputs)[1]["hold_output"]
    outputs, accepted, produced = result
    compare(inputs, expected, outputs)
    assert accepted[:dut.capacity] == list(range(dut.capacity))
    assert accepted[dut.capacity] >= hold
    assert produced[0] == hold
    if dut.arch == Arch.PIPELINED:
        assert accepted[dut.capacity:] == list(range(hold + 1, hold + 1 + len(inputs) - dut.capacity))
        assert produced == list(range(hold, hold + len(inputs)))
