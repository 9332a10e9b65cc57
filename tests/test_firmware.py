"""The C solver cross-compiled for RV32IM / RV32I and run on the simulated VexRiscv SoC: every
bit of joints and status equal to the vectorised model and the host C; cycles measured; a hung
CPU caught by the cycle limit; missing tools give one line and exit 2.

The default run shares one Verilator build (the vexriscv SoC) between its cases: >= 50 random
poses per config and ISA (RV32I code runs on the same CPU: the cost of software multiply alone).
The slow run: >= 2,000 random poses + the directed set per config and ISA, RV32I on the
multiplier-less vexriscv_min.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ik5r.core.fxconfig import constants, load_config
from ik5r.tools.cli import main
from ik5r.tools.commands.firmware import measure
from ik5r.tools.softcpu import SoftCpu, SoftCpuError

CONFIGS = ("q32w", "q18")


def _check(r: dict, vectors: int) -> None:
    assert r["vectors"] >= vectors
    assert r["mismatches"] == 0 and r["differing_bits_vs_model"] == 0, r
    cycles = r["cycles_per_solve"]
    # Every solve runs the IK (thousands of instructions), each instruction at least one cycle.
    assert 1_000 < r["instructions_per_solve"]["mean"] <= cycles["mean"] <= cycles["max"]
    # The whole run (start-up and the solves) retires at least the solves' instructions, one per
    # cycle at most.
    solved = r["instructions_per_solve"]["mean"] * r["vectors"]
    assert solved < r["simulated_instructions"] <= r["simulated_cycles"]
    assert 0 < r["code_bytes"] < 16_384 and 0 < r["data_bytes"] < 4_096


@pytest.mark.parametrize("isa", ("rv32im", "rv32i"))
@pytest.mark.parametrize("config", CONFIGS)
def test_bit_exact_on_vexriscv(config, isa):
    r = measure(constants(load_config(config)), cpu="vexriscv", isa=isa, vectors=56, seed=5,
                directed=False)
    _check(r, 56)


def test_rv32i_has_no_multiply_instruction():
    """The RV32I build calls libgcc's software multiply (and its cost shows in cycles)."""
    from ik5r.firmware_model import rv32

    k = constants(load_config("q32w"))
    symbols = {}
    for isa in ("rv32im", "rv32i"):
        fw = rv32.build(k, isa)
        out = subprocess.run([rv32.tool("objdump"), "-d", str(fw.elf)], capture_output=True,
                             text=True, check=True).stdout
        symbols[isa] = out
    mul_ops = ("\tmul\t", "\tmulh\t", "\tmulhu\t", "\tmulhsu\t")
    assert any(op in symbols["rv32im"] for op in mul_ops)
    assert not any(op in symbols["rv32i"] for op in mul_ops)
    assert "<__muldi3>:" in symbols["rv32i"]


def test_hung_cpu_is_caught_by_the_cycle_limit():
    k = constants(load_config("q32w"))
    from ik5r.firmware_model import vectors

    soft = SoftCpu(k, isa="rv32im", cpu="vexriscv", cycles_per_solve_limit=100)
    poses = vectors.random_poses(k, 1, 3)[:2]
    with pytest.raises(SoftCpuError, match="hung: no STOP write within the cycle limit"):
        soft.solve_batch(*poses.args())


def test_jobs_side_by_side_keep_the_pose_order():
    """Jobs of 3 poses on two simulator processes at once give every word and every solve's
    cycle count in pose order: the same as the same jobs one after the other (the simulation is
    deterministic), and the model's words."""
    from ik5r.firmware_model import vector, vectors

    k = constants(load_config("q32w"))
    poses = vectors.random_poses(k, 8, 21)[:8]
    runs = []
    for jobs in (2, 1):
        soft = SoftCpu(k, isa="rv32im", cpu="vexriscv", jobs=jobs)
        soft.job_poses = 3
        runs.append((soft, *soft.solve_batch(*poses.args())))
    (side, q, status), (serial, q1, status1) = runs
    q_model, status_model = vector.solve_batch(k, *poses.args())
    np.testing.assert_array_equal(q, q_model)
    np.testing.assert_array_equal(status, status_model)
    np.testing.assert_array_equal(q1, q_model)
    assert len(side.stats.cycles) == 8 and side.stats.cycles == serial.stats.cycles
    assert side.stats.total_cycles == serial.stats.total_cycles and side.stats.sim_cpu_seconds > 0


def test_early_stop_is_reported():
    """A STOP with fewer solves done than asked (here: a job's output as the harness writes it,
    the CPU having stopped after 1 of 2 solves) is an error, as is a trap code."""
    k = constants(load_config("q32w"))
    soft = SoftCpu(k, isa="rv32im", cpu="vexriscv")
    marks = [[10, 0, 5, 0, 0xFFFFFFFF], [12, 0, 6, 0, 0xFFFFFFFF], [14, 0, 7, 0, 0], [900, 0, 800, 0, 1]]
    out = [0, 0, 1000, 0, 900, 0, len(marks), *np.ravel(marks), 1] + [0] * (2 * 14 + 2 * 6)
    with pytest.raises(SoftCpuError, match="stopped early: 1 of 2 solves"):
        soft._parse(np.array(out, dtype=np.int64), 2, 10**6)
    out[1] = 0xBAD00002
    with pytest.raises(SoftCpuError, match="code 0xbad00002 \\(CPU trap\\)"):
        soft._parse(np.array(out, dtype=np.int64), 2, 10**6)


def test_cli_json_and_missing_cross_compiler(tmp_path, capsys):
    out = tmp_path / "fw.json"
    assert main(["firmware", "--config", "q18", "--vectors", "8", "--no-directed", "--cpu",
                 "vexriscv", "-q", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    for key in ("cpu", "isa", "config", "vectors", "mismatches", "cycles_per_solve",
                "instructions_per_solve", "code_bytes", "data_bytes", "sim_seconds"):
        assert key in r
    assert r["cpu"] == "vexriscv" and r["isa"] == "rv32im" and r["vectors"] == 8
    assert set(r["cycles_per_solve"]) >= {"mean", "max"}
    assert "0 mismatches" in capsys.readouterr().out
    # No cross compiler on PATH: one line, exit 2.
    env = dict(os.environ, PATH=str(Path(sys.executable).parent))
    proc = subprocess.run([sys.executable, "-m", "ik5r.tools.cli", "firmware", "--vectors", "1"],
                          capture_output=True, text=True, env=env)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "riscv64-unknown-elf-gcc not found" in proc.stderr
    # A CPU that cannot run the ISA: one line, exit 2.
    assert main(["firmware", "--cpu", "vexriscv_min", "--isa", "rv32im", "-q"]) == 2
    assert "does not execute rv32im" in capsys.readouterr().err


def test_solve_csv_on_rv32_equals_c(tmp_path):
    joints = tmp_path / "joints.csv"
    rng = np.random.default_rng(11)
    joints.write_text("q1,q2,q3,q4,q5\n" + "\n".join(",".join(f"{v:.5f}" for v in row)
                                                     for row in rng.uniform(-1, 1, (5, 5))) + "\n")
    poses = tmp_path / "poses.csv"
    assert main(["fk", str(joints), "-o", str(poses)]) == 0
    for solver in ("c", "rv32"):
        assert main(["solve", str(poses), "--solver", solver, "--all", "-o", str(tmp_path / f"{solver}.csv")]) == 0
    rv32_text = (tmp_path / "rv32.csv").read_text()
    assert rv32_text == (tmp_path / "c.csv").read_text() and "q1_raw" in rv32_text


@pytest.mark.slow
@pytest.mark.parametrize("isa", ("rv32im", "rv32i"))
@pytest.mark.parametrize("config", CONFIGS)
def test_bit_exact_large(config, isa):
    cpu = "vexriscv" if isa == "rv32im" else "vexriscv_min"
    r = measure(constants(load_config(config)), cpu=cpu, isa=isa, vectors=2000, seed=1)
    print(f"{cpu} {isa} {config}: {r['vectors']} poses, {r['mismatches']} mismatches, cycles per "
          f"solve {r['cycles_per_solve']}, instructions {r['instructions_per_solve']['mean']:.0f}")
    _check(r, 2000 + 200)


def test_soc_constructor_checks_and_deterministic_verilog():
    import gc
    import warnings

    from amaranth.hdl import UnusedElaboratable

    from ik5r.hdl.soc.system import SoC, generate_soc

    with warnings.catch_warnings():  # the half-built components of the failed constructors
        warnings.simplefilter("ignore", UnusedElaboratable)
        with pytest.raises(ValueError, match="ram_words"):
            SoC(ram_words=1000)
        with pytest.raises(ValueError, match="cpu must be one of"):
            SoC(cpu="nios2")
        with pytest.raises(ValueError, match="init has"):
            SoC(ram_words=256, init=[0] * 257)
        gc.collect()
    first = generate_soc(cpu="vexriscv_min", ram_words=256, init=[1, 2, 3], host_port=False)
    assert first == generate_soc(cpu="vexriscv_min", ram_words=256, init=[1, 2, 3], host_port=False)
    assert "module ik5r_soc(" in first and "module VexRiscv" in first


def test_missing_verilator_and_failed_build_are_one_line(monkeypatch, capsys):
    import shutil

    from ik5r.firmware_model import rv32

    real_which = shutil.which
    with monkeypatch.context() as patch:
        patch.setattr(shutil, "which", lambda name, *a, **kw: None if name == "verilator"
                      else real_which(name, *a, **kw))
        patch.setitem(sys.modules, "verilator", None)
        assert main(["firmware", "--vectors", "1", "--no-directed", "-q"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "verilator not found" in err
    monkeypatch.setattr(rv32, "CFLAGS", rv32.CFLAGS + ("-DIK5R_WIDTH=not_a_number",))
    assert main(["firmware", "--vectors", "1", "--no-directed", "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "firmware build (rv32im, q32w) failed" in err


def test_soc_verilog_is_verilator_lint_clean(tmp_path):
    """The SoC's own Verilog under -Wall with the project's waivers (hdl/verilator.vlt); the CPU
    is a port-only stub made from the wheel's module header (its source is not ours to lint)."""
    from amaranth.back import verilog

    from ik5r.hdl.soc.system import SoC, cpu_verilog
    from ik5r.tools.softcpu import verilator

    (tmp_path / "ik5r_soc.v").write_text(
        verilog.convert(SoC(cpu="vexriscv", ram_words=256), name="ik5r_soc", emit_src=False))
    text = cpu_verilog("vexriscv")
    header = text[text.index("module VexRiscv ("):]
    header = header[:header.index(");") + 2].replace("output reg", "output")
    (tmp_path / "VexRiscv.v").write_text("/* verilator lint_off UNUSEDSIGNAL */\n"
                                          "/* verilator lint_off UNDRIVEN */\n" + header + "\nendmodule\n")
    vlt = Path(__file__).resolve().parents[1] / "hdl" / "verilator.vlt"
    proc = subprocess.run([verilator(), "--lint-only", "-Wall", str(vlt), "ik5r_soc.v", "VexRiscv.v",
                           "--top-module", "ik5r_soc"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
