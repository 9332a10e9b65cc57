"""The IK peripheral's Wishbone handshake (hdl/formal/wishbone.py), by k-induction with a free
core and a free master: every request acknowledged within one clock, no acknowledgement without one,
no ERR; each injected fault breaks the proof on the assertion it violates."""

from __future__ import annotations

import pytest

from ik5r.hdl.formal.wishbone import MUTATIONS, prove_wishbone

BROKEN = {"late_ack": "request_acknowledged", "wait_on_core": "request_acknowledged",
          "stretched_ack": "ack_only_on_request", "spurious_ack": "ack_only_on_request"}


def test_handshake_is_proved_whatever_the_core_does():
    r = prove_wishbone("q18")
    assert r["status"] == "PASS", r["detail"]


@pytest.mark.parametrize("mutation", [pytest.param(m, marks=pytest.mark.slow)
                                      if m in ("late_ack", "spurious_ack") else m for m in MUTATIONS])
def test_injected_fault_breaks_the_proof(mutation):
    r = prove_wishbone("q18", mutation)
    assert r["status"] == "FAIL" and BROKEN[mutation] in r["failed"], r
