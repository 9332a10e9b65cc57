"""Self-test of the cocotb stream bench (``src/ik5r/tools/testbench/stream_tb.py``): a corrupted view of the output
must make the bench fail, each fault with its own finding, and the clean run must check the stream
rule under a stall with the reset asserted while the output is held.

One small block (atan2, iterative, q18) on Icarus, a short stream run per fault: the bench's
driver, monitor and scoreboard are the same for every block and the IK core.
"""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.sim

CASE = dict(block="atan2", arch="iterative", config="q18", sim="icarus")


def _run(fault=None):
    from ik5r.tools.testbench.runner import run_block, sim_design

    return run_block(sim_design(CASE["block"], CASE["arch"], CASE["config"]), CASE["sim"], stream_vectors=24,
                     bulk_vectors=0, seed=7, fault=fault)


class _Runs(dict):
    """The run of each kind (clean or a fault), made when a test first asks for it: under xdist
    the tests of this module land on different workers, each of which needs only its own."""

    def __missing__(self, kind):
        self[kind] = _run(None if kind == "clean" else {"kind": kind, "at": 5})
        return self[kind]


@pytest.fixture(scope="module")
def runs():
    from ik5r.tools.testbench.runner import simulator_missing

    missing = simulator_missing(CASE["sim"])
    if missing:
        pytest.fail(f"{missing} (CI installs both simulators)", pytrace=False)
    return _Runs()


def test_clean_run_checks_hold_across_reset(runs):
    r = runs["clean"]
    assert r["mismatches"] == 0, r["first_mismatch"]
    assert r["hold_violations"] == 0
    s = r["stream"]
    assert s["resets"] == 1 and s["reset_while_held"] is True
    assert s["held_cycles"] > 10          # the rule was checked, under long stalls


def test_bit_flip_is_caught(runs):
    r = runs["flip"]
    assert r["mismatches"] >= 1
    assert r["first_mismatch"]["kind"] in ("value", "tag")


def test_dropped_item_is_caught(runs):
    r = runs["drop"]
    assert r["mismatches"] >= 1 and r["tag_errors"] >= 1
    assert r["first_mismatch"]["kind"] == "tag"


def test_unstable_output_is_caught(runs):
    r = runs["unstable"]
    assert r["hold_violations"] == 1
    assert r["first_mismatch"]["kind"].startswith("output changed while held")


def test_stream_stride_and_bulk_rest_split_the_edge_set(tmp_path):
    """``edge_stride`` n (the stream run) and ``edge_rest`` (the bulk run) take each edge item
    exactly once between them, in the set's order."""
    import json

    import numpy as np

    from ik5r.tools.testbench.job import Job
    from ik5r.tools.testbench.runner import generate_sources, sim_design

    _, portmap = generate_sources(sim_design("ik", "compact", "q18"), tmp_path)   # a small IK core
    path = tmp_path / "job.json"
    path.write_text(json.dumps({"portmap": str(portmap), "block": "ik", "config": "q18", "work_dir": str(tmp_path)}))
    job = Job(str(path))
    every = job.edge_items()
    n = len(next(iter(every.values())))
    for stride in (2, 4):
        picked, rest = job.edge_items(stride), job.edge_items(stride, rest=True)
        assert len(next(iter(picked.values()))) == -(-n // stride)
        for role, values in every.items():
            merged = np.empty_like(values)
            merged[::stride] = picked[role]
            merged[np.arange(n) % stride != 0] = rest[role]
            assert (merged == values).all(), role
