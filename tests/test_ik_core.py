"""The IK core (hdl/pipelined/core.py) against the bit-accurate model (``model.solve_batch``).

Amaranth's simulator; every output bit (q1..q5, status, tag) of random reachable poses (all four
branches, with and without n, o) and a directed set (the paper's pose, tool point on the base axis
with vertical and horizontal approach, straight and folded elbow, unreachable, off-plane and
degenerate approaches, full-scale and most negative words), for both architectures on q18 and
q32. The pipelined core runs at full rate (exact latency, one pose per clock), then with random
input gaps and output back-pressure (order, no loss, output held stable), then with the output held
until it is full (exactly its capacity taken, nothing lost, full rate again once released). The
``compact`` arch of ``generate`` (the sequenced engine) is tested in tests/test_seq_core.py.
"""

from __future__ import annotations

import gc

import pytest

from ik5r.core.fxconfig import constants, load_config
from ik5r.firmware_model import model
from ik5r.firmware_model.poses import FIELDS, concat
from ik5r.firmware_model.vectors import directed_poses, random_poses
from ik5r.hdl.pipelined.core import IKCore
from ik5r.tools.testbench.amaranth_stream import (
    check_output_held,
    compare,
    output_held_phase,
    run_phases,
    run_stream,
)
from ik5r.tools.testbench.blocks import IK_OUTPUTS, ik_outputs

CONFIGS = ("q18", "q32")
#: q32w: q32's words on a 38-bit internal format (``ik.internal_guard_bits`` = 6).
#: The stream behaviour (full rate, fixed latency, back-pressure, output held) is the same generator at
#: every width: q18 in the default run. q32 and q32w (~2 CPU minutes each in Amaranth's simulator) are in
#: the slow set; the q32w pipelined core's Verilog is simulated in the default run by cocotb on Verilator
#: (tests/test_cocotb_core.py), and q32's blocks by tests/test_cocotb_blocks.py.
PIPELINED_CONFIGS = ("q18",) + tuple(pytest.param(name, marks=pytest.mark.slow) for name in ("q32", "q32w"))
TAG_WIDTH = 6


def _k(name):
    return constants(load_config(name))


# --- stimulus ------------------------------------------------------------------------------------

def poses_for(k, random_count, seed):
    """The directed set and ``random_count`` random poses (every branch, with and without n/o)."""
    return concat(directed_poses(k), random_poses(k, -(-random_count // 8), seed)[:random_count])


def expected_of(k, poses):
    """model.solve_batch (the specification) over the poses: a list of dicts of output fields."""
    out = ik_outputs(k, poses, model.solve_batch)
    return [{name: int(out[name][i]) for name in IK_OUTPUTS} for i in range(len(poses))]


def inputs_of(poses, tag_width=0):
    fields = poses.fields()
    items = [{name: int(fields[name][i]) for name in FIELDS} for i in range(len(poses))]
    if tag_width:
        for i, item in enumerate(items):
            item["tag"] = i % (1 << tag_width)
    return items


def with_tags(items, expected):
    """The expected outputs carrying their item's tag."""
    return [dict(exp, tag=item["tag"]) for item, exp in zip(items, expected)]


# --- tests ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("cfg", PIPELINED_CONFIGS)
def test_pipelined(cfg):
    k = _k(cfg)
    poses = poses_for(k, 48, seed=1)
    items = inputs_of(poses, TAG_WIDTH)
    expected = with_tags(items, expected_of(k, poses))
    dut = IKCore(constants=k, arch="pipelined", tag_width=TAG_WIDTH)
    assert dut.cycles_per_result == 1
    # Full rate; random gaps and back-pressure with one long stall; the output held until the
    # core is full, then released (the poses again, as many as needed): one simulation.
    sub = slice(0, 120)
    repeats, count = -(-(dut.capacity + 40) // len(items)), dut.capacity + 40
    held_items, held_expected = (items * repeats)[:count], (expected * repeats)[:count]
    full, stalled, held = run_phases(dut, [(items, {}), (items[sub], {"stall_seed": 5, "long_stall": True}),
                                           output_held_phase(dut, held_items)])
    outputs, accepted, produced = full
    compare(items, expected, outputs)
    # Full rate: one pose per clock in, fixed latency out.
    assert accepted == list(range(len(items)))
    assert [b - a for a, b in zip(accepted, produced)] == [dut.latency] * len(items)
    compare(items[sub], expected[sub], stalled[0])
    check_output_held(dut, held_items, held_expected, held)


@pytest.mark.filterwarnings("ignore:.*created but never used")
def test_no_tag_and_latency():
    k = _k("q18")
    dut = IKCore(constants=k, arch="pipelined")
    assert "tag" not in dut.in_fields and "tag" not in dut.out_fields
    poses = random_poses(k, 3, seed=3)
    outputs, _, _ = run_stream(dut, inputs_of(poses))
    compare(inputs_of(poses), expected_of(k, poses), outputs)
    big = IKCore(constants=_k("q32"), arch="pipelined")
    big._MustUse__used = True       # only its latency is wanted
    wide = IKCore(constants=_k("q32w"), arch="pipelined")
    wide._MustUse__used = True
    # Fixed by the blocks' stage counts: more CORDIC iterations, more stages.
    assert 150 < dut.latency < big.latency < wide.latency < 350


@pytest.mark.filterwarnings("ignore:.*created but never used")
def test_constructor_validation():
    k = _k("q18")
    with pytest.raises(ValueError):
        IKCore(constants=k, arch="iterative-ish")
    with pytest.raises(TypeError):
        IKCore(constants=k.cfg, arch="pipelined")
    with pytest.raises(ValueError):
        IKCore(constants=k, arch="pipelined", tag_width=-1)
    with pytest.raises(ValueError):
        IKCore(constants=k, arch="pipelined", dsp="xilinx")
    for arch in ("compact", "iterative", "staged"):    # the compact core is the sequenced engine
        with pytest.raises(ValueError, match="SequencedIKCore"):
            IKCore(constants=k, arch=arch)
    gc.collect()   # the half-built components warn here (filtered), not in a later test


