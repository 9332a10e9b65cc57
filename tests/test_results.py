"""``python -m ik5r.tools.results``: measurements collected into records, the README section rendered
from the records alone, records of other Verilog left out."""

from __future__ import annotations

import json
import os

from ik5r.core.fxconfig import constants, load_config
from ik5r.hdl.generate import generate
from ik5r.tools import results, results_board


def _synth_result(block="sqrt", arch="iterative", config="q18", luts=123, fmax=111.5, seed=1):
    return {"block": block, "arch": arch, "dsp": "generic", "tag_width": 0, "config": config,
            "module": f"ik5r_{block}_{arch}", "target": "ecp5", "device": "85k", "speed_grade": 6,
            "seed": seed, "luts": luts, "ffs": 45, "dsps": 0, "brams": 0, "fmax_mhz": fmax,
            "latency_cycles": 20, "cycles_per_result": 20, "results_per_second": fmax * 1e6 / 20,
            "cache_dir": "/somewhere/on/this/machine", "cached": False, "key": "abc"}


def _write_run(build, name, result, verilog_text, mtime):
    folder = build / "synth" / name
    folder.mkdir(parents=True)
    (folder / "design.v").write_text(verilog_text)
    (folder / "result.json").write_text(json.dumps(result))
    os.utime(folder / "result.json", (mtime, mtime))


def test_collect_and_render(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(f"# title\n\n{results.BEGIN}\nold text\n{results.END}\ntail\n")
    build = tmp_path / "build"
    current = generate("sqrt", "iterative", constants(load_config("q18")))[0]
    _write_run(build, "old", _synth_result(luts=999), current, 1_000)
    _write_run(build, "new", _synth_result(luts=123), current, 2_000)
    _write_run(build, "seed3", _synth_result(luts=7, fmax=99.04, seed=3), current, 3_000)
    _write_run(build, "stale", _synth_result(block="atan2", luts=555), "module other; endmodule\n", 3_000)
    (build / "bench").mkdir()
    (build / "bench" / "bench.md").write_text("| solver | poses/s |\n| --- | ---: |\n| float | 42 |\n")
    (build / "bench" / "bench.json").write_text("{}\n")

    assert results.main(["--build", str(build), "--sweep", str(tmp_path / "none"),
                         "--readme", str(readme)]) == 0
    records = tmp_path / "docs" / "results" / "records"
    names = sorted(p.name for p in (records / "synth").glob("*.json"))
    assert names == ["ik5r_sqrt_iterative_q18_ecp5-85k.json"]     # newest seed-1 run, current Verilog
    record = json.loads((records / "synth" / names[0]).read_text())
    assert record["luts"] == 123 and "cache_dir" not in record and len(record["verilog_sha256"]) == 64
    assert record["fmax_mhz_by_seed"] == {"1": 111.5, "3": 99.0}     # a robustness run, same Verilog
    text = readme.read_text()
    assert text.startswith("# title\n") and text.endswith("tail\n") and "old text" not in text
    assert "| sqrt | iterative | generic | q18 | ecp5-85k speed 6 | 123 |" in text
    assert "| float | 42 |" in text and "No sweep yet" in text
    assert "sqrt iterative q18 on the ecp5-85k: Fmax 111.5, 99.0 MHz at nextpnr seeds 1, 3" in text

    # Render from the records alone (a fresh clone has no build/); a record whose Verilog hash is
    # not this checkout's is left out.
    stale = dict(record, verilog_sha256="0" * 64, block="rotate", module="ik5r_rotate_iterative")
    (records / "synth" / "ik5r_rotate_iterative_q18_ecp5-85k.json").write_text(json.dumps(stale))
    assert results.main(["--build", str(tmp_path / "empty"), "--readme", str(readme), "--no-collect"]) == 0
    text = readme.read_text()
    assert "| sqrt | iterative | generic | q18 |" in text and "| rotate |" not in text


def test_a_router2_run_is_its_own_design_point(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(f"{results.BEGIN}\n{results.END}\n")
    build = tmp_path / "build"
    current = generate("sqrt", "iterative", constants(load_config("q18")))[0]
    _write_run(build, "r2", dict(_synth_result(fmax=90.0), router="router2"), current, 1_000)
    _write_run(build, "r1seed3", _synth_result(fmax=99.0, seed=3), current, 2_000)
    assert results.main(["--build", str(build), "--sweep", str(tmp_path / "none"),
                         "--readme", str(readme)]) == 0
    record = json.loads(next((tmp_path / "docs" / "results" / "records" / "synth").glob("*.json")).read_text())
    # The router1 run at seed 3 is not a seed of the router2 design point.
    assert record["router"] == "router2" and "fmax_mhz_by_seed" not in record
    assert "sqrt iterative q18 on the ecp5-85k: routed with nextpnr's router2" in readme.read_text()


def test_the_routes_verdict_names_a_record_of_other_verilog(tmp_path):
    from ik5r.tools import routes

    def synth(name, luts, fmax, cycles, module, **more):
        path = tmp_path / "synth" / f"{name}.json"
        path.parent.mkdir(exist_ok=True)
        path.write_text(json.dumps({"target": "ecp5", "device": name.rsplit("-", 1)[1], "luts": luts,
                                    "ffs": 1, "dsps": 1, "brams": 1, "fmax_mhz": fmax,
                                    "cycles_per_result": cycles, "latency_cycles": cycles, "module": module, **more}))
    synth("ik5r_soc_vexriscv_q32w_ecp5-25k", 3000, 80.0, 1, "soc")
    synth("ik5r_ik_dspecp5_dsp_output_regs1_pipelined_q32w_ecp5-85k", 60000, 110.0, 1, "regs", router="router2")
    synth("ik5r_ik_compact_q32w_ecp5-25k", 4000, 80.0, 700, "compact")
    synth("ik5r_ik_dspecp5_pipelined_q32w_ecp5-85k", 60000, 100.0, 1, "pipelined")
    (tmp_path / "firmware").mkdir()
    (tmp_path / "firmware" / "vexriscv_rv32im_q32w.json").write_text(json.dumps(
        {"cycles_per_solve": {"mean": 28000.0}, "mismatches": 0, "vectors": 10}))
    text = "\n".join(routes.routes_part(tmp_path, lambda r: r["module"] != "pipelined", lambda fw: True))
    compact = next(line for line in text.split("\n") if line.startswith("- **compact IK core**"))
    pipelined = next(line for line in text.split("\n") if line.startswith("- **pipelined IK core"))
    assert "it beats the soft CPU per LUT" in compact and "other Verilog" not in compact
    assert "(record of other Verilog) on the ecp5-85k" in pipelined
    assert pipelined.endswith("that record beats the soft CPU per LUT.")
    assert "| pipelined IK core (ECP5 DSP + carry primitives) (record of other Verilog) |" in text
    # A route placed with router2 (the others: router1) says so.
    assert "| pipelined IK core, a fabric register after each DSP (ECP5 primitives), routed by nextpnr's router2 |" in text


def test_a_firmware_record_of_other_verilog_is_named(tmp_path):
    """A route timed by a firmware record is current only if the record ran the SoC Verilog this
    checkout simulates (``verilog_sha256``): a record of other Verilog, or one made before the
    key, is marked in the table."""
    from ik5r.tools import routes
    from ik5r.tools.softcpu import SIM_RAM_WORDS

    (tmp_path / "synth").mkdir()
    (tmp_path / "synth" / "ik5r_soc_vexriscv_q32w_ecp5-25k.json").write_text(json.dumps(
        {"target": "ecp5", "device": "25k", "luts": 3000, "ffs": 1, "dsps": 1, "brams": 1,
         "fmax_mhz": 80.0, "cycles_per_result": 1, "latency_cycles": 1, "module": "soc"}))
    (tmp_path / "firmware").mkdir()
    record = {"cpu": "vexriscv", "config": "q18", "arm": None, "ram_bytes": 4 * SIM_RAM_WORDS,
              "cycles_per_solve": {"mean": 28000.0}, "mismatches": 0, "vectors": 10}
    path = tmp_path / "firmware" / "vexriscv_rv32im_q32w.json"
    for sha, current in (("0" * 64, False), (None, False), (routes._firmware_current, True)):
        if callable(sha):
            from ik5r.tools.softcpu import firmware_verilog_sha256
            sha = firmware_verilog_sha256(record)
        path.write_text(json.dumps({**record, "verilog_sha256": sha} if sha else record))
        row = routes.route_rows(tmp_path, lambda r: True)[0]
        assert row["current"] is current


def test_an_older_firmware_run_never_replaces_a_newer_record(tmp_path):
    """A build/firmware JSON older than the committed record (another worktree's run, say) is not
    copied over it; a newer one is."""
    build, records = tmp_path / "build", tmp_path / "records"
    (build / "firmware").mkdir(parents=True)
    (records / "firmware").mkdir(parents=True)
    run, record = build / "firmware" / "cpu.json", records / "firmware" / "cpu.json"
    run.write_text(json.dumps({"cycles": 1, "measured_at": 1_000.0}))
    record.write_text(json.dumps({"cycles": 2, "measured_at": 2_000.0}))
    results.collect(build, tmp_path / "none", records, tmp_path / "docs", results.VerilogOfCheckout())
    assert json.loads(record.read_text())["cycles"] == 2
    run.write_text(json.dumps({"cycles": 3, "measured_at": 3_000.0}))
    assert str(record) in results.collect(build, tmp_path / "none", records, tmp_path / "docs",
                                          results.VerilogOfCheckout())
    assert json.loads(record.read_text())["cycles"] == 3


def test_a_board_record_of_other_rtlil_is_left_out(tmp_path):
    """A board record counts only if the RTLIL its bitstream was built from is what this checkout
    hands Yosys for the same board, config, arm, baud and core."""
    from ik5r.tools.board import BOARDS

    boards = results_board.BoardOfCheckout()
    r = {"board": "icebreaker", "core": "serial", "config": "q18", "arm": None, "baud": 3_000_000,
         "clock_mhz": 12.0, "fmax_mhz": 20.0, "timing_met": True, "resources": {"ICESTORM_LC": {"used": 5}},
         "bitstream_bytes": 1, "line_poses_per_s": 4_838.7, "core_poses_per_s": 1.0}
    sha = boards.sha256(r)
    assert len(sha) == 64 and BOARDS["icebreaker"]["core"] == "serial"
    (tmp_path / "board").mkdir()
    (tmp_path / "board" / "icebreaker_serial_q18.json").write_text(json.dumps(dict(r, rtlil_sha256=sha)))
    (tmp_path / "board" / "icebreaker_serial_q32w.json").write_text(
        json.dumps(dict(r, config="q32w", rtlil_sha256=sha)))       # q18's RTLIL: not q32w's
    (tmp_path / "board" / "ulx3s-85f_pipelined_q18.json").write_text(json.dumps(dict(r, board="ulx3s-85f")))
    builds, stale = results_board.board_builds(tmp_path, boards)
    assert [b["config"] for b in builds] == ["q18"]
    assert stale == ["board/icebreaker_serial_q32w.json", "board/ulx3s-85f_pipelined_q18.json"]
    assert "| icebreaker | serial | q18 | 12 | 3,000,000 |" in "\n".join(results_board.board_part(tmp_path, builds))
