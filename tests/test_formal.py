"""Formal checks of the stream contract (``hdl/formal``, SymbiYosys with Boolector), on q18.

Every block (atan2, rotate, sqrt, acos; pipelined and iterative) and both IK cores (pipelined,
compact): the ``control`` group (hold, conservation, reset, credits) proved by k-induction on the
real component with its data abstracted. The self-test: each injected fault (a broken hold, a lost
item, a changed held payload) must make the proof fail with a counterexample. The jobs run two at
a time (each is a solver subprocess), started when the first test of this module is reached.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import pytest

from ik5r.hdl.formal.contract import MUTATIONS
from ik5r.hdl.formal.run import JOBS, prove

pytestmark = pytest.mark.formal

#: Faults and the components they are injected into (the bench's two flow-control builds).
#: The assertion each fault must break.
BROKEN = {"ready_glitch": "hold_valid", "drop_input": "conservation", "payload_flip": "hold_payload"}
MUTANTS = [(mutation, block, arch) for mutation in MUTATIONS
           for block, arch in (("sqrt", "pipelined"), ("sqrt", "iterative"))]


@pytest.fixture(scope="module")
def proofs():
    with ThreadPoolExecutor(max_workers=2) as pool:
        futures = {("control", block, arch, None): pool.submit(prove, block, arch, "control")
                   for block, arch in JOBS}
        futures.update({("control", block, arch, mutation): pool.submit(
            prove, block, arch, "control", mutation=mutation, method="bmc")
            for mutation, block, arch in MUTANTS})
        yield lambda key: futures[key].result()


@pytest.mark.parametrize("block,arch", JOBS, ids=[f"{b}-{a}" for b, a in JOBS])
def test_control_proved_by_induction(proofs, block, arch):
    r = proofs(("control", block, arch, None))
    assert r.status == "PASS", r.detail
    assert r.method == "k-induction" and r.config == "q18"


@pytest.mark.parametrize("mutation,block,arch", MUTANTS, ids=[f"{m}-{b}-{a}" for m, b, a in MUTANTS])
def test_injected_fault_fails_the_proof(proofs, mutation, block, arch):
    r = proofs(("control", block, arch, mutation))
    assert r.status == "FAIL", f"{mutation} not caught: {r.status} {r.detail}"
    assert r.method == "bmc" and r.depth == r.latency + 8
    assert BROKEN[mutation] in r.failed, r.failed
