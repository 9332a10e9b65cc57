"""The IK peripheral for LiteX users: its generated Verilog as a LiteX module.

``IK5RPeripheral(platform, constants, core="compact")`` is a ``LiteXModule`` that instantiates the
Verilog of :class:`ik5r.hdl.soc.periph.IKPeripheral` (written next to the build, added to the
platform's sources), exposes its Wishbone slave as ``bus`` and its interrupt as ``irq``, and has
two CSRs for LiteX's ``csr.h``: ``id`` (the ID magic) and ``core`` (the ``CORE`` word: kind,
width, capacity). The registers themselves are the map of :mod:`ik5r.core.regmap`, reached
through the Wishbone region ``ik5r``: LiteX's ``mem.h`` gives its base (``IK5R_BASE``), so the C
driver ``firmware_model/ik5r_hw.c`` builds unchanged with ``-DIK5R_HW_BASE=IK5R_BASE``.

A LiteX SoC adds the core in one line: ``add_ik5r(soc, constants)`` (the module, the bus region,
the interrupt when the SoC has an interrupt controller). Needs ``litex`` (the ``litex`` extra).
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from migen import ClockSignal, Instance, ResetSignal, Signal
from litex.gen import LiteXModule
from litex.soc.interconnect import wishbone
from litex.soc.interconnect.csr import CSRStatus

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import CoreArch
from ik5r.core.regmap import MAP_BYTES
from ik5r.hdl.soc.periph import ADDR_WIDTH, IKPeripheral, peripheral_verilog

__all__ = ["IK5RPeripheral", "add_ik5r", "litex_soc_sources", "MODULE"]

MODULE = "ik5r_periph"


class _Interrupt:
    """What LiteX's interrupt interconnect reads from a module: ``ev.irq``."""

    def __init__(self, irq):
        self.irq = irq


class IK5RPeripheral(LiteXModule):
    """The IK peripheral's Verilog in a LiteX design (see the module docstring)."""

    def __init__(self, platform, constants: Constants, *, core: str = CoreArch.COMPACT,
                 build_dir: str | Path = "build/ik5r_litex"):
        if not isinstance(constants, Constants):
            raise TypeError(f"constants must be an ik5r.core.fxconfig.Constants, got {constants!r}")
        periph = IKPeripheral(constants=constants, core=core)
        ids = periph.ids
        self.bus = wishbone.Interface(data_width=32, address_width=32, addressing="word")
        self.irq = Signal()
        self.ev = _Interrupt(self.irq)
        self.id = CSRStatus(32, reset=ids["ID"], description="ik5r ID magic ('IK5R')")
        self.core = CSRStatus(32, reset=ids["CORE"], description="ik5r CORE word: kind, width, capacity")
        path = Path(build_dir) / f"{MODULE}_{core}_{constants.cfg.name}.v"
        path.parent.mkdir(parents=True, exist_ok=True)
        text = peripheral_verilog(periph, name=MODULE)
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
        platform.add_source(str(path))
        self.specials += Instance(
            MODULE, i_clk=ClockSignal(), i_rst=ResetSignal(),
            i_bus__cyc=self.bus.cyc, i_bus__stb=self.bus.stb, i_bus__we=self.bus.we,
            i_bus__adr=self.bus.adr[:ADDR_WIDTH], i_bus__dat_w=self.bus.dat_w, i_bus__sel=self.bus.sel,
            o_bus__dat_r=self.bus.dat_r, o_bus__ack=self.bus.ack, o_bus__err=self.bus.err,
            o_irq=self.irq)


def add_ik5r(soc, constants: Constants, *, core: str = CoreArch.COMPACT, origin: int | None = None,
             name: str = "ik5r", build_dir: str | Path = "build/ik5r_litex") -> IK5RPeripheral:
    """Add the IK peripheral to a LiteX ``soc``: the module, its Wishbone region ``name`` (at
    ``origin``, else wherever the SoC's allocator puts it), its interrupt if the SoC has an
    interrupt controller. Returns the module."""
    from litex.soc.integration.soc import SoCRegion

    periph = IK5RPeripheral(soc.platform, constants, core=core, build_dir=build_dir)
    soc.add_module(name=name, module=periph)
    soc.bus.add_slave(name, periph.bus, SoCRegion(origin=origin, size=MAP_BYTES, cached=False))
    if hasattr(soc, "irq") and getattr(soc.irq, "enabled", False):
        soc.irq.add(name, use_loc_if_exists=True)
    return periph


def litex_soc_sources(soc, out: str | Path, name: str = "ik5r_litex") -> dict[str, Path]:
    """Finalise ``soc`` and write its Verilog (``out/gateware/<name>.v``) and LiteX's software
    headers ``out/generated/{csr,mem,soc}.h`` (no BIOS, no toolchain run); the paths by name."""
    from litex.soc.integration import export

    out = Path(out).resolve()
    (out / "gateware").mkdir(parents=True, exist_ok=True)
    (out / "generated").mkdir(parents=True, exist_ok=True)
    soc.finalize()
    paths = {"verilog": out / "gateware" / f"{name}.v", "csr.h": out / "generated" / "csr.h",
             "mem.h": out / "generated" / "mem.h", "soc.h": out / "generated" / "soc.h"}
    # LiteX writes the memories' .init files into the working directory: the gateware folder.
    with contextlib.chdir(out / "gateware"):
        soc.platform.get_verilog(soc, name=name).write(str(paths["verilog"].resolve()))
    paths["csr.h"].write_text(export.get_csr_header(soc.csr_regions, soc.constants,
                                                    csr_base=soc.mem_regions["csr"].origin))
    paths["mem.h"].write_text(export.get_mem_header(soc.mem_regions))
    paths["soc.h"].write_text(export.get_soc_header(soc.constants))
    return paths
