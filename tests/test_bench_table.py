"""``make bench``'s simulation rows (``ik5r.tools.bench``): a row per design point, the ECP5
primitives netlist its own row, kept apart from the generic Verilog's when rows are reused."""

from __future__ import annotations

from ik5r.core.modes import Block, CoreArch, Dsp
from ik5r.tools import bench


def _row(dsp, rate, block=Block.IK, arch=CoreArch.PIPELINED, simulator="verilator-harness"):
    return {"block": block, "arch": arch, "dsp": dsp, "simulator": simulator,
            "vectors": 10, "mismatches": 0, "vectors_per_second": rate, "build_seconds": 1.0,
            "latency_cycles": 339, "cycles_per_result": 1}


def test_the_ecp5_netlist_row_is_named_and_kept_apart():
    assert any(run[4] == Dsp.ECP5 and run[0] == Block.IK for run in bench.SIM_RUNS)
    # No simulator asked for: every row is the previous run's of its design point (none runs).
    previous = [_row(dsp, 1000.0 * i, block, arch, sim)
                for i, (block, arch, sim, _, dsp) in enumerate(bench.SIM_RUNS)]
    rows = bench.simulation_speeds("q18", simulators=set(), previous=previous[::-1])
    assert rows == previous
    harness = [(r["dsp"], r["vectors_per_second"]) for r in rows
               if r["simulator"] == "verilator-harness" and r["block"] == Block.IK
               and r["arch"] == CoreArch.PIPELINED]
    assert sorted(dsp for dsp, _ in harness) == sorted((Dsp.GENERIC, Dsp.ECP5)) and len(set(harness)) == 2
    rows = [_row(Dsp.GENERIC, 111.0), _row(Dsp.ECP5, 222.0)]
    text = bench.table({"config": "q18", "poses": 1, "solvers": {}, "simulation": rows})
    lines = [line for line in text.splitlines() if line.startswith("| ik pipelined")]
    assert len(lines) == 2
    assert "ECP5 primitives netlist" not in lines[0] and "| 111 |" in lines[0]
    assert "ik pipelined (ECP5 primitives netlist) |" in lines[1] and "| 222 |" in lines[1]
