"""The Wishbone handshake of the IK peripheral (:class:`~ik5r.hdl.soc.periph.IKPeripheral`),
proved with SymbiYosys whatever the core does.

:class:`WishboneHarness` puts the real slave (its decoder, registers, queue logic) in front of a
*free core*: a component with the IK core's stream ports whose ``i.ready``, ``o.valid`` and
``o.payload`` are free values every clock (``$anyseq``), so a property proved holds for any
behaviour of any core, including one that never takes a pose or never gives a result. The master
is free too (any ``cyc``, ``stb``, ``we``, ``adr``, ``dat_w``, ``sel`` each clock, reset in any
clock), with the rules of the classic protocol assumed: a master holds its request (``cyc``,
``stb``, ``we``, ``adr``, ``dat_w``, ``sel``) until acknowledged, and ends its cycle after an
acknowledgement (``stb`` low in the next clock), which makes "one acknowledgement per request"
observable. Proved by k-induction (every reachable state):

* ``ack_only_on_request``: ``ack`` only in a clock with ``cyc & stb`` (none without a request,
  none twice for one request);
* ``request_acknowledged``: a request waits at most :data:`MAX_WAIT` clocks for its ``ack`` (a
  write none, a read one);
* ``no_err``: ``err`` never rises (unmapped offsets are acknowledged with a defined value);
* ``irq_means_result``: the interrupt is high only while a result waits.

``mutation`` injects a fault between the slave and the checker, each must break the proof:
``late_ack`` (the acknowledgement one clock late), ``stretched_ack`` (held one clock too long),
``wait_on_core`` (the slave waits for the core to take a pose before acknowledging: with a core
that never does, the bus hangs), ``spurious_ack`` (an acknowledgement in a free clock).
"""

from __future__ import annotations

import os
import time

from amaranth.back import rtlil
from amaranth.hdl import Assert, Assume, Cat, Module, Signal, unsigned
from amaranth.hdl._ast import AnySeq
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ik5r.core import regmap as R
from ik5r.core.fxconfig import constants, load_config
from ik5r.core.modes import CoreArch

from ..pipelined.core import core_fields
from ..soc.periph import ADDR_WIDTH, IKPeripheral

__all__ = ["FreeCore", "WishboneHarness", "MUTATIONS", "MAX_WAIT", "prove_wishbone"]

MUTATIONS = ("late_ack", "stretched_ack", "wait_on_core", "spurious_ack")
#: Clocks a request may wait for its acknowledgement (a read's one wait state).
MAX_WAIT = 1
INDUCTION_DEPTH = 4


class FreeCore(wiring.Component):
    """The IK core's ports (payloads of ``constants``, an 8-bit tag) with free outputs."""

    def __init__(self, constants, capacity: int = 3):
        in_fields, out_fields = core_fields(constants)
        ins = {name: shape for name, (shape, _, _) in in_fields.items()} | {"tag": unsigned(R.TAG_BITS)}
        outs = {name: shape for name, (shape, _, _) in out_fields.items()} | {"tag": unsigned(R.TAG_BITS)}
        self.capacity, self.latency, self.cycles_per_result = capacity, 1, 1
        super().__init__({"i": In(stream.Signature(data.StructLayout(ins))),
                          "o": Out(stream.Signature(data.StructLayout(outs)))})

    def elaborate(self, platform):
        m = Module()
        m.d.comb += [self.i.ready.eq(AnySeq(1)), self.o.valid.eq(AnySeq(1)),
                     self.o.payload.eq(AnySeq(self.o.payload.shape().size))]
        return m


class _FreeCorePeripheral(IKPeripheral):
    def _make_core(self, constants, kind, dsp):
        return FreeCore(constants)


class WishboneHarness(wiring.Component):
    """The slave with a free core, a free master and the assertions (module docstring)."""

    def __init__(self, *, config: str = "q18", mutation: str | None = None):
        if mutation not in (None, *MUTATIONS):
            raise ValueError(f"mutation must be one of {MUTATIONS} or None, got {mutation!r}")
        self.mutation = mutation
        self.dut = _FreeCorePeripheral(constants=constants(load_config(config)), core=CoreArch.COMPACT)
        self.assert_names = {}
        super().__init__({"cyc": In(1), "stb": In(1), "we": In(1), "adr": In(ADDR_WIDTH),
                          "dat_w": In(32), "sel": In(4), "glitch": In(1)})

    @property
    def ports(self):
        return [self.cyc, self.stb, self.we, self.adr, self.dat_w, self.sel, self.glitch]

    def _assert(self, test, name: str):
        check = Assert(test, name, src_loc_at=1)
        self.assert_names[(os.path.basename(check.src_loc[0]), check.src_loc[1])] = name
        return check

    def _seen_ack(self, m, ack, err):
        """The acknowledgement as the checker sees it: the slave's, or the injected fault's."""
        seen = Signal()
        late = Signal()
        m.d.sync += late.eq(ack)
        fault = {None: ack, "late_ack": late, "stretched_ack": ack | late,
                 "wait_on_core": ack & (~(self.we & (self.adr == R.by_name("CTRL").offset // 4))
                                        | self.dut.core.i.ready),
                 "spurious_ack": ack | self.glitch}[self.mutation]
        m.d.comb += seen.eq(fault | err)
        return seen

    def elaborate(self, platform):
        m = Module()
        m.submodules.dut = dut = self.dut
        bus = dut.bus
        m.d.comb += [bus.cyc.eq(self.cyc), bus.stb.eq(self.stb), bus.we.eq(self.we), bus.adr.eq(self.adr),
                     bus.dat_w.eq(self.dat_w), bus.sel.eq(self.sel)]
        ack = self._seen_ack(m, bus.ack, bus.err)
        request = self.cyc & self.stb
        acked = Signal()            # the previous clock acknowledged a request
        waited = Signal(range(MAX_WAIT + 2))
        m.d.sync += acked.eq(ack & request)
        m.d.sync += waited.eq(0)
        with m.If(request & ~ack & (waited <= MAX_WAIT)):
            m.d.sync += waited.eq(waited + 1)
        held = Signal()             # the previous clock had a request without ack
        m.d.sync += held.eq(request & ~ack)
        previous = [Signal.like(v, name=f"prev_{v.name}") for v in (self.we, self.adr, self.dat_w, self.sel)]
        m.d.sync += [p.eq(v) for p, v in zip(previous, (self.we, self.adr, self.dat_w, self.sel))]
        same = Cat(*(p == v for p, v in zip(previous, (self.we, self.adr, self.dat_w, self.sel)))).all()
        m.d.comb += [
            Assume(~held | (request & same)),     # the master holds a request until its ack
            Assume(~acked | ~self.stb),           # the master ends its cycle after an ack
            self._assert(~ack | request, "ack_only_on_request"),
            self._assert(~request | ack | (waited < MAX_WAIT), "request_acknowledged"),
            self._assert(~bus.err, "no_err"),
            self._assert(~dut.irq | dut.core.o.valid, "irq_means_result"),
        ]
        return m


def prove_wishbone(config: str = "q18", mutation: str | None = None, depth: int = INDUCTION_DEPTH,
                   workdir=None) -> dict:
    """The handshake proof (k-induction to ``depth``): {"status": PASS/FAIL/..., "failed": [...]}."""
    from .run import _run_sby

    start = time.monotonic()
    top = WishboneHarness(config=config, mutation=mutation)
    text = rtlil.convert(top, name="top", platform="formal", ports=top.ports)
    status, detail, failed, cpu = _run_sby(text, top.assert_names, "prove", depth, "memory_map\nopt -fast\n",
                                           workdir, f"wishbone-{mutation or 'ok'}", traces=mutation is None)
    return {"component": "ik5r.hdl.soc.periph.IKPeripheral (free core)", "config": config,
            "mutation": mutation, "method": "k-induction", "depth": depth, "status": status,
            "failed": failed, "detail": detail, "seconds": round(time.monotonic() - start, 1),
            "process_seconds": cpu}


def main(argv=None) -> int:
    """``python -m ik5r.hdl.formal.wishbone [--config q18] [--json FILE]``: the proof and every
    injected fault; exit 0 when the proof passes and every fault breaks it."""
    import argparse
    import json
    from pathlib import Path

    parser = argparse.ArgumentParser(prog="python -m ik5r.hdl.formal.wishbone", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", default="q18")
    parser.add_argument("--json", default=None, metavar="FILE")
    args = parser.parse_args(argv)
    results = [prove_wishbone(args.config, mutation) for mutation in (None, *MUTATIONS)]
    for r in results:
        print(f"{r['mutation'] or 'proof'}: {r['status']} {', '.join(r['failed'])} ({r['seconds']} s)")
    if args.json:
        Path(args.json).write_text(json.dumps({"results": results}, indent=1) + "\n")
    ok = results[0]["status"] == "PASS" and all(r["status"] == "FAIL" for r in results[1:])
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
