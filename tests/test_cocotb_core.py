"""cocotb runs of the IK core (``ik5r sim --block ik``) against the bit-accurate model (``src/ik5r/tools/testbench``).

Each case: arch x config x simulator; a cocotb-driven stream run (random idles, random back-pressure
with long stalls, a reset in the middle of traffic, latency and cycles-per-result measured: the
pipelined core must take one pose per clock with the output always ready) and a bulk run, each of N
random reachable poses (one in ten random words) plus the directed set
(``ik5r.firmware_model.vectors.directed_poses``: every branch of the paper's pose, base-axis, singular,
unreachable, invalid and full-scale cases); every output bit (q1..q5, status) and the tag for
order and loss.

The core is large (q32 pipelined: ~250 stages) and Icarus runs it at tens of cycles per second, so
the default run takes each core once on each simulator: on Verilator both cores of q32w (the default
config: 38-bit internal format), on Icarus the ECP5 variant (MULT18X18D and CCU2C chains) of the q18
pipelined core, with 16 + 16 random poses besides the directed set (Icarus simulates its carry cells
slowly; q18's 18-bit words already split into a DSP limb and a narrow LUT limb). The compact core's
Icarus run is its word-serial wrapper's (tests/test_cocotb_serial.py: the same engine inside). Where a
pose is slow to simulate (the ECP5 variant, the compact core) the stream run takes every fourth
(the compact core: eighth) directed pose and the bulk run the others. The other cases are in the slow set: the
generic cores on Icarus (pipelined q18: 100 + 300 random poses), the ECP5 variant of q32w on Icarus
(the README's headline design: ~3 CPU minutes of Icarus) and of q32, every ECP5 config on Verilator
(every carry cell simulated makes its Verilator build ~8 minutes and its run ~60 poses/s).
``IK5R_SIM_FULL=1`` runs all 18 cases (both archs, q18, q32 and q32w, both simulators, and the
ECP5-DSP variant).
"""

from __future__ import annotations

import os

import pytest

from ik5r.core.fxconfig import constants, load_config
from ik5r.firmware_model.vectors import directed_poses
from ik5r.core.modes import CORE_ARCHS

pytestmark = pytest.mark.sim


CONFIGS = ("q18", "q32", "q32w")
SIMS = ("icarus", "verilator")
FULL = os.environ.get("IK5R_SIM_FULL", "") not in ("", "0")
CASE_KEYS = ("arch", "config", "dsp", "sim")     # sim_pool (conftest.py)
# "compact" = the sequenced engine (hdl/sequenced/engine.py).
DEFAULT = {("compact", "q32w", "generic", "verilator"), ("pipelined", "q32w", "generic", "verilator"),
           ("pipelined", "q18", "ecp5", "icarus")}


def _sizes(arch: str, config: str, dsp: str, sim: str) -> tuple[int, int]:
    """(stream, bulk) random poses, each plus the directed set."""
    if arch == "pipelined" and (dsp, sim) == ("ecp5", "icarus") and config != "q32" and not FULL:
        # Icarus simulates the ECP5 variant's carry chains (~900 CCU2C chains at q32w) at ~25 cycles
        # a CPU second: a handful of random poses besides the directed set (the generic cores take
        # thousands on Verilator).
        return 16, 16
    if arch == "pipelined":
        return (100, 300) if sim == "icarus" and not FULL else (500, 3000) if FULL else (200, 1000)
    return 4, 20          # one pose per `latency` cycles


CASES = [
    pytest.param(a, c, "generic", s, id=f"ik-{a}-{c}-{s}",
                 marks=() if FULL or (a, c, "generic", s) in DEFAULT else (pytest.mark.slow,))
    for s in SIMS for a in CORE_ARCHS for c in CONFIGS
] + [
    # The ECP5 variant: MULT18X18D and CCU2C instances (models in hdl/sim/) in the pipelined core.
    pytest.param("pipelined", c, "ecp5", s, id=f"ik-pipelined-dspecp5-{c}-{s}",
                 marks=() if FULL or ("pipelined", c, "ecp5", s) in DEFAULT else (pytest.mark.slow,))
    for s in SIMS for c in CONFIGS
]


def _edge_stride(arch: str, dsp: str) -> int:
    """The stream run (idles, back-pressure, a reset) takes every n-th directed pose where a pose
    is slow to simulate (the ECP5 variant's carry cells on Icarus, the compact core's program);
    the bulk run then takes the others, so each directed pose is still checked on every bit, once."""
    if FULL or (arch, dsp) == ("pipelined", "generic"):
        return 1
    # The compact core's stream run: ~10k cycles/s through cocotb, its bulk run ~50k.
    return 8 if arch == "compact" else 4


def run_case(arch, config, dsp, sim):
    from ik5r.tools.testbench.runner import run_block, sim_design

    stream, bulk = _sizes(arch, config, dsp, sim)
    return run_block(sim_design("ik", arch, config, dsp=dsp), sim, stream_vectors=stream, bulk_vectors=bulk,
                     seed=2024, cflags="-O0", edge_stride=_edge_stride(arch, dsp),
                     bulk_edge_rest=_edge_stride(arch, dsp) > 1)


@pytest.mark.parametrize("arch,config,dsp,sim", CASES)
def test_core_matches_model(sim_pool, arch, config, dsp, sim):
    r = sim_pool((arch, config, dsp, sim))
    stream, bulk = _sizes(arch, config, dsp, sim)
    assert r["mismatches"] == 0, f"first mismatch: {r['first_mismatch']} (log: {r['log']})"
    assert r["tag_errors"] == 0 and r["stale_outputs"] == 0
    s, b = r["stream"], r["bulk"]
    assert s is not None and b is not None, f"a cocotb test did not finish (log: {r['log']})"
    assert s["resets"] == 1
    directed = len(directed_poses(constants(load_config(config))))
    stride = _edge_stride(arch, dsp)
    in_stream = -(-directed // stride)
    in_bulk = directed if stride == 1 else directed - in_stream
    assert s["vectors"] >= stream + in_stream and b["vectors"] >= bulk + in_bulk
    assert r["vectors"] == s["vectors"] + b["vectors"]
    assert r["latency_cycles"] == r["latency_cycles_portmap"]
    assert r["cycles_per_result"] == r["cycles_per_result_portmap"]
    if sim == "verilator":
        # The build is the core's lint too (-Wall, hdl/verilator.vlt): clean.
        assert r["lint_warnings"] == [], "\n".join(r["lint_warnings"][:20])
    if arch == "pipelined":
        # A full-rate burst with the output always ready: one pose per clock.
        assert r["cycles_per_result"] == 1


@pytest.mark.slow
def test_ecp5_core_with_dsp_output_regs_matches_model():
    """The ECP5 variant with a fabric register after each DSP (``--dsp-output-regs 1``, q18 on
    Icarus, like the default ECP5 case): the same bits, the latency of its port map, a pose a
    clock."""
    from ik5r.tools.testbench.runner import run_block, sim_design

    design = sim_design("ik", "pipelined", "q18", dsp="ecp5", dsp_output_regs=1)
    r = run_block(design, "icarus", stream_vectors=16, bulk_vectors=16, seed=2024, edge_stride=4,
                  bulk_edge_rest=True)
    assert r["mismatches"] == 0, f"first mismatch: {r['first_mismatch']} (log: {r['log']})"
    assert r["tag_errors"] == 0 and r["stale_outputs"] == 0
    assert r["stream"] is not None and r["bulk"] is not None and r["vectors"] >= 32
    assert r["latency_cycles"] == r["latency_cycles_portmap"] == design.verilog()[1]["latency_cycles"]
    assert r["cycles_per_result"] == 1


@pytest.mark.slow
@pytest.mark.parametrize("config", ["q18", "q32w"])
def test_two_pose_compact_core_matches_model(config):
    """The compact core of two poses a program (``--poses 2``) on Verilator: every bit against the
    model through the stream run (idles, back-pressure, a reset mid-traffic: programs whose second
    pose is skipped) and the bulk run; its latency and cycles per result those of its port map."""
    from ik5r.tools.testbench.runner import run_block, sim_design

    design = sim_design("ik", "compact", config, poses=2)
    r = run_block(design, "verilator", stream_vectors=8, bulk_vectors=40, seed=2025, cflags="-O0",
                  edge_stride=8, bulk_edge_rest=True)
    assert r["mismatches"] == 0, f"first mismatch: {r['first_mismatch']} (log: {r['log']})"
    assert r["tag_errors"] == 0 and r["stale_outputs"] == 0
    assert r["stream"] is not None and r["bulk"] is not None and r["stream"]["resets"] == 1
    assert r["vectors"] >= 48 + len(directed_poses(constants(load_config(config))))
    assert r["latency_cycles"] == r["latency_cycles_portmap"]
    assert r["cycles_per_result"] == r["cycles_per_result_portmap"]
    assert r["lint_warnings"] == [], "\n".join(r["lint_warnings"][:20])


@pytest.mark.parametrize("config,wide,poses,sim", [
    pytest.param("q18", True, 2, "verilator", id="q18-wide-poses2-verilator"),
    pytest.param("q32w", True, 2, "verilator", id="q32w-wide-poses2-verilator",
                 marks=() if FULL else (pytest.mark.slow,)),
    pytest.param("q32w", False, 1, "icarus", id="q32w-icarus", marks=() if FULL else (pytest.mark.slow,)),
])
def test_compact_core_on_ecp5_dsps_matches_model(config, wide, poses, sim):
    """The compact core with ``--dsp ecp5`` (its limb multiplier on MULT18X18D, hdl/sim's model:
    the limb registers are the DSPs' input registers, one DSP or two with the wide product step):
    every bit against the model through the stream and bulk runs, the latency and cycles per
    result of its port map, lint-clean on Verilator."""
    from ik5r.tools.testbench.runner import run_block, sim_design

    design = sim_design("ik", "compact", config, dsp="ecp5", poses=poses, wide_product=wide)
    assert design.verilog()[0].count("MULT18X18D #(") == (2 if wide else 1)
    r = run_block(design, sim, stream_vectors=8, bulk_vectors=24, seed=2026, cflags="-O0",
                  edge_stride=8, bulk_edge_rest=True)
    assert r["mismatches"] == 0, f"first mismatch: {r['first_mismatch']} (log: {r['log']})"
    assert r["tag_errors"] == 0 and r["stale_outputs"] == 0
    assert r["stream"] is not None and r["bulk"] is not None and r["stream"]["resets"] == 1
    assert r["vectors"] >= 32 + len(directed_poses(constants(load_config(config))))
    assert r["latency_cycles"] == r["latency_cycles_portmap"]
    assert r["cycles_per_result"] == r["cycles_per_result_portmap"]
    assert not r.get("lint_warnings"), "\n".join(r["lint_warnings"][:20])
