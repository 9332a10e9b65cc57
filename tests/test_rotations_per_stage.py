"""Micro-rotations per pipeline stage (``rotations_per_stage``, issue 30): the same CORDIC steps
and square-root digits, 2 or 4 of them in one stage, so the same bits in fewer cycles.

Amaranth's simulator on every block (q18, the cases of ``test_hdl_blocks``: every output bit,
exact latency, one result per clock, gaps, back-pressure, the output held); the latencies of
each choice; the option refused where it cannot apply. The IK core is checked bit for bit by
the harness runs (``tests/test_harness.py``) and ``ik5r sim --rotations-per-stage``.
"""

from __future__ import annotations

import gc
import random

import pytest
from test_hdl_blocks import acos_cases, atan2_cases, check_block, rotate_cases, sqrt_cases

from ik5r.core.fxconfig import constants, load_config
from ik5r.hdl.blocks.acos import Acos
from ik5r.hdl.blocks.cordic import Atan2, Rotate
from ik5r.hdl.blocks.sqrt import Sqrt
from ik5r.hdl.generate import generate, module_name

K = constants(load_config("q18"))


#: The default run: a CORDIC block and the square root, both choices among them (acos is made of
#: the two); the rest in the slow set.
# The CORDIC blocks at 4 per stage cost minutes of CPU and gigabytes before the first clock (what
# crashed the xdist worker that ran rotate-4): each micro-rotation's direction is the sign of the
# previous one's result, and add_sub replicates it across the adder's width, so the expression of
# a stage of 4 re-references the first step's value about width^4 times. Amaranth 0.5 walks such
# trees without memo twice: Module's statement check (_dsl._check_rhs, at elaboration, so also
# ik5r verilog) and the simulator's compiler. Measured at q18 (generate, rotate, pipelined, one
# process): 1 per stage 0.6 s CPU, 2 per stage 2.9 s, 4 per stage over 100 s in _check_rhs. A
# cure changes the Verilog (a wire between grouped steps, or another form of add_sub's operand
# inversion): a design change with re-simulation and re-placed records, not done here.
DEFAULT = {("atan2", 2), ("sqrt", 4)}


@pytest.mark.parametrize("block,per_stage", [
    pytest.param(b, r, id=f"{b}-{r}", marks=() if (b, r) in DEFAULT else (pytest.mark.slow,))
    for b in ("atan2", "rotate", "sqrt", "acos") for r in (2, 4)])
def test_blocks_bit_exact(block, per_stage):
    rng = random.Random(30 + per_stage)
    if block == "atan2":
        dut, (inputs, expected) = Atan2(constants=K, arch="pipelined", tag_width=3,
                                        rotations_per_stage=per_stage), atan2_cases(K, rng, 40)
    elif block == "rotate":
        dut, (inputs, expected) = Rotate(constants=K, arch="pipelined", tag_width=3,
                                         rotations_per_stage=per_stage), rotate_cases(K, rng, 40)
    elif block == "sqrt":
        dut, (inputs, expected) = Sqrt(constants=K, arch="pipelined", tag_width=3,
                                       rotations_per_stage=per_stage), sqrt_cases(K, rng, 40, K.cfg.frac_length)
    else:
        dut, (inputs, expected) = Acos(constants=K, arch="pipelined", tag_width=3,
                                       rotations_per_stage=per_stage), acos_cases(K, rng, 40)
    check_block(dut, inputs, expected, tag_width=3)


@pytest.mark.filterwarnings("ignore:.*created but never used")
def test_latencies():
    """q18 (16 micro-rotations, 9 square-root digits of a length word): each stage of
    micro-steps takes ``per_stage`` of them, the last one what is left."""
    got = {r: (Atan2(constants=K, arch="pipelined", rotations_per_stage=r).latency,
               Rotate(constants=K, arch="pipelined", rotations_per_stage=r).latency,
               Sqrt(constants=K, arch="pipelined", rotations_per_stage=r).latency,
               Acos(constants=K, arch="pipelined", rotations_per_stage=r).latency) for r in (1, 2, 4)}
    iterations = K.cfg.iterations
    assert got[1] == (32, 31, 19, 51)
    # atan2: iterations steps; rotate: iterations + 1 (skewed); sqrt and acos: fewer too.
    for r in (2, 4):
        assert got[r][0] == got[1][0] - iterations + -(-iterations // r)
        assert got[r][1] == got[1][1] - (iterations + 1) + -(-(iterations + 1) // r)
    for column in (2, 3):
        assert got[4][column] < got[2][column] < got[1][column]
    gc.collect()    # the blocks built for their latency warn (never elaborated) here, not in a later test


@pytest.mark.filterwarnings("ignore:.*created but never used")
def test_option_checked_and_named():
    with pytest.raises(ValueError, match="pipelined"):
        Atan2(constants=K, arch="iterative", rotations_per_stage=2)
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="positive integer"):
            Rotate(constants=K, arch="pipelined", rotations_per_stage=bad)
    text, pmap = generate("sqrt", "pipelined", K, 0, rotations_per_stage=2)
    assert pmap["module"] == module_name("sqrt", "pipelined", rotations_per_stage=2)
    assert pmap["options"]["rotations_per_stage"] == 2
    assert pmap["latency_cycles"] == Sqrt(constants=K, arch="pipelined", rotations_per_stage=2).latency
    assert "rotations_per_stage" not in generate("sqrt", "pipelined", K, 0)[1]["options"]
    gc.collect()    # the refused and measured blocks warn (never elaborated) here, not in a later test
