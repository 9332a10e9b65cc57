"""ik5r.tools.litex: a LiteX SoC (VexRiscv, no UART) adds the IK peripheral in one line; its
Verilog instantiates the generated peripheral, LiteX's csr.h and mem.h name it, and the C driver
compiles warning-free (rv32im, -Werror, strict C99) against those headers, its base LiteX's."""

from __future__ import annotations

import subprocess
from pathlib import Path

from ik5r.core.fxconfig import constants, load_config

SOURCE = Path(__file__).resolve().parents[1] / "firmware_model"


def _soc():
    from litex.build.generic_platform import GenericPlatform, Pins
    from litex.soc.integration.soc_core import SoCCore
    from migen.genlib.io import CRG

    platform = GenericPlatform("ik5r-test", [("sys_clk", 0, Pins(1)), ("sys_rst", 0, Pins(1))])
    soc = SoCCore(platform, clk_freq=int(50e6), cpu_type="vexriscv", integrated_rom_size=0x8000,
                  integrated_main_ram_size=0x4000, with_uart=False)
    soc.crg = CRG(platform.request("sys_clk"), platform.request("sys_rst"))
    return soc


def test_litex_soc_adds_the_core_in_one_line_and_the_driver_compiles(tmp_path):
    import litex

    from ik5r.core.regmap import ID_MAGIC
    from ik5r.core.regmap_out import c_header
    from ik5r.firmware_model import rv32
    from ik5r.firmware_model.codegen import generate_header
    from ik5r.tools.litex import MODULE, add_ik5r, litex_soc_sources

    k = constants(load_config("q18"))
    soc = _soc()
    periph = add_ik5r(soc, k, build_dir=tmp_path / "ik5r")          # the one line
    paths = litex_soc_sources(soc, tmp_path / "soc")
    assert not list(Path.cwd().glob("ik5r_litex_*.init"))      # written beside the Verilog instead
    assert list(paths["verilog"].parent.glob("ik5r_litex_*.init"))
    verilog = paths["verilog"].read_text()
    assert f"{MODULE} {MODULE}(" in verilog
    source = next((tmp_path / "ik5r").glob("*.v")).read_text()
    assert source.startswith(f"// {MODULE}: ik5r generated Verilog") and f"module {MODULE}(" in source
    mem, csr = paths["mem.h"].read_text(), paths["csr.h"].read_text()
    assert "#define IK5R_BASE" in mem and "#define CSR_IK5R_ID_ADDR" in csr
    assert periph.id.status.reset.value == ID_MAGIC
    (tmp_path / "ik5r_regs.h").write_text(c_header())
    (tmp_path / "ik5r_config.h").write_text(generate_header(k))
    (tmp_path / "main.c").write_text(
        "#include <generated/csr.h>\n#include <generated/mem.h>\n#include \"ik5r.h\"\n#include \"ik5r_hw.h\"\n"
        "int probe(void);\nint probe(void)\n{\n"
        "    return ik5r_id_read() == 0x494B3552u && ik5r_hw_probe() == 0;\n}\n")
    include = Path(litex.__file__).parent / "soc" / "software" / "include"
    cpu_include = Path(litex.__file__).parent / "soc" / "cores" / "cpu" / "vexriscv"
    strict = list(rv32.CFLAGS)
    # LiteX's own headers (csr.h includes the CPU's system.h) use GNU C's asm: the file that
    # includes them is built as GNU C99, the driver as strict C99.
    gnu = [f for f in strict if f not in ("-std=c99", "-pedantic")] + ["-std=gnu99"]
    for name, src, flags in (("main", tmp_path / "main.c", gnu), ("ik5r_hw", SOURCE / "ik5r_hw.c", strict)):
        proc = subprocess.run(
            [rv32.tool("gcc"), "--specs=picolibc.specs", "-march=rv32im", *flags, "-DIK5R_HW_BASE=IK5R_BASE",
             "-include", str(paths["mem.h"]), "-I", str(tmp_path), "-I", str(SOURCE), "-I", str(tmp_path / "soc"),
             "-I", str(include), "-I", str(cpu_include), "-c", str(src), "-o", str(tmp_path / f"{name}.o")],
            capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
    # The driver's base is LiteX's: the ID register's address is IK5R_BASE + 0x58.
    base = int(mem.split("#define IK5R_BASE ")[1].split()[0].rstrip("L"), 16)
    dump = subprocess.run([rv32.tool("objdump"), "-d", str(tmp_path / "ik5r_hw.o")], capture_output=True,
                          text=True, check=True).stdout
    assert f",0x{base >> 12:x}" in dump
