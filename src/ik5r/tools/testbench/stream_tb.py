"""cocotb test module: a generic valid/ready stream testbench, configured by a job JSON (:mod:`.job`).

Two tests, both comparing every output field bit for bit with the reference model and checking the
tag (a running sequence number) for order and loss:

``test_stream`` (fully cocotb-driven, in the shape of cocotb's matrix_multiplier example)
    The components of :mod:`.components` (or, for the compact IK core's word-serial wrapper, the
    beat driver and monitor of :mod:`.serial`): random idle cycles between items, random
    back-pressure with long stalls, an in-order scoreboard, and a reset in the middle of traffic:
    items in flight are flushed (and sent again afterwards), any output of a flushed item
    afterwards is a stale-output error. Before the random traffic it measures latency (one item
    into an empty block) and cycles per result (a full-rate burst).

``test_bulk`` (fast)
    Drives the generated wrapper's bulk engine (:mod:`.bulk`, :mod:`.wrapper`): Python writes the
    packed input vectors and the valid / ready patterns to files, pulses ``bulk_start`` and waits
    for ``bulk_done``; the HDL streams the vectors and logs every accepted output. Expected values
    come from the numpy model (checked against the scalar model on the edge set and a random
    sample).
"""

from __future__ import annotations

import sys
import time

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import ClockCycles, FallingEdge

from .bulk import CLOCK_NS, BulkRun
from .components import StreamTB, _sig
from .job import Job, Results
from .serial import BeatDriver, BeatMonitor


def _limit(job: Job, items: int) -> int:
    lat = job.pm.latency_cycles or 100
    cpr = job.pm.cycles_per_result or 1
    return 20 * (lat + 50) + items * (cpr + 1) * 40 + 10000


async def _start(dut, job: Job):
    Clock(_sig(dut, job.pm.clk), CLOCK_NS, unit="ns").start()
    for name in ("bulk_start", "bulk_count"):
        try:
            _sig(dut, name).value = 0
        except (AttributeError, KeyError):
            pass
    pm = job.pm
    _sig(dut, pm.i.valid).value = 0
    _sig(dut, pm.o.ready).value = 0
    _sig(dut, pm.i.payload).value = 0
    _sig(dut, pm.rst).value = 1
    await ClockCycles(_sig(dut, pm.clk), 3)
    await FallingEdge(_sig(dut, pm.clk))
    _sig(dut, pm.rst).value = 0


@cocotb.test()
async def test_stream(dut):
    job = Job()
    opts = job.doc.get("stream")
    if not opts:
        return
    results = Results(job)
    t0 = time.perf_counter()
    await _start(dut, job)
    tb = StreamTB(dut, job, results, *((BeatDriver, BeatMonitor) if job.serial else ()))
    inputs = job.inputs(int(opts.get("vectors", 1000)), salt=1, edge_stride=int(opts.get("edge_stride", 1)))
    expected = job.expected(inputs)
    tb.load(inputs, expected)
    n = len(next(iter(inputs.values())))
    order = list(range(n))
    lat = job.pm.latency_cycles or 0
    if opts.get("progress"):
        from tqdm import tqdm
        tb.progress = tqdm(total=n, unit="item", desc=f"{job.doc['block']} {job.doc.get('arch', '')} stream",
                           file=sys.stderr, dynamic_ncols=True, mininterval=0.5)
    try:
        await _stream_phases(dut, job, tb, results, opts, inputs, expected, n, order, lat, t0)
    except AssertionError as error:
        if not results.mismatches:      # stopped before any mismatch (no progress): that is one
            results.mismatch("aborted", None, None, str(error))
        raise
    finally:
        if tb.progress is not None:
            tb.progress.close()
        if "stream" not in results.sections:       # failed part-way: still report what was seen
            results.sections["stream"] = {"vectors": n, "cycles": tb.cycle, "aborted": True}
            results.write(job.work / "result_stream.json")


def _mean_interval(outs: list) -> float | None:
    """Cycles between results, over an even number of intervals: a compact core of two poses a
    program gives its results in pairs (any other core, evenly: the same mean)."""
    outs = outs[1:] if len(outs) % 2 == 0 else outs
    return (outs[-1] - outs[0]) / (len(outs) - 1) if len(outs) > 1 else None


async def _stream_phases(dut, job, tb, results, opts, inputs, expected, n, order, lat, t0):

    # 1. latency: one item into an empty block, always ready.
    tb.driver.queue.extend(order[:1])
    await tb.run_until_idle(_limit(job, 1))
    latency = tb.sb.out_cycles[-1][0] - tb.sb.out_cycles[-1][2] if tb.sb.out_cycles else None
    # 2. cycles per result: a full-rate burst.
    # At most half the items, so the random phase (with its mid-traffic reset) keeps the rest.
    burst = min((n - 1) // 2, max(32, 3 * lat + 16))
    tb.driver.queue.extend(order[1:1 + burst])
    await tb.run_until_idle(_limit(job, burst))
    cpr = _mean_interval([c for c, _, _ in tb.sb.out_cycles[-burst:]] if len(tb.sb.out_cycles) > burst else [])
    # 3. random idles and back-pressure with long stalls, reset in the middle of traffic.
    rest = order[1 + burst:]
    tb.driver.idle_prob, tb.driver.idle_max = float(opts.get("idle_prob", 0.3)), int(opts.get("idle_max", 8))
    tb.bp.mode = "random"
    half = len(rest) // 2
    tb.driver.queue.extend(rest)
    resets = 0
    held_at_reset = False
    if opts.get("reset", True) and half:
        # Reset once traffic is flowing, the block holds items in flight and its output is held
        # (o.valid & ~o.ready): stability under a stall and the reset's release checked together.
        limit_c = tb.cycle + _limit(job, half)
        while len(tb.driver.accepted) < 1 + burst + half or not tb.sb.pending or tb.monitor.held is None:
            await tb.step()
            if tb.cycle > limit_c:
                raise AssertionError("traffic did not reach the mid-point")
        in_flight = len(tb.sb.pending)
        tb.reset.trigger(int(opts.get("reset_cycles", 4)))
        resets = 1
        held_at_reset = True
        dut._log.info("reset asserted at cycle %d with %d items in flight", tb.cycle, in_flight)
    await tb.run_until_idle(_limit(job, len(rest)))
    # Nothing may come out after the last item: a few more cycles, ready high.
    tb.bp.mode = "always"
    for _ in range(max(20, 2 * lat)):
        await tb.step()
    missing = sorted(set(order) - set(tb.sb.got))
    if missing:
        results.mismatch("lost", None, None, f"{len(missing)} items never came out, first {missing[:5]}")
    idx = np.array(sorted(i for i, v in tb.sb.got.items() if v is not None), dtype=np.int64)
    if idx.size:
        got = {role: np.array([tb.sb.got[i][role] for i in idx], dtype=np.int64) for role in expected}
        results.errors({r: v[idx] for r, v in inputs.items()}, got)
    wall = time.perf_counter() - t0
    results.sections["stream"] = {"vectors": n, "cycles": tb.cycle, "resets": resets,
                                  "reset_while_held": held_at_reset, "held_cycles": tb.monitor.held_cycles,
                                  "latency_cycles": latency, "cycles_per_result": cpr,
                                  "wall_seconds": wall}
    if job.serial:
        results.sections["stream"]["beats_dropped_by_reset"] = {"input": tb.driver.beats_dropped,
                                                                "output": tb.monitor.beats_dropped}
    doc = results.write(job.work / "result_stream.json")
    dut._log.info("stream: %d compared, %d mismatches, latency %s, cycles/result %s, %.0f cycles/s",
                  results.compared, results.mismatches, latency, cpr, tb.cycle / wall)
    assert results.mismatches == 0, f"first mismatch: {doc['first_mismatch']}"
    assert results.compared == n


@cocotb.test()
async def test_bulk(dut):
    job = Job()
    opts = job.doc.get("bulk")
    if not opts:
        return
    results = Results(job)
    t0 = time.perf_counter()
    await _start(dut, job)
    run = BulkRun(dut, job, results, opts)
    results.sections["bulk"] = await run.run(t0)
    doc = results.write(job.work / "result_bulk.json")
    wall = results.sections["bulk"]["wall_seconds"]
    dut._log.info("bulk: %d compared, %d mismatches, %.0f vectors/s (sim only %.0f), %d cycles",
                  results.compared, results.mismatches, run.seq / wall, run.seq / max(run.sim_seconds, 1e-9),
                  run.sim_cycles)
    assert results.mismatches == 0, f"first mismatch: {doc['first_mismatch']}"
