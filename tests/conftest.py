"""Shared fixture of the cocotb test modules (tests/test_cocotb_*.py)."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import pytest

from ik5r.hdl.tb.runner import simulator_missing

WORKERS = int(os.environ.get("IK5R_SIM_WORKERS", "2"))


@pytest.fixture(scope="module")
def sim_pool(request):
    """Starts every selected case of the requesting module in a thread pool (each case is a
    simulator subprocess), Verilator builds first (the long poles); ``sim_pool(key)`` is the
    result of a case, and fails (never skips) when its simulator is not installed. The
    module names its case parameters in ``CASE_KEYS`` (the simulator last) and runs a case with
    ``run_case(*key)``. A case whose simulator is missing is not started: its test fails."""
    mod = request.module
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
            missing = simulator_missing(key[-1])
            if missing:
                pytest.fail(f"{missing} (CI installs both simulators)", pytrace=False)
            return futures[key].result()

        yield result
