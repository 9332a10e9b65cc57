"""The IK peripheral in the soft-CPU SoC (Verilator): one firmware solves every pose on the
hardware (ik5r_hw_solve, the driver) and in software (ik5r_solve), and every word of the two is
equal, and equal to the model and the host C; each call is timed from the CPU's side. The driver
compiles warning-free for the host and rv32im, and its build switch routes ik5r_solve.

Default run: q18, the compact core, 56 random poses + the directed set. Slow run (make test-slow):
q32w, both cores, 2,000 random poses + the directed set.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from ik5r.core.fxconfig import constants, load_config
from ik5r.tools.cli import main
from ik5r.tools.commands.firmware import measure

SOURCE = Path(__file__).resolve().parents[1] / "firmware_model"


def _check(r: dict, vectors: int) -> None:
    assert r["vectors"] >= vectors
    assert r["mismatches"] == 0 and r["differing_bits_vs_model"] == 0, r
    assert r["differing_words_hw_vs_sw"] == 0 and r["mismatches_hw_vs_sw"] == 0, r
    assert r["differing_words_irq_vs_sw"] == 0, r
    calls, core = r["call_cycles"], r["core_latency_cycles"]
    # A call waits for the core and moves 14 words in and 6 out, at least a clock each.
    assert core + 20 <= calls["min"] <= calls["mean"] <= calls["max"]
    assert r["bus_overhead_cycles"]["mean"] == pytest.approx(calls["mean"] - core)


def test_hardware_and_software_paths_agree_on_every_word_q18_compact():
    r = measure(constants(load_config("q18")), cpu="vexriscv", isa="rv32im", vectors=56, seed=7,
                peripheral="compact")
    _check(r, 56 + 300)
    assert r["peripheral"] == "compact" and r["core_cycles_per_result"] < r["core_latency_cycles"]


def test_cli_peripheral_json(tmp_path, capsys):
    out = tmp_path / "fw.json"
    assert main(["firmware", "--config", "q18", "--peripheral", "compact", "--vectors", "8",
                 "--no-directed", "-q", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    for key in ("call_cycles", "bus_overhead_cycles", "core_latency_cycles", "bus_share",
                "differing_words_hw_vs_sw", "cycles_per_solve", "mismatches"):
        assert key in r
    assert r["vectors"] == 8 and r["cycles_per_solve"]["mean"] == r["call_cycles"]["mean"]
    assert "0 differing words hardware vs software" in capsys.readouterr().out
    # The record names the SoC Verilog it ran: this checkout's for its CPU, RAM, core and config,
    # not that of the SoC without the core.
    from ik5r.tools.softcpu import firmware_verilog_sha256

    assert r["verilog_sha256"] == firmware_verilog_sha256(r)
    assert r["verilog_sha256"] != firmware_verilog_sha256({**r, "peripheral": None})


def _host_compile(tmp_path: Path, *flags: str) -> Path:
    from ik5r.core.cbuild import compiler
    from ik5r.core.regmap_out import c_header
    from ik5r.firmware_model.codegen import generate_header

    (tmp_path / "ik5r_regs.h").write_text(c_header())
    (tmp_path / "ik5r_config.h").write_text(generate_header(constants(load_config("q32w"))))
    (tmp_path / "use.c").write_text(
        '#include "ik5r.h"\n#include "ik5r_hw.h"\n'
        "uint32_t call(const int32_t p[3], const int32_t a[3], int32_t q[5]);\n"
        "uint32_t call(const int32_t p[3], const int32_t a[3], int32_t q[5])\n"
        "{\n    return ik5r_solve(p, a, 0, 0, 0, 0, 0, 0, q);\n}\n")
    objects = []
    for name in ("ik5r_hw.c", "use.c"):
        obj = tmp_path / (name[:-2] + ".o")
        src = SOURCE / name if name != "use.c" else tmp_path / name
        proc = subprocess.run([compiler(), "-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-O2",
                               *flags, "-I", str(tmp_path), "-I", str(SOURCE), "-c", str(src), "-o", str(obj)],
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        objects.append(obj)
    return objects[1]


def test_driver_compiles_warning_free_and_the_switch_picks_the_path(tmp_path):
    """-Werror on the host (the rv32im build is the SoC run's); with IK5R_SOLVER_HW a call of
    ik5r_solve is a call of ik5r_hw_solve, without it the software solver's."""
    (tmp_path / "hw").mkdir()
    (tmp_path / "sw").mkdir()
    hardware = _host_compile(tmp_path / "hw", "-DIK5R_SOLVER_HW")
    software = _host_compile(tmp_path / "sw")
    undefined = {}
    for name, obj in (("hw", hardware), ("sw", software)):
        out = subprocess.run(["nm", "-u", str(obj)], capture_output=True, text=True, check=True).stdout
        undefined[name] = {line.split()[-1] for line in out.splitlines()}
    assert "ik5r_hw_solve" in undefined["hw"] and "ik5r_solve" not in undefined["hw"]
    assert "ik5r_solve" in undefined["sw"] and "ik5r_hw_solve" not in undefined["sw"]


def test_soc_with_peripheral_is_verilator_lint_clean(tmp_path):
    from amaranth.back import verilog

    from ik5r.hdl.soc.periph import IKPeripheral
    from ik5r.hdl.soc.system import SoC, cpu_verilog
    from ik5r.tools.softcpu import verilator

    periph = IKPeripheral(constants=constants(load_config("q18")), core="compact")
    (tmp_path / "ik5r_soc.v").write_text(
        verilog.convert(SoC(cpu="vexriscv", ram_words=256, periph=periph), name="ik5r_soc", emit_src=False))
    text = cpu_verilog("vexriscv")
    header = text[text.index("module VexRiscv ("):]
    header = header[:header.index(");") + 2].replace("output reg", "output")
    (tmp_path / "VexRiscv.v").write_text("/* verilator lint_off UNUSEDSIGNAL */\n"
                                          "/* verilator lint_off UNDRIVEN */\n" + header + "\nendmodule\n")
    vlt = Path(__file__).resolve().parents[1] / "hdl" / "verilator.vlt"
    proc = subprocess.run([verilator(), "--lint-only", "-Wall", str(vlt), "ik5r_soc.v", "VexRiscv.v",
                           "--top-module", "ik5r_soc"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("core", ("compact", "pipelined"))
def test_both_paths_large_q32w(core):
    r = measure(constants(load_config("q32w")), cpu="vexriscv", isa="rv32im", vectors=2000, seed=1,
                peripheral=core)
    print(f"{core}: {r['vectors']} poses, {r['differing_words_hw_vs_sw']} differing words, call "
          f"{r['call_cycles']}, overhead {r['bus_overhead_cycles']}")
    _check(r, 2000 + 300)
