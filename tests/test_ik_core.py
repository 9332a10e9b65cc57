"""The IK core (hdl/ik_core.py) against the bit-accurate model (``model.solve_batch``).

Amaranth's simulator; every output bit (q1..q5, status, tag) of random reachable poses (all four
branches, with and without n, o) and a directed set (the paper's pose, tool point on the base axis
with vertical and horizontal approach, straight and folded elbow, unreachable, off-plane and
degenerate approaches, full-scale and most negative words), for both architectures on q18 and
q32. The pipelined core runs at full rate (exact latency, one pose per clock) and then with random
input gaps and output back-pressure (order, no loss, output held stable); the compact core with
back-pressure too.
"""

from __future__ import annotations

import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from ik5r.fxconfig import constants, load_config
from ik5r.hdl import ik_vectors as V
from ik5r.hdl.ik_core import IKCore

CONFIGS = ("q18", "q32")
TAG_WIDTH = 6


def _k(name):
    return constants(load_config(name))


# --- stimulus ------------------------------------------------------------------------------------

def poses_for(k, random_count, seed):
    return V.concat(V.directed_poses(k), V.random_poses(k, random_count, np.random.default_rng(seed)))


def expected_of(k, poses):
    """model.solve_batch (the specification) over the poses: a list of dicts of output fields."""
    out = V.solve(k, poses)
    return [{name: int(out[name][i]) for name in V.OUTPUTS} for i in range(len(out["status"]))]


def inputs_of(poses, tag_width=0):
    count = len(poses["px"])
    items = [{name: int(poses[name][i]) for name in V.INPUTS} for i in range(count)]
    if tag_width:
        for i, item in enumerate(items):
            item["tag"] = i % (1 << tag_width)
    return items


# --- the stream driver ---------------------------------------------------------------------------

def run_core(dut, items, *, stall_seed=None, long_stall=False):
    """Send ``items`` through ``dut``; returns (outputs, accept cycles, output cycles).

    With ``stall_seed``, random input gaps and output back-pressure (and with ``long_stall`` one
    stall of 3 * latency cycles); checks that a held output does not change and that nothing more
    comes out at the end."""
    fields = list(dut.out_fields)
    outputs, accepted, produced = [], [], []
    limit = (len(items) + 4) * dut.cycles_per_result * (4 if stall_seed is not None else 1) \
        + 8 * dut.latency + 100

    async def bench(ctx):
        rng = random.Random(stall_seed)
        index, cycle, held = 0, 0, None
        stall_at = len(items) // 2 if long_stall else -1
        stall_left = 0
        while len(outputs) < len(items):
            assert cycle < limit, f"timeout: {len(outputs)} of {len(items)} results"
            offer = index < len(items) and (stall_seed is None or rng.random() >= 0.3)
            if offer:
                ctx.set(dut.i.payload, items[index])
            ctx.set(dut.i.valid, offer)
            if len(outputs) == stall_at and stall_left == 0:
                stall_left, stall_at = 3 * dut.latency, -1
            take = stall_left == 0 and (stall_seed is None or rng.random() >= 0.4)
            stall_left = max(0, stall_left - 1)
            ctx.set(dut.o.ready, take)
            _, _, i_ready, o_valid, payload = await ctx.tick().sample(
                dut.i.ready, dut.o.valid, dut.o.payload)
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
        ctx.set(dut.i.valid, 0)
        ctx.set(dut.o.ready, 1)
        for _ in range(dut.cycles_per_result + 2):
            _, _, o_valid = await ctx.tick().sample(dut.o.valid)
            assert not o_valid, "extra output"

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return outputs, accepted, produced


def compare(items, expected, outputs, tag_width):
    assert len(outputs) == len(expected)
    bad = []
    for i, (item, exp, out) in enumerate(zip(items, expected, outputs)):
        want = dict(exp, tag=item["tag"]) if tag_width else exp
        if out != want:
            bad.append((i, item, want, out))
    assert not bad, (f"{len(bad)} of {len(items)} mismatch; first: item {bad[0][0]} in {bad[0][1]} "
                     f"model {bad[0][2]} hdl {bad[0][3]}")


# --- tests ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("cfg", CONFIGS)
def test_pipelined(cfg):
    k = _k(cfg)
    poses = poses_for(k, 200, seed=1)
    items, expected = inputs_of(poses, TAG_WIDTH), expected_of(k, poses)
    dut = IKCore(constants=k, arch="pipelined", tag_width=TAG_WIDTH)
    assert dut.cycles_per_result == 1
    outputs, accepted, produced = run_core(dut, items)
    compare(items, expected, outputs, TAG_WIDTH)
    # Full rate: one pose per clock in, fixed latency out.
    assert accepted == list(range(len(items)))
    assert [b - a for a, b in zip(accepted, produced)] == [dut.latency] * len(items)
    # Random gaps and back-pressure, one long stall.
    sub = slice(0, 150)
    outputs, _, _ = run_core(dut, items[sub], stall_seed=5, long_stall=True)
    compare(items[sub], expected[sub], outputs, TAG_WIDTH)


@pytest.mark.parametrize("cfg", CONFIGS)
def test_compact(cfg):
    k = _k(cfg)
    # One pose per `latency` cycles (~1000 cycles/s in Amaranth's simulator): the directed set and
    # fewer random poses (the pipelined test runs 200 through the same expressions).
    poses = poses_for(k, 60, seed=2)
    items, expected = inputs_of(poses, TAG_WIDTH), expected_of(k, poses)
    dut = IKCore(constants=k, arch="compact", tag_width=TAG_WIDTH)
    assert dut.cycles_per_result == dut.latency
    outputs, accepted, produced = run_core(dut, items)
    compare(items, expected, outputs, TAG_WIDTH)
    assert [b - a for a, b in zip(accepted, produced)] == [dut.latency] * len(items)
    assert all(b - a == dut.latency for a, b in zip(accepted, accepted[1:]))
    outputs, _, _ = run_core(dut, items[:12], stall_seed=6)
    compare(items[:12], expected[:12], outputs, TAG_WIDTH)


@pytest.mark.filterwarnings("ignore:.*created but never used")
def test_no_tag_and_latency():
    k = _k("q18")
    dut = IKCore(constants=k, arch="pipelined")
    assert "tag" not in dut.in_fields and "tag" not in dut.out_fields
    poses = V.random_poses(k, 20, np.random.default_rng(3))
    outputs, _, _ = run_core(dut, inputs_of(poses))
    compare(inputs_of(poses), expected_of(k, poses), outputs, 0)
    big = IKCore(constants=_k("q32"), arch="pipelined")
    big._MustUse__used = True       # only its latency is wanted
    # Fixed by the blocks' stage counts: more CORDIC iterations, more stages.
    assert 150 < dut.latency < big.latency < 300


@pytest.mark.filterwarnings("ignore:.*created but never used")
def test_constructor_validation():
    k = _k("q18")
    with pytest.raises(ValueError):
        IKCore(constants=k, arch="iterative-ish")
    with pytest.raises(TypeError):
        IKCore(constants=k.cfg, arch="pipelined")
    with pytest.raises(ValueError):
        IKCore(constants=k, arch="pipelined", tag_width=-1)
