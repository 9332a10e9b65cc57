"""The IK core as a Wishbone B4 (classic) slave: the peripheral of the soft CPU.

The register decoder is built from the register map written once as data,
:data:`ik5r.core.regmap.REGISTERS` (offsets, access types, fields, actions); the C header, the
JSON map, the SVD and the README table come from the same data (:mod:`ik5r.core.regmap_out`).
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Module, Mux, Signal, Value, unsigned
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

import ik5r
from ik5r.core import regmap as R
from ik5r.core.fxconfig import Constants
from ik5r.core.modes import CoreArch, Dsp

__all__ = ["WishboneSignature", "IKPeripheral", "PERIPHERAL_CORES", "ADDR_WIDTH", "generate_peripheral",
           "peripheral_verilog"]

#: Cores the peripheral wraps (``CORE.KIND`` of the map).
PERIPHERAL_CORES = tuple(map(str, R.CORE_KINDS))
#: Word-address bits the slave decodes (its window: :data:`ik5r.core.regmap.MAP_BYTES`).
ADDR_WIDTH = (R.MAP_BYTES // 4 - 1).bit_length()
_POSE_FIELDS = ("px", "py", "pz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz", "q5_default")


class WishboneSignature(wiring.Signature):
    """Wishbone B4 classic, 32-bit data, byte lanes, word addresses, seen from the master."""

    def __init__(self, addr_width: int):
        super().__init__({"cyc": Out(1), "stb": Out(1), "we": Out(1), "adr": Out(unsigned(addr_width)),
                          "dat_w": Out(32), "sel": Out(4), "dat_r": In(32), "ack": In(1), "err": In(1)})


def _core(constants: Constants, kind: str, dsp: str):
    if kind == CoreArch.COMPACT:
        from ..sequenced.engine import SequencedIKCore
        return SequencedIKCore(constants=constants, tag_width=R.TAG_BITS)
    from ..pipelined.core import IKCore
    return IKCore(constants=constants, arch=CoreArch.PIPELINED, tag_width=R.TAG_BITS, dsp=dsp)


def _pack(register: R.Register, values: dict):
    """The register's read word from {field name: value} (missing fields read 0)."""
    word = Const(0, 32)
    for f in register.fields:
        if f.name in values:
            value = Value.cast(values[f.name]).as_unsigned()
            word = word | (Cat(value, Const(0, f.bits))[:f.bits] << f.lsb)
    return word[:32]


def _field(register: str, field: str) -> R.Field:
    return next(f for f in R.by_name(register).fields if f.name == field)


def _lanes(sel) -> object:
    return Cat(*(bit.replicate(8) for bit in sel))


class IKPeripheral(wiring.Component):
    """The IK core behind a Wishbone B4 classic slave, with a result queue and an interrupt.

    Function: the CPU writes a pose (``PX``..``Q5_DEFAULT``) and ``CTRL`` with ``START``; the pose
    is copied into an input register, from which the core takes it (the registers may be rewritten
    at once for the next pose); results wait at the core's output (``RESULT``, ``Q1``..``Q5``),
    and reading ``Q5`` takes one off. Misuse is defined in :mod:`ik5r.core.regmap`.
    Formats: 32-bit registers, word addresses ``bus.adr`` (offset / 4) in a window of
    :data:`ADDR_WIDTH` bits; pose and joint words are the config's signed words (low W bits
    written, joints sign-extended), status bits of :mod:`ik5r.core.status`.
    Latency: a write is acknowledged in the clock of its request, a read in the next (one wait
    state, its data registered), whatever the core does; ``err`` is never raised. A pose's result
    is valid ``core.latency`` (+ 1 for the input register) clocks after its ``START``.
    Throughput: the compact core one pose per ``core.cycles_per_result`` clocks (holding up to 3),
    the pipelined core one pose per clock (holding ``core.capacity``, its output FIFO the queue).
    Ports: ``bus`` (:class:`WishboneSignature`, slave side), ``irq`` (level: ``IRQ_ENABLE.DONE``
    and a result waiting).
    """

    def __init__(self, *, constants: Constants, core: str = CoreArch.COMPACT, dsp: str = Dsp.GENERIC):
        if not isinstance(constants, Constants):
            raise TypeError(f"constants must be an ik5r.core.fxconfig.Constants, got {constants!r}")
        if core not in PERIPHERAL_CORES:
            raise ValueError(f"core must be one of {PERIPHERAL_CORES}, got {core!r}")
        self.constants, self.kind = constants, core
        self.core = self._make_core(constants, core, dsp)
        self.capacity = self.core.capacity + 1          # + the input register
        self.latency = self.core.latency + 1
        self.ids = R.id_values(constants, ik5r.__version__, core, self.capacity)
        super().__init__({"bus": In(WishboneSignature(ADDR_WIDTH)), "irq": Out(1)})

    def _make_core(self, constants: Constants, kind: str, dsp: str):
        """The core behind the registers (the formal harness puts a free one here)."""
        return _core(constants, kind, dsp)

    def elaborate(self, platform):
        m = Module()
        m.submodules.core = core = self.core
        bus = self.bus
        # A request acts in its first clock. A write is acknowledged in that clock; a read in the
        # next, with its data registered (a combinational read path from the CPU's address to its
        # data register was the SoC's critical path). The master holds a request until its ack.
        request = bus.cyc & bus.stb
        read_wait = Signal()
        write, read = request & bus.we, request & ~bus.we & ~read_wait
        m.d.sync += read_wait.eq(read)
        access = write | read
        m.d.comb += [bus.ack.eq(write | (request & ~bus.we & read_wait)), bus.err.eq(0)]
        word = {r.name: bus.adr == r.offset // 4 for r in R.REGISTERS}
        hit = {name: access & selected for name, selected in word.items()}
        mapped = Cat(*hit.values()).any()
        lanes = _lanes(bus.sel)

        pose = {r.name: Signal(32, name=f"reg_{r.name.lower()}") for r in R.POSE_REGISTERS}
        flags, irq_enable, events = Signal(3), Signal(1), Signal(5)
        # The flags a START takes are those of its own CTRL write.
        new_flags = Signal(3)
        m.d.comb += new_flags.eq(Mux(write & hit["CTRL"], (flags & ~lanes[:3]) | (bus.dat_w & lanes)[:3], flags))
        m.d.sync += flags.eq(new_flags)
        for name, reg in (*pose.items(), ("IRQ_ENABLE", irq_enable)):
            with m.If(write & hit[name]):
                m.d.sync += reg.eq((reg & ~lanes[:len(reg)]) | (bus.dat_w & lanes)[:len(reg)])

        start_bit = _field("CTRL", "START").lsb
        start = write & hit["CTRL"] & bus.dat_w[start_bit] & bus.sel[start_bit // 8]
        accepted, pop, tag, pending = self._queue(m, core, pose, new_flags, start, read & hit["Q5"])
        seen = Signal()
        m.d.sync += seen.eq(core.o.valid & ~pop)
        set_events = Cat(core.o.valid & ~seen, start & ~accepted, read & hit["Q5"] & ~core.o.valid,
                         write & Cat(*(hit[r.name] for r in R.REGISTERS if r.access == "RO")).any(),
                         access & ~mapped)
        clear = Mux(write & hit["EVENTS"], (bus.dat_w & lanes)[:5], 0)
        m.d.sync += events.eq((events & ~clear) | set_events)
        m.d.comb += self.irq.eq(irq_enable & core.o.valid)

        values = self._read_values(core, pose, flags, irq_enable, events, tag, pending)
        with m.If(read):
            m.d.sync += bus.dat_r.eq(0)
            for name, value in values.items():
                with m.If(word[name]):
                    m.d.sync += bus.dat_r.eq(value)
        return m

    def _queue(self, m, core, pose, flags, start, pop_read):
        """The input register in front of the core and the count of poses inside."""
        held = Signal(core.i.payload.shape())
        full = Signal()
        tag = Signal(R.TAG_BITS)
        pending = Signal(range(self.capacity + 1))
        accepted = ~full | core.i.ready
        pop = pop_read & core.o.valid
        m.d.comb += [core.i.payload.eq(held), core.i.valid.eq(full), core.o.ready.eq(pop)]
        with m.If(core.i.valid & core.i.ready):
            m.d.sync += full.eq(0)
        with m.If(start & accepted):
            names = dict(zip(_POSE_FIELDS, pose.values()))
            m.d.sync += [getattr(held, name).eq(reg[:self.constants.cfg.width]) for name, reg in names.items()]
            m.d.sync += [held.has_roll.eq(flags[0]), held.shoulder_back.eq(flags[1]),
                         held.elbow_down.eq(flags[2]), held.tag.eq(tag), tag.eq(tag + 1), full.eq(1)]
        m.d.sync += pending.eq(pending + (start & accepted) - pop)
        return accepted, pop, tag, pending

    def _read_values(self, core, pose, flags, irq_enable, events, tag, pending) -> dict:
        out = core.o.payload
        valid = core.o.valid

        def joint(j):
            return Mux(valid, getattr(out, f"q{j}").as_signed(), 0)

        result = _pack(R.by_name("RESULT"), {
            "STATUS": Mux(valid, out.status, 0), "TAG": Mux(valid, out.tag, 0), "PENDING": pending,
            "BUSY": pending > valid, "VALID": valid})
        values = {name: reg for name, reg in pose.items()}
        values.update({"CTRL": flags, "RESULT": result, "EVENTS": events, "IRQ_ENABLE": irq_enable})
        values.update({f"Q{j}": joint(j) for j in range(1, 6)})
        values.update({name: Const(value, 32) for name, value in self.ids.items()})
        return values


def generate_peripheral(constants: Constants, core: str = CoreArch.COMPACT, *, name: str = "ik5r_periph") -> str:
    """Verilog of the peripheral alone (top module ``name``: ports ``clk``, ``rst``, ``bus__*``,
    ``irq``), with a header comment saying what it is (no time stamp: deterministic)."""
    return peripheral_verilog(IKPeripheral(constants=constants, core=core), name=name)


def peripheral_verilog(periph: IKPeripheral, *, name: str = "ik5r_periph") -> str:
    """Verilog of ``periph`` (see :func:`generate_peripheral`)."""
    from amaranth.back import verilog

    from ..provenance import HEADER_END, config_hash, source_commit, tool_versions

    constants, core = periph.constants, periph.kind
    body = verilog.convert(periph, name=name, emit_src=False)
    tools = tool_versions()
    lines = [f"{name}: ik5r generated Verilog, do not edit: the IK core ({core}) as a Wishbone B4 "
             "classic slave (ik5r.hdl.soc.periph.IKPeripheral; register map ik5r.core.regmap)",
             f"config: {constants.cfg.name} (numbers and arm: sha256 {config_hash(constants)}); "
             f"ID words {', '.join(f'{k} 0x{v:08X}' for k, v in periph.ids.items())}",
             f"core latency {periph.core.latency} cycles, cycles per result {periph.core.cycles_per_result}, "
             f"capacity {periph.capacity} poses",
             f"tools: amaranth {tools['amaranth']}; yosys {tools['yosys']}", f"source: {source_commit()}"]
    return "".join(f"// {line}\n" for line in lines) + HEADER_END + body
