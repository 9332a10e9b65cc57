"""Formal checks of the stream contract (``hdl/formal``, SymbiYosys with Boolector), on q18.

Every block (atan2, rotate, sqrt, acos; pipelined and iterative) and both IK cores (pipelined,
compact): the ``control`` group (hold, conservation, reset, credits) proved by k-induction on the
real component with its data abstracted (the pipelined IK core's, minutes, in the slow set); the
``order`` group (two marked items) by BMC from reset, to 2 x latency + 4 cycles where one item is
in flight (iterative blocks, compact core) and to latency + 8 for the pipelined builds (the blocks
in the default run, the IK cores in the slow set). The self-test: each injected fault (a broken hold, a lost item, a changed held payload) must
make the proof fail with a counterexample on the assertion it breaks. The jobs of the selected
tests run two at a time (each is a solver subprocess), started when the first test of this module
is reached.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import pytest

from ik5r.hdl.formal.contract import MUTATIONS
from ik5r.hdl.formal.run import JOBS, prove

pytestmark = pytest.mark.formal

#: Faults and the components they are injected into (the bench's two flow-control builds).
#: The assertions a fault may break first (a counterexample stops at the first failing cycle;
#: the component popping its output while o.ready is low breaks the hold and, in the same cycle,
#: the count of items inside).
BROKEN = {"ready_glitch": {"hold_valid", "hold_payload", "conservation", "segment_count",
                            "credits", "capacity"},
          "drop_input": {"conservation", "segment_count", "credits", "capacity"},
          "payload_flip": {"hold_payload"}}
MUTANTS = [(mutation, block, arch) for mutation in MUTATIONS
           for block, arch in (("sqrt", "pipelined"), ("sqrt", "iterative"))]


#: Jobs left to the slow set (minutes each): see the module docstring.
SLOW = {("control", "ik", "pipelined"), ("order", "ik", "pipelined"), ("order", "ik", "staged")}


def _param(check, block, arch):
    marks = (pytest.mark.slow,) if (check, block, arch) in SLOW else ()
    return pytest.param(check, block, arch, id=f"{check}-{block}-{arch}", marks=marks)


PROOFS = [_param(check, block, arch) for check in ("control", "order") for block, arch in JOBS]


@pytest.fixture(scope="module")
def proofs(request):
    """Starts the proof jobs of this module's selected tests in a pool of two."""
    selected = []
    for item in request.session.items:
        if item.module is request.module and hasattr(item, "callspec"):
            params = item.callspec.params
            key = (params.get("check", "control"), params["block"], params["arch"],
                   params.get("mutation"))
            if key not in selected:
                selected.append(key)
    with ThreadPoolExecutor(max_workers=2) as pool:
        futures = {key: pool.submit(prove, key[1], key[2], key[0], mutation=key[3],
                                    method="bmc" if key[3] else None)
                   for key in selected}
        yield lambda key: futures[key].result()


@pytest.mark.parametrize("check,block,arch", PROOFS)
def test_contract_proved(proofs, check, block, arch):
    r = proofs((check, block, arch, None))
    assert r.status == "PASS", r.detail
    assert r.config == "q18"
    if check == "control":
        assert r.method == "k-induction"
    else:
        assert r.method == "bmc"
        assert r.depth == (2 * r.latency + 4 if r.capacity == 1 else r.latency + 8)


@pytest.mark.parametrize("mutation,block,arch", MUTANTS, ids=[f"{m}-{b}-{a}" for m, b, a in MUTANTS])
def test_injected_fault_fails_the_proof(proofs, mutation, block, arch):
    r = proofs(("control", block, arch, mutation))
    assert r.status == "FAIL", f"{mutation} not caught: {r.status} {r.detail}"
    assert r.method == "bmc" and r.depth == r.latency + 8
    assert r.failed and set(r.failed) <= BROKEN[mutation], r.failed
