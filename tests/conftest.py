"""Shared fixture of the cocotb test modules (tests/test_cocotb_*.py), and the order of the run.

Two ways to run the suite, the same tests either way:

* ``pytest`` (one process): each cocotb module starts all its selected cases in a thread pool of
  ``IK5R_SIM_WORKERS`` (default 2) simulator subprocesses, Verilator builds first.
* ``pytest -n N`` (pytest-xdist, what ``make test`` does): each case is a test like any other,
  run where xdist sends it, one simulator per worker (no thread pool: N workers are N busy
  processes); the heaviest tests are collected first so that the long poles start at once and
  the light tests fill in around them. Each worker's simulator builds use one make job
  (``IK5R_BUILD_JOBS``, ``ik5r.tools.testbench.runner``), generated Verilog is shared through
  ``build/verilog-cache``.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import pytest

from ik5r.tools.testbench.runner import simulator_missing

WORKERS = int(os.environ.get("IK5R_SIM_WORKERS", "2"))


def _under_xdist(config) -> bool:
    return getattr(config, "workerinput", None) is not None or (
        config.pluginmanager.hasplugin("xdist") and getattr(config.option, "numprocesses", None))


def _case_weight(item) -> int:
    """A rough rank of a test's cost (larger runs first under xdist; ties keep collection order).
    Simulations of the pipelined IK core and Verilator builds are the long poles, then the other
    cocotb cases, then the tests that convert or simulate the IK core in Amaranth, then the IK
    cores' proof jobs."""
    name = item.nodeid
    if item.get_closest_marker("sim") is not None and hasattr(item, "callspec"):
        params = item.callspec.params
        weight = 50
        weight += 40 if params.get("sim") == "verilator" else 0
        weight += 40 if "ik-" in name and params.get("arch") == "pipelined" else 0
        weight += 10 if params.get("dsp") == "ecp5" else 0
        return weight
    if any(part in name for part in ("test_ik_core.py", "test_verilator_lint", "test_verilog_deterministic[ik]")):
        return 40
    if "test_formal.py" in name and "-ik-" in name:
        return 30      # the IK cores' proof jobs: up to a CPU minute each

    return 0


def pytest_configure(config):
    # An xdist worker is one of N busy processes: its simulator builds get one make job each and
    # run beside the other workers' (ik5r.tools.testbench.runner._build_lock), rather than all cores each,
    # one at a time, the other workers waiting.
    if getattr(config, "workerinput", None) is not None:
        os.environ.setdefault("IK5R_BUILD_JOBS", "1")


def pytest_collection_modifyitems(config, items):
    """Heaviest first (stable: ties keep collection order). xdist's ``--dist load
    --maxschedchunk 1`` (``make test``) hands worker i the items 2i and 2i + 1 first, then one
    at a time as workers free up: the first 2N items are paired heavy with lighter, so that the N
    heaviest start at once, one on each worker."""
    if not _under_xdist(config):
        return
    items.sort(key=_case_weight, reverse=True)
    workers = int(getattr(config, "workerinput", {}).get("workercount", 0))
    head = items[:2 * workers]
    if workers and len(head) == 2 * workers:
        items[:2 * workers] = [item for i in range(workers) for item in (head[i], head[-1 - i])]


@pytest.fixture(scope="session")
def under_xdist(request) -> bool:
    """Whether this run is split over pytest-xdist workers (each collects every test: a module
    fixture that starts the jobs of all selected tests would run each of them once per worker)."""
    return _under_xdist(request.config)


@pytest.fixture(scope="module")
def sim_pool(request):
    """``sim_pool(key)`` is the result of a case of the requesting module, and fails (never
    skips) when its simulator is not installed. The module names its case parameters in
    ``CASE_KEYS`` (the simulator last) and runs a case with ``run_case(*key)``.

    One process: every selected case of the module starts in a thread pool (each case is a
    simulator subprocess), Verilator builds first (the long poles); a case whose simulator is
    missing is not started. Under xdist: a case runs when its test asks for it."""
    mod = request.module

    def missing_fails(key):
        missing = simulator_missing(key[-1])
        if missing:
            pytest.fail(f"{missing} (CI installs both simulators)", pytrace=False)

    if _under_xdist(request.config):
        def run(key):
            missing_fails(key)
            return mod.run_case(*key)

        yield run
        return
    selected = []
    for item in request.session.items:
        if item.module is mod and hasattr(item, "callspec"):
            key = tuple(item.callspec.params[name] for name in mod.CASE_KEYS)
            if key not in selected and simulator_missing(key[-1]) is None:
                selected.append(key)
    selected.sort(key=lambda key: (key[-1] != "verilator", "pipelined" in key))
    with ThreadPoolExecutor(max_workers=WORKERS) as ex:
        futures = {key: ex.submit(mod.run_case, *key) for key in selected}

        def result(key):
            missing_fails(key)
            return futures[key].result()

        yield result
