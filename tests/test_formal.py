"""Formal checks of the stream contract (``hdl/formal``, SymbiYosys with Boolector), on q18.

What is proved how (``hdl/formal/run.py``; the record: docs/results/records/formal_q18*.json):

* ``control`` (hold, conservation, reset, credits): k-induction (depth 2, every reachable state)
  on the real component with its data abstracted, for every block (atan2, rotate, sqrt, acos;
  pipelined and iterative) and IK core (pipelined, compact; the cores' jobs in the slow set and
  the committed records).
* ``order`` (two marked items: none invented or duplicated, B not before A, A not lost):
  k-induction for the pipelined blocks (the marks tracked through the delay line, the FIFO's
  write register, its RAM and its output register: ``hdl/formal/pipelined.py``; the FIFO by
  the FIFO lemma, proved first for the block's FIFO: acos's, a 65-deep FIFO, ~25 CPU s), for the
  pipelined IK core (the same, its tag followed through its stash RAM by a ghost delay line that
  the stash lemma justifies: ``hdl/formal/stash.py``, and its FIFO by the FIFO lemma at depth
  257; ~20 CPU s with both lemmas), for the iterative blocks (their one item's stage, step and
  tag register: ``hdl/formal/iterative.py``) and for the compact core
  (the sequenced engine, against a ghost queue of the tags inside: ``hdl/formal/sequenced.py``).
* the stash lemma (the real stash RAM code, at the pipelined core's distance and width, is a
  delay line), by k-induction in seconds (default run); the FIFO lemma (the real output FIFO
  keeps the marks' order: ``hdl/formal/fifo.py``: the marks' slots and one arbitrary entry
  tracked, not every entry), by k-induction with each pipelined build's order job, for its
  FIFO's width and depth (33, 65 or 257: seconds each).

The self-test: each injected fault (a broken hold, a lost item, a changed held payload) must make
the control proof fail with a counterexample from reset on the assertion it breaks (BMC); a
broken hold must break the order induction of a pipelined block, of an iterative block and of
the pipelined IK core (a flipped output tag too: the iterative block and the pipelined IK core,
in the slow set), and the control induction of the compact core
(slow set); a stash lemma
claiming a distance one off must fail; the FIFO lemma on the core's FIFO must fail (by induction
and by BMC from reset) without each of its assumptions or with its read assumption at the wrong
entry. In one process the jobs of the selected tests run two at a time (each is a solver
subprocess), started when the first test of this module is reached; under xdist each job runs in
its test.
"""

from __future__ import annotations

import hashlib
import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from ik5r.core.fxconfig import constants, load_config
from ik5r.hdl.formal.contract import MUTATIONS, OUTSIDE, TAG_WIDTH
from ik5r.hdl.formal.run import (
    INDUCTION_ONLY,
    JOBS,
    ORDER_INDUCTION,
    harness,
    prove,
    prove_fifo_lemma,
    prove_stash_lemma,
    stash_lemma_links,
)
from ik5r.hdl.generate import build

pytestmark = pytest.mark.formal

#: Faults and the components they are injected into (the bench's two flow-control builds).
#: The assertions a fault may break first (a counterexample stops at the first failing cycle;
#: the component popping its output while o.ready is low breaks the hold and, in the same cycle,
#: the count of items inside).
BROKEN = {"ready_glitch": {"hold_valid", "hold_payload", "conservation", "segment_count",
                            "credits", "capacity"},
          "drop_input": {"conservation", "segment_count", "credits", "capacity"},
          "payload_flip": {"hold_payload"}}
#: Each fault on one architecture by default (each is caught on both: the other in the slow set).
MUTANTS_DEFAULT = {("ready_glitch", "pipelined"), ("drop_input", "iterative"), ("payload_flip", "iterative")}
MUTANTS = [pytest.param(mutation, block, arch, id=f"{mutation}-{block}-{arch}",
                        marks=() if (mutation, arch) in MUTANTS_DEFAULT else (pytest.mark.slow,))
           for mutation in MUTATIONS if mutation not in OUTSIDE
           for block, arch in (("sqrt", "pipelined"), ("sqrt", "iterative"))]


#: Jobs left to the slow set: both IK cores' control and order proofs, the longest jobs (the
#: pipelined core's ~50 and ~40 CPU s, the compact core's ~55 and ~30 s cold, its two-pose
#: build's ~100 s each: together more than a sixth of the default run's CPU), proved in the
#: committed records docs/results/records/formal_q18.json and formal_q18_sequenced.json, which
#: `make formal` re-makes. Every block's jobs, the lemmas and
#: the fault self-tests below run by default.
SLOW = {(check, "ik", arch) for check in ("control", "order")
        for arch in ("pipelined", "compact", "compact-poses2")}


def _param(check, block, arch):
    marks = (pytest.mark.slow,) if (check, block, arch) in SLOW else ()
    return pytest.param(check, block, arch, id=f"{check}-{block}-{arch}", marks=marks)


PROOFS = [_param(check, block, arch) for check in ("control", "order") for block, arch in JOBS]


def _prove(key):
    """A fault in the control group: a counterexample from reset (BMC), except in the compact
    core (see SEQUENCED_MUTANTS); in the order group: the default (induction)."""
    check, block, arch, mutation = key
    method = "bmc" if mutation and check == "control" and (block, arch) not in INDUCTION_ONLY else None
    return prove(block, arch, check, mutation=mutation, method=method)


@pytest.fixture(scope="module")
def proofs(request, under_xdist):
    """``proofs(key)`` is the result of a proof job. One process: the jobs of this module's
    selected tests start in a pool of two at the first test. Under xdist (``make test``) a job
    runs when its test asks for it: every worker collects every test, so a pool would run each
    job once per worker."""
    if under_xdist:
        yield _prove
        return
    selected = []
    for item in request.session.items:
        if (item.module is request.module and hasattr(item, "callspec")
                and "block" in item.callspec.params):
            params = item.callspec.params
            key = (params.get("check", "control"), params["block"], params["arch"],
                   params.get("mutation"))
            if key not in selected:
                selected.append(key)
    with ThreadPoolExecutor(max_workers=2) as pool:
        futures = {key: pool.submit(_prove, key) for key in selected}
        yield lambda key: futures[key].result()


@pytest.mark.parametrize("check,block,arch", PROOFS)
def test_contract_proved(proofs, check, block, arch):
    r = proofs((check, block, arch, None))
    assert r.status == "PASS", r.detail
    assert r.config == "q18"
    # Every job by k-induction: every reachable state, not a bounded run from reset.
    assert (block, arch) in ORDER_INDUCTION and r.method == "k-induction"
    if check == "order" and (block, arch) == ("ik", "pipelined"):
        # Its stash and FIFO lemmas proved, its control group assumed (proved by its job).
        assert [lemma["status"] for lemma in r.lemmas] == ["PASS", "PASS", "ASSUMED"], r.lemmas
    elif check == "order" and arch == "pipelined":
        # Its FIFO lemma (hdl/formal/fifo.py) proved for its FIFO's width and depth.
        assert [lemma["status"] for lemma in r.lemmas] == ["PASS"], r.lemmas
        assert f"depth {r.capacity}," in r.lemmas[0]["lemma"], r.lemmas


#: The committed records of the IK cores' proofs (the slow set's jobs), and the q18 design each
#: fingerprints: ``design_sha256``, the SHA-256 of the core's Verilog body (header stripped) as the
#: testbenches convert it (tag width 8; the pipelined core's ECP5 variant, whose conversion the
#: default cocotb run shares; the compact core's the lint test's), taken when the record was made.
RECORDS = Path(__file__).resolve().parents[1] / "docs" / "results" / "records"
CORE_RECORDS = {"pipelined": ("formal_q18.json", "pipelined", {"dsp": "ecp5"}),
                "compact": ("formal_q18_sequenced.json", "compact", {}),
                "compact-poses2": ("formal_q18_sequenced.json", "compact", {"poses": 2})}


def core_fingerprint(arch: str) -> str:
    """``design_sha256`` of the IK core ``arch`` of this checkout (see :data:`CORE_RECORDS`)."""
    from ik5r.hdl.provenance import strip_header
    from ik5r.tools.testbench.runner import sim_design

    _, core, options = CORE_RECORDS[arch]
    text, _ = sim_design("ik", core, "q18", **options).verilog()
    return hashlib.sha256(strip_header(text).encode()).hexdigest()


@pytest.mark.parametrize("arch", sorted(CORE_RECORDS))
def test_core_proof_records_are_of_this_checkout(arch):
    """The IK cores' proofs run in the slow set; their committed records (the README's "proved")
    must be of this checkout's cores: both groups passed by k-induction, on the design this
    checkout generates (a change of the core's Verilog needs `make formal` and a new record)."""
    record = json.loads((RECORDS / CORE_RECORDS[arch][0]).read_text())
    jobs = [j for j in record["jobs"] if (j["block"], j["arch"]) == ("ik", arch)]
    assert sorted(j["check"] for j in jobs) == ["control", "order"], jobs
    assert all(j["status"] == "PASS" and j["method"] == "k-induction" and j["mutation"] is None
               and j["config"] == "q18" for j in jobs), jobs
    fingerprint = core_fingerprint(arch)
    assert all(j.get("design_sha256") == fingerprint for j in jobs), (
        f"{CORE_RECORDS[arch][0]}: its ik/{arch} proofs are of another design than this checkout's "
        f"(re-run `make formal` and re-make the record)")


@pytest.mark.parametrize("mutation,block,arch", MUTANTS)
def test_injected_fault_fails_the_proof(proofs, mutation, block, arch):
    r = proofs(("control", block, arch, mutation))
    assert r.status == "FAIL", f"{mutation} not caught: {r.status} {r.detail}"
    assert r.method == "bmc" and r.depth == r.latency + 8
    assert r.failed and set(r.failed) <= BROKEN[mutation], r.failed


#: The sequenced compact core's self-test: by k-induction (a counterexample from reset needs an
#: item through the whole program, see run.INDUCTION_ONLY). The faulty core's proof must not go
#: through: the induction step fails on the assertion the fault breaks. Slow set (about a CPU
#: minute; the default run's broken-hold self-tests are the blocks' and the pipelined core's).
SEQUENCED_MUTANTS = [pytest.param("ready_glitch", "ik", "compact", id="ready_glitch-ik-compact",
                                  marks=pytest.mark.slow)]


@pytest.mark.parametrize("mutation,block,arch", SEQUENCED_MUTANTS)
def test_injected_fault_breaks_the_induction(proofs, mutation, block, arch):
    r = proofs(("control", block, arch, mutation))
    assert r.status in ("FAIL", "UNKNOWN"), f"{mutation} not caught: {r.status} {r.detail}"
    assert r.method == "k-induction"
    assert r.failed and set(r.failed) <= BROKEN[mutation], r.failed


#: A broken hold in a pipelined block or IK core under the order group's k-induction: the component pops
#: its FIFO while the output is held, so the items counted inside and the marks' places no
#: longer agree (the induction step, or a counterexample from reset, fails).
#: A tag fault (``tag_flip``: the output tag's LSB inverted on its way out, the component
#: intact) must break the order induction of the pipelined IK core and of an iterative block (their
#: tracking: not vacuous); the pipelined IK core's faults (a CPU minute or more: its proof is in the
#: slow set too) in the slow set, the sqrt block's in the default run (its iterative arch's
#: broken hold in the slow set: the pipelined one's is the same fault).
ORDER_MUTANTS = [pytest.param("order", mutation, block, arch, id=f"order-{mutation}-{block}-{arch}",
                              marks=(pytest.mark.slow,) if (block == "ik" or (mutation, arch) == (
                                  "ready_glitch", "iterative")) else ())
                 for mutation, block, arch in (("ready_glitch", "sqrt", "pipelined"),
                                               ("ready_glitch", "sqrt", "iterative"),
                                               ("tag_flip", "sqrt", "iterative"),
                                               ("ready_glitch", "ik", "pipelined"),
                                               ("tag_flip", "ik", "pipelined"))]
ORDER_BROKEN = BROKEN["ready_glitch"] | {"fifo_refill", "mark_output", "mark_ram", "mark_a_once",
                                         "mark_b_once", "order", "a_not_lost", "mark_waiting",
                                         "mark_stage", "mark_occupied", "mark_fifo", "mark_invented",
                                         "fifo_mark_once"}


@pytest.mark.parametrize("check,mutation,block,arch", ORDER_MUTANTS)
def test_injected_fault_breaks_the_order_induction(proofs, check, mutation, block, arch):
    r = proofs((check, block, arch, mutation))
    assert r.status in ("FAIL", "UNKNOWN"), f"{mutation} not caught: {r.status} {r.detail}"
    assert r.method == "k-induction"
    assert r.failed and set(r.failed) <= ORDER_BROKEN, r.failed
    if mutation == "tag_flip":
        # Not the control group (it is not broken): the marks' own assertions.
        assert not set(r.failed) & BROKEN["ready_glitch"], r.failed


@pytest.fixture(scope="module")
def stash_links():
    """(origin, where, word width) of the pipelined IK core's stash RAM(s) carrying the tag."""
    dut = build("ik", "pipelined", constants(load_config("q18")), tag_width=TAG_WIDTH)
    module = dut.elaborate(None)
    # Elaborated only to read its stash links: not a design to use.
    for elaboratable in (dut, module, *(sub for sub, _ in module._named_submodules.values())):
        elaboratable._MustUse__silence = True
    return stash_lemma_links(dut, module)


def test_stash_lemma_proved(stash_links):
    """The assumption the pipelined IK core's order induction makes (hdl/formal/stash.py)."""
    assert stash_links, "the core's tag no longer passes a stash RAM: drop the lemma"
    for link in stash_links:
        lemma = prove_stash_lemma(*link)
        assert lemma["status"] == "PASS", lemma
        assert lemma["method"] == "k-induction"


def test_stash_lemma_with_a_wrong_distance_fails(stash_links):
    """The lemma is not vacuous: claiming the delay one cycle longer (the real RAM) breaks the
    induction on the delay assertion; on a short stash (same code) BMC finds the counterexample
    from reset (on the core's 184-cycle stash that BMC takes many minutes)."""
    lemma = prove_stash_lemma(*stash_links[0], skew=1)
    assert lemma["status"] in ("FAIL", "UNKNOWN") and lemma["failed"] == ["stash_delay"], lemma
    short = prove_stash_lemma(1, 12, 2, skew=1, method="bmc")
    assert short["status"] == "FAIL" and short["failed"] == ["stash_delay"], short


@pytest.fixture(scope="module")
def fifo_shape():
    """(payload layout, depth) of the output FIFO of the pipelined IK core (257). The FIFO
    lemma itself is proved with each pipelined build's order job (test_contract_proved)."""
    top = harness("ik", "pipelined", "q18", ("order",))
    top._MustUse__silence = True
    return top.dut.o.payload.shape(), top.dut.capacity


#: The FIFO lemma's self-test: a premise left out (tag 3 written, a mark written twice, the
#: assumption on the RAM's read data) or the read assumption taken at the wrong entry (skew), and
#: the assertions that may fail first. By default the invented mark and the skewed read (the
#: tracked entry's own check); the other two premises in the slow set.
FIFO_MUTANTS = {"mark_invented": {"fifo_entry_invented", "fifo_invented"},
                "fifo_mark_once": {"fifo_once", "fifo_entry", "fifo_slots", "fifo_out", "fifo_ram",
                                   "fifo_read_entry"},
                "fifo_read": {"fifo_out", "fifo_invented"},
                "skew": {"fifo_read_entry", "fifo_out", "fifo_invented"}}


@pytest.mark.parametrize("without", [pytest.param(name, marks=() if name in ("mark_invented", "skew")
                                                  else (pytest.mark.slow,)) for name in sorted(FIFO_MUTANTS)])
def test_fifo_lemma_needs_its_premises(fifo_shape, without):
    """On the pipelined IK core's FIFO (depth 257): without one of its assumptions, or with its
    read assumption at the next entry, the lemma's induction fails, and BMC from reset finds a
    counterexample (so the lemma's assumptions are not vacuous, and its tracked entry checks the
    read assumption)."""
    layout, depth = fifo_shape
    kwargs = {"skew": 1} if without == "skew" else {"without": without}
    for method in ("k-induction", "bmc"):
        broken = prove_fifo_lemma(layout, depth, method=method, **kwargs)
        assert broken["status"] in (("FAIL", "UNKNOWN") if method == "k-induction" else ("FAIL",)), broken
        assert broken["failed"] and set(broken["failed"]) <= FIFO_MUTANTS[without], broken


def test_fifo_lemma_needs_its_writer_to_respect_w_rdy(fifo_shape):
    """``CreditFifo`` does not refuse a write while full (the build's credits keep it from
    one): without that premise the lemma's induction fails on the IK core's FIFO (depth 257),
    and BMC from reset finds the overwritten item on a FIFO of depth 5 (the FIFO's own pointer
    invariant, or the lemma's, fails)."""
    layout, depth = fifo_shape
    broken = prove_fifo_lemma(layout, depth, without="fifo_write_full")
    assert broken["status"] in ("FAIL", "UNKNOWN") and broken["failed"], broken
    assert set(broken["failed"]) <= FIFO_MUTANTS["fifo_mark_once"], broken
    short = prove_fifo_lemma(layout, 5, method="bmc", bmc_depth=12, without="fifo_write_full")
    assert short["status"] == "FAIL" and short["failed"], short
    assert all(name in FIFO_MUTANTS["fifo_mark_once"] or name.startswith("output_fifo.py:")
               for name in short["failed"]), short
    assert prove_fifo_lemma(layout, 5)["status"] == "PASS"


def test_an_engine_error_says_why(tmp_path):
    """A job that ends in ERROR reports the solver's own words (sby says only "returned ERROR")."""
    from ik5r.hdl.formal.run import _engine_errors

    engine = tmp_path / "engine_0"
    engine.mkdir()
    (engine / "logfile.txt").write_text("SMT-solver: boolector\nboolector: out of memory in 'bv_mul'\n")
    why = _engine_errors(tmp_path, "Traceback ...\nBrokenPipeError: [Errno 32] Broken pipe\n")
    assert "engine_0: boolector: out of memory in 'bv_mul'" in why.splitlines()
    assert "stderr: BrokenPipeError: [Errno 32] Broken pipe" in why.splitlines()
