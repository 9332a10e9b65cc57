"""A minimal RISC-V system on chip for running the C solver on a soft CPU.

The CPU is a VexRiscv variant shipped as Verilog by the ``pythondata-cpu-vexriscv`` wheel (its
source is never copied here: :func:`cpu_verilog` reads it from the installed wheel). The SoC is
the CPU, one on-chip RAM holding program and data, and two memory-mapped registers.

Memory map (byte addresses):

- ``0x0000_0000`` .. RAM size: the RAM (code, constants, data, stack, job area); aliased above.
- ``0xF000_0000`` ``MARK`` (write): pulses the ``mark`` output with the written word; the firmware
  writes it between solves so that a simulation can time them.
- ``0xF000_0004`` ``STOP`` (write): sets the sticky ``stop`` output, the written word on
  ``stop_code``; the firmware's last act (0: finished, else an error or trap code).

- ``0xF000_1000`` .. ``0xF000_1FFF``: the IK peripheral (with ``periph``: :class:`.periph.IKPeripheral`,
  register map :mod:`ik5r.core.regmap`); its interrupt is the CPU's external interrupt 0.

Other reads of the register page return 0 (MARK and STOP alias over it). Both buses are Wishbone (classic, plus incrementing bursts
for cache-line refills, served at one word per clock; a single access takes two clocks). The RAM
is one memory with two ports: the instruction bus reads on one, the data bus reads and writes on
the other (same address: a true dual-port block RAM).
"""

from __future__ import annotations

from pathlib import Path

from amaranth.hdl import Cat, ClockSignal, Const, Instance, Module, Mux, ResetSignal, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

__all__ = ["CPUS", "SoC", "cpu_verilog", "MARK_ADDR", "STOP_ADDR", "PERIPH_ADDR"]

MARK_ADDR = 0xF000_0000
STOP_ADDR = 0xF000_0004
#: Base of the IK peripheral (ik5r.core.regmap_out.DEFAULT_BASE, the C header's IK5R_HW_BASE).
PERIPH_ADDR = 0xF000_1000

#: Soft CPUs: name -> (wheel Verilog file, ISAs it executes, description).
CPUS = {
    "vexriscv": ("VexRiscv.v", ("rv32im", "rv32i"),
                 "VexRiscv (litex 'standard'): 5-stage pipeline with bypassing, 4 KiB instruction "
                 "and 4 KiB data cache, single-cycle multiplier, iterative divider, dynamic branch "
                 "prediction (the class of a Nios II/f)"),
    "vexriscv_min": ("VexRiscv_Min.v", ("rv32i",),
                     "VexRiscv (litex 'minimal'): 5-stage pipeline without bypassing, caches, "
                     "branch prediction or multiplier (the class of a Nios II/e)"),
}


def cpu_verilog(cpu: str) -> str:
    """The Verilog text of ``cpu`` from the installed ``pythondata-cpu-vexriscv`` wheel."""
    if cpu not in CPUS:
        raise ValueError(f"cpu must be one of {tuple(CPUS)}, got {cpu!r}")
    try:
        import pythondata_cpu_vexriscv as wheel
    except ImportError as exc:
        raise RuntimeError("pythondata-cpu-vexriscv is not installed: "
                           "pip install pythondata-cpu-vexriscv (the 'dev' extra)") from exc
    return (Path(wheel.data_location) / CPUS[cpu][0]).read_text()


class _RamPort:
    """One Wishbone slave on a memory port: the address to present to the RAM this clock, the
    acknowledge and the data out. An incrementing burst read (CTI 010) is acknowledged every
    clock: while a beat is acknowledged, the RAM is already addressed with the next word."""

    def __init__(self, m: Module, bus: dict, selected, name: str):
        self.ack = Signal(name=f"{name}_ack")
        burst = (bus["CTI"] == 0b010) & ~bus["WE"]
        self.request = bus["CYC"] & bus["STB"] & selected
        self.next_word = self.ack & burst
        m.d.sync += self.ack.eq(self.request & (~self.ack | burst))


class SoC(wiring.Component):
    """VexRiscv + on-chip RAM + MARK/STOP registers (see the module docstring for the map).

    Function: runs the program in the RAM from address 0 after reset; ``hold`` keeps the CPU in
    reset (the RAM keeps its contents) while the host port reads and writes RAM words.
    Formats: 32-bit little-endian words; ``host_addr`` is a word index.
    Latency / throughput: a RAM access takes two clocks, a burst word one; a register write two.
    Ports: ``stop``/``stop_code`` (sticky, cleared while ``hold``), ``mark``/``mark_value`` (one
    clock per MARK write); with ``host_port``: ``hold``, ``host_addr``, ``host_wdata``,
    ``host_we``, ``host_rdata`` (the word at ``host_addr`` of the clock before).
    """

    def __init__(self, *, cpu: str = "vexriscv", ram_words: int = 16384, init=(),
                 host_port: bool = True, periph=None):
        if cpu not in CPUS:
            raise ValueError(f"cpu must be one of {tuple(CPUS)}, got {cpu!r}")
        if not isinstance(ram_words, int) or ram_words < 256 or ram_words & (ram_words - 1):
            raise ValueError(f"ram_words must be a power of two >= 256, got {ram_words!r}")
        init = [int(word) & 0xFFFF_FFFF for word in init]
        if len(init) > ram_words:
            raise ValueError(f"init has {len(init)} words, the RAM {ram_words}")
        from .periph import IKPeripheral

        if periph is not None and not isinstance(periph, IKPeripheral):
            raise TypeError(f"periph must be an IKPeripheral or None, got {periph!r}")
        self.cpu, self.ram_words, self.init, self.host_port = cpu, ram_words, init, bool(host_port)
        self.periph = periph
        self.addr_width = ram_words.bit_length() - 1
        members = {"stop": Out(1), "stop_code": Out(32), "mark": Out(1), "mark_value": Out(32)}
        if host_port:
            members.update(hold=In(1), host_addr=In(self.addr_width), host_wdata=In(32),
                           host_we=In(1), host_rdata=Out(32))
        super().__init__(members)

    @staticmethod
    def _bus(prefix: str) -> dict:
        widths = {"CYC": 1, "STB": 1, "ACK": 1, "WE": 1, "ADR": 30, "DAT_MISO": 32,
                  "DAT_MOSI": 32, "SEL": 4, "ERR": 1, "CTI": 3, "BTE": 2}
        return {name: Signal(width, name=f"{prefix}_{name.lower()}") for name, width in widths.items()}

    def _cpu(self, m: Module, ibus: dict, dbus: dict, hold, irq) -> None:
        ports = {}
        for prefix, bus in (("iBusWishbone", ibus), ("dBusWishbone", dbus)):
            for name, sig in bus.items():
                direction = "i" if name in ("ACK", "DAT_MISO", "ERR") else "o"
                ports[f"{direction}_{prefix}_{name}"] = sig
        m.submodules.cpu = Instance(
            "VexRiscv", i_clk=ClockSignal(), i_reset=ResetSignal() | hold,
            i_externalResetVector=Const(0, 32), i_timerInterrupt=0, i_softwareInterrupt=0,
            i_externalInterruptArray=Const(0, 32) if self.periph is None else Cat(irq, Const(0, 31)),
            **ports)

    def elaborate(self, platform):
        m = Module()
        ibus, dbus = self._bus("ibus"), self._bus("dbus")
        hold = self.hold if self.host_port else Const(0)
        io_page = dbus["ADR"][26:30] == 0xF
        periph_sel, periph_ack, periph_data, irq = self._periph(m, dbus, io_page)
        self._cpu(m, ibus, dbus, hold, irq)
        # no_rw_check: no read data is used in a clock in which its address is written (the data
        # bus ignores read data on a write, the program is not written while it runs, the host
        # port works with the CPU held), so Yosys needs no collision logic and maps the RAM on
        # ECP5 to one DP16KD set (8 for 16 KiB) instead of two.
        m.submodules.ram = ram = Memory(shape=32, depth=self.ram_words, init=self.init,
                                        attrs={"no_rw_check": 1})
        iread = ram.read_port(domain="sync")
        dread = ram.read_port(domain="sync")
        dwrite = ram.write_port(granularity=8)

        iport = _RamPort(m, ibus, Const(1), "ibus")
        dport = _RamPort(m, dbus, ~io_page, "dbus")
        io_ack = Signal()
        # Without the peripheral, the same expressions as before it existed (the same Verilog).
        io_regs = io_page if self.periph is None else io_page & ~periph_sel
        m.d.sync += io_ack.eq(dbus["CYC"] & dbus["STB"] & io_regs & ~io_ack)
        m.d.comb += [
            iread.addr.eq(ibus["ADR"] + iport.next_word),
            ibus["ACK"].eq(iport.ack), ibus["DAT_MISO"].eq(iread.data),
            dbus["ACK"].eq(dport.ack | io_ack if self.periph is None else dport.ack | io_ack | periph_ack),
            dbus["DAT_MISO"].eq(Mux(dport.ack, dread.data, 0 if self.periph is None
                                    else Mux(periph_ack, periph_data, 0))),
        ]
        daddr = Signal(self.addr_width)
        m.d.comb += [
            daddr.eq(dbus["ADR"] + dport.next_word),
            dwrite.data.eq(dbus["DAT_MOSI"]),
            dwrite.en.eq(Mux(dport.request & dbus["WE"] & ~dport.ack, dbus["SEL"], 0)),
        ]
        if self.host_port:
            with m.If(self.hold):
                m.d.comb += [daddr.eq(self.host_addr), dwrite.data.eq(self.host_wdata),
                             dwrite.en.eq(Mux(self.host_we, 0b1111, 0))]
            m.d.comb += self.host_rdata.eq(dread.data)
        m.d.comb += [dread.addr.eq(daddr), dwrite.addr.eq(daddr)]
        self._registers(m, dbus, io_regs & ~io_ack, hold)
        return m

    def _periph(self, m: Module, dbus: dict, io_page):
        """The IK peripheral on the data bus: (selected, ack, read data, irq)."""
        if self.periph is None:
            return Const(0), Const(0), Const(0, 32), Const(0)
        from .periph import ADDR_WIDTH

        m.submodules.ik = p = self.periph
        window = (PERIPH_ADDR >> 2) >> ADDR_WIDTH
        selected = io_page & (dbus["ADR"][ADDR_WIDTH:26] == window % (1 << (26 - ADDR_WIDTH)))
        m.d.comb += [p.bus.cyc.eq(dbus["CYC"] & selected), p.bus.stb.eq(dbus["STB"] & selected),
                     p.bus.we.eq(dbus["WE"]), p.bus.adr.eq(dbus["ADR"][:ADDR_WIDTH]),
                     p.bus.dat_w.eq(dbus["DAT_MOSI"]), p.bus.sel.eq(dbus["SEL"])]
        return selected, p.bus.ack, p.bus.dat_r, p.irq

    def _registers(self, m: Module, dbus: dict, io_write_ok, hold) -> None:
        write = dbus["CYC"] & dbus["STB"] & dbus["WE"] & io_write_ok
        word = dbus["ADR"][:4]
        m.d.sync += self.mark.eq(write & (word == (MARK_ADDR >> 2) % 16))
        with m.If(write & (word == (MARK_ADDR >> 2) % 16)):
            m.d.sync += self.mark_value.eq(dbus["DAT_MOSI"])
        with m.If(hold):
            m.d.sync += [self.stop.eq(0), self.stop_code.eq(0)]
        with m.Elif(write & (word == (STOP_ADDR >> 2) % 16)):
            m.d.sync += [self.stop.eq(1), self.stop_code.eq(dbus["DAT_MOSI"])]


def generate_soc(*, cpu: str = "vexriscv", ram_words: int = 16384, init=(),
                 host_port: bool = True, name: str = "ik5r_soc", periph=None) -> str:
    """Verilog of the SoC (top module ``name``) followed by the CPU's Verilog from the wheel;
    ``periph``: an :class:`.periph.IKPeripheral` on the data bus, or None."""
    from amaranth.back import verilog

    soc = SoC(cpu=cpu, ram_words=ram_words, init=init, host_port=host_port, periph=periph)
    text = verilog.convert(soc, name=name, emit_src=False)
    return text + "\n" + cpu_verilog(cpu)
