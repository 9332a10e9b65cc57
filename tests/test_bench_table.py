"""``make bench``'s simulation rows (``ik5r.tools.bench``): a row per design point, the ECP5
primitives netlist its own row, kept apart from the generic Verilog's when rows are reused."""

from __future__ import annotations

from ik5r.core.modes import Block, CoreArch, Dsp
from ik5r.tools import bench


def _row(dsp, rate, block=Block.IK, arch=CoreArch.PIPELINED, simulator="verilator-harness", poses=1):
    return {"block": block, "arch": arch, "dsp": dsp, "poses": poses, "simulator": simulator,
            "vectors": 10, "mismatches": 0, "vectors_per_second": rate, "build_seconds": 1.0,
            "latency_cycles": 339, "cycles_per_result": 1}


def test_the_ecp5_netlist_row_is_named_and_kept_apart():
    assert any(run.dsp == Dsp.ECP5 and run.block == Block.IK for run in bench.SIM_RUNS)
    assert len({run.key for run in bench.SIM_RUNS}) == len(bench.SIM_RUNS)
    # No simulator asked for: every row is the previous run's of its design point (none runs).
    previous = [_row(run.dsp, 1000.0 * i, run.block, run.arch, run.simulator, run.poses)
                for i, run in enumerate(bench.SIM_RUNS)]
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


def test_the_two_pose_compact_row_is_named_and_kept_apart():
    compact = [run for run in bench.SIM_RUNS if run.arch == CoreArch.COMPACT]
    assert sorted(run.poses for run in compact) == [1, 2]
    previous = [_row(Dsp.GENERIC, 100.0 * run.poses, run.block, run.arch, run.simulator, run.poses)
                for run in bench.SIM_RUNS]
    rows = bench.simulation_speeds("q18", simulators=set(), previous=previous)
    rates = {r["poses"]: r["vectors_per_second"] for r in rows if r["arch"] == CoreArch.COMPACT}
    assert rates == {1: 100.0, 2: 200.0}
    # A row recorded before the poses field is the one-pose core's.
    old = _row(Dsp.GENERIC, 1.0, arch=CoreArch.COMPACT)
    del old["poses"]
    assert bench._row_key(old) == bench.SimRun(Block.IK, CoreArch.COMPACT, "verilator-harness", 0).key
    text = bench.table({"config": "q18", "poses": 1, "solvers": {},
                        "simulation": [_row(Dsp.GENERIC, 5.0, arch=CoreArch.COMPACT),
                                       _row(Dsp.GENERIC, 9.0, arch=CoreArch.COMPACT, poses=2)]})
    lines = [line for line in text.splitlines() if line.startswith("| ik compact")]
    assert lines[0].startswith("| ik compact |") and lines[1].startswith("| ik compact, 2 poses a program |")
