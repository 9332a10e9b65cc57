"""Both IK cores built for the shipped arms, under cocotb, against the bit-accurate model of the
same arm: every output bit (q1..q5, status) and the tag, stream run (idles, back-pressure, a
reset) and bulk run, random reachable poses of that arm plus its directed set.

All in the slow set (``make test-slow``): each is a Verilator C++ build of its own (the pipelined
core's ~2 CPU minutes). The default run's arm other than the arm of record is a random one,
tests/test_arm_unseen.py (its compact core's Verilog alone, through its own testbench and FK); both
cores are generated from the same traced graph of the arm's constants."""

from __future__ import annotations

from pathlib import Path

import pytest

from ik5r.core.arm import shipped_arm_names
from ik5r.core.chain import closed_form_arm

pytestmark = pytest.mark.sim

CASE_KEYS = ("arch", "arm", "config", "sim")       # sim_pool (conftest.py)
ARMS = tuple(n for n in shipped_arm_names() if closed_form_arm(n) is not None and n != "hu-5r")
CASES = [
    pytest.param(arch, arm, "q32w", "verilator", id=f"ik-{arch}-{arm}-q32w-verilator", marks=pytest.mark.slow)
    for arch in ("compact", "pipelined") for arm in ARMS
]


def _sizes(arch: str) -> tuple[int, int]:
    """(stream, bulk) random poses, each plus the directed set (the compact core: one pose per
    `latency` cycles, so few)."""
    return (100, 400) if arch == "pipelined" else (4, 16)


def run_case(arch, arm, config, sim):
    from ik5r.tools.testbench.runner import run_block, sim_design

    stream, bulk = _sizes(arch)
    stride = 1 if arch == "pipelined" else 4
    return run_block(sim_design("ik", arch, config, arm), sim, stream_vectors=stream, bulk_vectors=bulk,
                     seed=2026, cflags="-O0", edge_stride=stride, bulk_edge_rest=stride > 1)


@pytest.mark.parametrize("arch,arm,config,sim", CASES)
def test_core_of_the_arm_matches_its_model(sim_pool, arch, arm, config, sim):
    from ik5r.core.arm import load_arm
    from ik5r.tools.design import Design

    r = sim_pool((arch, arm, config, sim))
    assert r["arm"] == arm
    assert r["mismatches"] == 0, f"first mismatch: {r['first_mismatch']} (log: {r['log']})"
    assert r["tag_errors"] == 0 and r["stale_outputs"] == 0
    s, b = r["stream"], r["bulk"]
    assert s is not None and b is not None, f"a cocotb test did not finish (log: {r['log']})"
    stream, bulk = _sizes(arch)
    assert s["vectors"] >= stream and b["vectors"] >= bulk and r["vectors"] == s["vectors"] + b["vectors"]
    assert r["latency_cycles"] == r["latency_cycles_portmap"]
    # The core simulated is the arm's: its header and port map name it, and its body is not the
    # arm of record's (the arm's constants are in the Verilog).
    text, pmap = Design.resolve("ik", arch, config=config, arm=arm, tag_width=8).verilog()
    assert pmap["arm"] == {"name": arm, "sha256": load_arm(arm).dh_sha256(), "reach_cm": load_arm(arm).reach}
    assert f"// arm: {arm} (DH numbers and limits: sha256 {load_arm(arm).dh_sha256()}" in text
    assert arm in str(r["build_dir"])


#: An arm with reversed joints and limits (tests/arms/scorbot-reversed.toml): FK of random joints
#: within its limits, every branch, through the compact core, every bit against the model, which
#: gives those joints back (tests/test_arm_sense_limits.py).
REVERSED = str(Path(__file__).parent / "arms" / "scorbot-reversed.toml")


@pytest.mark.parametrize("arch,arm,config,sim", [
    pytest.param("compact", REVERSED, "q32w", "verilator", id="ik-compact-scorbot-reversed-q32w-verilator",
                 marks=pytest.mark.slow),
    pytest.param("pipelined", REVERSED, "q32w", "verilator", id="ik-pipelined-scorbot-reversed-q32w-verilator",
                 marks=pytest.mark.slow)])
def test_core_of_an_arm_with_reversed_joints_matches_its_model(sim_pool, arch, arm, config, sim):
    import numpy as np

    from ik5r.core import status as st
    from ik5r.core.arm import load_arm
    from ik5r.core.fxconfig import Constants, load_config
    from ik5r.firmware_model import vector
    from ik5r.firmware_model.vectors import edge_poses

    r = sim_pool((arch, arm, config, sim))
    assert r["arm"] == "scorbot-reversed"
    assert r["mismatches"] == 0, f"first mismatch: {r['first_mismatch']} (log: {r['log']})"
    assert r["tag_errors"] == 0 and r["stale_outputs"] == 0
    assert r["stream"] is not None and r["bulk"] is not None, f"a cocotb test did not finish (log: {r['log']})"
    # The run takes the whole directed set (stream and bulk together); out_of_limits is in it.
    k = Constants(load_config(config), load_arm(arm))
    assert np.any(np.asarray(vector.solve_batch(k, *edge_poses(k).args())[1]) & st.OUT_OF_LIMITS)
