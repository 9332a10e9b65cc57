"""cocotb runs of every hardware block against the bit-accurate model (``src/ik5r/tools/testbench``).

Each case: block x arch x config x simulator, a cocotb-driven stream run (random idles, random
back-pressure with long stalls, a reset in the middle of traffic, latency / cycles-per-result
measurement) and a bulk run, each of N random vectors + the block's edge set; every output field
bit for bit, tags for order and loss. The blocks with multipliers are also run as the ECP5 variant
(``dsp="ecp5"``: MULT18X18D instances with their registers and CCU2C add/sub chains, simulated
with the models in hdl/sim/).

The default run keeps to a few minutes on 2 cores: each (block, arch, config) once, on Icarus but
for the sqrt block's iterative q18 case on Verilator (a Verilator case is a C++ build of tens of CPU
seconds, an Icarus one a few; every block is simulated in Verilator inside the IK cores,
tests/test_cocotb_core.py); the ECP5 variants in the slow set (their mapping runs by default inside
the ECP5 IK core); 300 + 1000 vectors on the pipelined blocks, 50 + 100 on the iterative ones (an
item takes latency cycles), each plus the edge set. ``IK5R_SIM_FULL=1`` runs the
full matrix on both simulators with 2000 + 2000 vectors everywhere; ``make test-slow`` the rest of the
matrix. Cases run two at a time in a
thread pool (each is a simulator subprocess), started when the first case is reached.
"""

from __future__ import annotations

import os

import pytest

from ik5r.core.modes import ARCHS, Block

pytestmark = pytest.mark.sim


BLOCKS = tuple(block.value for block in Block if block != Block.IK)
CONFIGS = ("q18", "q32")
SIMS = ("icarus", "verilator")
FULL = os.environ.get("IK5R_SIM_FULL", "") not in ("", "0")
CASE_KEYS = ("block", "arch", "config", "dsp", "sim")     # sim_pool (conftest.py)
#: Blocks with multipliers: the ones whose ECP5 variant differs.
DSP_BLOCKS = ("atan2", "acos", "rotate")


#: (block, arch, config) of the generic cases on Verilator in the default run; the others on Icarus.
VERILATOR_DEFAULT = (("sqrt", "iterative", "q18"),)


def _in_default(block, arch, config, sim, dsp="generic") -> bool:
    if FULL:
        return True
    if dsp != "generic":
        # The ECP5 mapping (MULT18X18D limbs, CCU2C chains) runs by default inside the IK core
        # (tests/test_cocotb_core.py: the ECP5 q18 core on Icarus); the blocks' in the slow set.
        return False
    return ((block, arch, config) in VERILATOR_DEFAULT) == (sim == "verilator")


def _sizes(arch: str, dsp: str) -> tuple[int, int]:
    """(stream vectors, bulk vectors), each plus the edge set. The ECP5 variant simulates every
    carry-chain cell (~4x slower on Icarus) and differs from the generic one, which runs the full
    count, only in how the same arithmetic is mapped: fewer vectors."""
    if FULL:
        return 2000, 2000
    if arch != "pipelined":
        return 50, 100
    return (300, 1000) if dsp == "generic" else (100, 100)


CASES = [
    pytest.param(b, a, c, "generic", s, id=f"{b}-{a}-{c}-{s}",
                 marks=() if _in_default(b, a, c, s) else (pytest.mark.slow,))
    for s in SIMS for b in BLOCKS for a in ARCHS for c in CONFIGS
] + [
    pytest.param(b, "pipelined", c, "ecp5", s, id=f"{b}-pipelined-dspecp5-{c}-{s}",
                 marks=() if _in_default(b, "pipelined", c, s, "ecp5") else (pytest.mark.slow,))
    for s in SIMS for b in DSP_BLOCKS for c in CONFIGS
]


def run_case(block, arch, config, dsp, sim):
    from ik5r.tools.testbench.runner import run_block, sim_design

    stream, bulk = _sizes(arch, dsp)
    # O0: the C++ of a Verilator build compiles ~4x faster; these runs are short.
    return run_block(sim_design(block, arch, config, dsp=dsp), sim, stream_vectors=stream, bulk_vectors=bulk,
                     seed=2024, cflags="-O0")


@pytest.mark.parametrize("block,arch,config,dsp,sim", CASES)
def test_block_matches_model(sim_pool, block, arch, config, dsp, sim):
    r = sim_pool((block, arch, config, dsp, sim))
    stream, bulk = _sizes(arch, dsp)
    assert r["mismatches"] == 0, f"first mismatch: {r['first_mismatch']} (log: {r['log']})"
    assert r["tag_errors"] == 0 and r["stale_outputs"] == 0
    s, b = r["stream"], r["bulk"]
    assert s is not None and b is not None, f"a cocotb test did not finish (log: {r['log']})"
    assert s["resets"] == 1
    assert s["vectors"] >= stream and b["vectors"] >= bulk
    # Every vector of both runs came out and was compared (none lost, none duplicated).
    assert r["vectors"] == s["vectors"] + b["vectors"]
    assert r["latency_cycles"] == r["latency_cycles_portmap"]
    assert r["cycles_per_result"] == r["cycles_per_result_portmap"]
    assert r["dsp"] == dsp
    if sim == "verilator":
        # The build is the block's lint too (-Wall, hdl/verilator.vlt): clean.
        assert r["lint_warnings"] == [], "\n".join(r["lint_warnings"][:20])
