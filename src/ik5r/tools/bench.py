"""``make bench``: every speed figure of ik5r measured side by side in one run.

    python -m ik5r.tools.bench [--poses 1000000] [--config q32w] [-o build/bench]

Solvers on the same poses (FK of joint vectors uniform in the limits): the float64 reference (all
four branches, FK round trip included), the vectorised bit-accurate model and the C solver (batched,
one branch each), and for comparison roboticstoolbox-python's ``ik_LM`` and ikpy's
``inverse_kinematics`` (numerical, one solution per pose, timed on a few poses and extrapolated).
Ratios compare CPU times (every solver here runs on one core). The bulk runs of the pipelined
atan2 block and IK core give the simulation speed (every output bit checked against the model,
stimulus, model and comparison in the wall time): the Verilator C++ harness fed from a file, and
the cocotb bulk runs on Icarus and Verilator. The C solver's instruction count per solve comes from ``valgrind --tool=callgrind`` (the basis for
a soft CPU's time per pose), next to the hardware core's cycles per pose. Timings are wall clock and
CPU time of this process (numpy and the C run on one core), best of ``--repeat``.
Writes bench.json and bench.md (the table) into the output folder and prints the table.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ik5r.core import reference
from ik5r.core.arm import Arm, load_arm
from ik5r.core.fxconfig import Constants, constants, load_config
from ik5r.core.modes import Arch, Block, CoreArch, Dsp
from ik5r.firmware_model.poses import PoseBatch


def _timed(fn, repeat: int) -> tuple[float, float]:
    wall = cpu = math.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        cpu, wall = min(cpu, time.process_time() - c0), min(wall, time.perf_counter() - t0)
    return wall, cpu


def fixed_inputs(k: Constants, p, n, o, a, rng):
    """solve_batch arguments for float poses: words, random branch bits, roll given on every row."""
    count = len(p)
    poses, _ = PoseBatch.quantise(k.cfg, p, a, n, o, back=rng.random(count) < 0.5, down=rng.random(count) < 0.5)
    return poses.args()


def _dh_robot(arm: Arm):
    import roboticstoolbox as rtb

    return rtb.DHRobot([rtb.RevoluteDH(d=arm.d[i], a=arm.a[i], alpha=arm.alpha[i], offset=arm.theta_offset[i],
                                       qlim=arm.limits[i]) for i in range(5)])


def _ikpy_chain(arm: Arm):
    from ikpy.chain import Chain
    from ikpy.link import OriginLink, URDFLink

    # Standard DH as URDF: joint i's fixed origin is the previous joint's Tz(d) Tx(a) Rx(alpha).
    links, previous = [OriginLink()], (0.0, 0.0, 0.0)
    for i in range(5):
        a, d, alpha = previous
        links.append(URDFLink(name=f"joint{i + 1}", origin_translation=np.array([a, 0.0, d]),
                              origin_orientation=np.array([alpha, 0.0, 0.0]), rotation=np.array([0.0, 0.0, 1.0]),
                              bounds=arm.limits[i]))
        previous = (arm.a[i], arm.d[i], arm.alpha[i])
    a, d, alpha = previous
    links.append(URDFLink(name="tool", origin_translation=np.array([a, 0.0, d]),
                          origin_orientation=np.array([alpha, 0.0, 0.0]), joint_type="fixed"))
    return Chain(links, active_links_mask=[False] + [True] * 5 + [False])


def numerical_baselines(arm: Arm, p, n, o, a, lm_count: int, ikpy_count: int) -> dict:
    """Per-pose time and success rate of ik_LM and ikpy on the first poses."""
    out = {}
    from spatialmath import SE3

    robot = _dh_robot(arm)
    frames = []
    for i in range(lm_count):
        t = np.eye(4)
        t[:3, 0], t[:3, 1], t[:3, 2], t[:3, 3] = n[i], o[i], a[i], p[i]
        frames.append(SE3(t, check=False))
    t0 = time.process_time()
    ok = sum(bool(robot.ik_LM(frame, q0=np.zeros(5)).success) for frame in frames)
    out["rtb_ik_LM"] = {"poses": lm_count, "s_per_pose": (time.process_time() - t0) / lm_count,
                        "success": ok / lm_count}
    chain = _ikpy_chain(arm)
    t0 = time.process_time()
    errors = []
    for i in range(ikpy_count):
        solution = chain.inverse_kinematics(p[i], a[i], orientation_mode="Z")
        errors.append(np.linalg.norm(chain.forward_kinematics(solution)[:3, 3] - p[i]))
    out["ikpy"] = {"poses": ikpy_count, "s_per_pose": (time.process_time() - t0) / ikpy_count,
                   "success": float(np.mean(np.array(errors) < 1e-3))}
    return out


def callgrind_instructions(k: Constants, poses: list[str]) -> dict | None:
    """Instructions per ik5r_solve call (callgrind, -O2 host build), or None without valgrind."""
    from ik5r.firmware_model.csolver import build_test_driver

    if shutil.which("valgrind") is None:
        return None
    driver = build_test_driver(k, sanitize=False)
    with tempfile.TemporaryDirectory() as tmp:
        out_file = Path(tmp) / "callgrind.out"
        subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out_file}",
                        "--toggle-collect=ik5r_solve", str(driver)], input="\n".join(poses) + "\n",
                       capture_output=True, text=True, check=True)
        totals = re.search(r"^(?:summary|totals):\s+(\d+)", out_file.read_text(), re.MULTILINE)
    return {"solves": len(poses), "instructions_per_solve": int(totals.group(1)) / len(poses),
            "build": "host x86-64 gcc -O2 (test_driver.c)"}


class SimRun(NamedTuple):
    """One simulation benchmark: a design point (block, arch, primitives, poses a program of the
    compact core), its simulator and how many vectors."""
    block: str
    arch: str
    simulator: str
    vectors: int
    dsp: str = Dsp.GENERIC
    poses: int = 1

    @property
    def key(self) -> tuple:
        return self.block, self.arch, self.simulator, self.dsp, self.poses


def _row_key(r: dict) -> tuple:
    """A bench row's :attr:`SimRun.key` (rows made before a field existed have its default)."""
    return (r["block"], r.get("arch", Arch.PIPELINED), r["simulator"], r.get("dsp", Dsp.GENERIC),
            r.get("poses", 1))


#: The simulation benchmarks: bulk runs, every output bit checked. ``verilator-harness``: the
#: Verilator C++ harness fed from a file (:mod:`.testbench.harness`), full rate, one simulator
#: process per CPU; the others: the cocotb bulk run (random idles and back-pressure). The
#: pipelined core takes a pose per clock (its rate is the simulator's cycle rate), the compact
#: core one per ``cycles_per_result`` clocks. The ``dsp="ecp5"`` row runs the netlist that is
#: placed (MULT18X18D, CCU2C chains: ``--dsp ecp5``); ``poses=2`` the compact core computing two
#: poses a program (``--poses 2``).
SIM_RUNS = (SimRun(Block.ATAN2, Arch.PIPELINED, "verilator-harness", 2_000_000),
            SimRun(Block.ATAN2, Arch.PIPELINED, "verilator", 200_000),
            SimRun(Block.ATAN2, Arch.PIPELINED, "icarus", 5_000),
            SimRun(Block.IK, CoreArch.PIPELINED, "verilator-harness", 1_000_000),
            SimRun(Block.IK, CoreArch.PIPELINED, "verilator-harness", 1_000_000, Dsp.ECP5),
            SimRun(Block.IK, CoreArch.COMPACT, "verilator-harness", 20_000),
            SimRun(Block.IK, CoreArch.COMPACT, "verilator-harness", 20_000, poses=2),
            SimRun(Block.IK, CoreArch.PIPELINED, "verilator", 20_000),
            SimRun(Block.IK, CoreArch.PIPELINED, "icarus", 300))


def _simulate(run: SimRun, config: str) -> dict:
    from .testbench.harness import run_harness
    from .testbench.runner import run_block, sim_design

    design = sim_design(run.block, run.arch, config, dsp=run.dsp, poses=run.poses)
    if run.simulator == "verilator-harness":
        r = run_harness(design, vectors=run.vectors, seed=3, pattern="full")
        h = r["harness"]
        # Per CPU second of the simulator processes: the machine's other load left out.
        cpu = h["sim_cpu_seconds"]
        # Per CPU second of everything (simulators, stimulus, model, comparison): what the run
        # costs, whatever else shares the machine; on N free CPUs the wall rate is at most N times it.
        return dict(r, bulk_vectors_per_second=r["vectors_per_second"], cycles=h["cycles"],
                    cpu_vectors_per_second=h.get("vectors_per_cpu_second"),
                    sim_cpu_vectors_per_second=r["vectors"] / cpu if cpu else None,
                    sim_cpu_cycles_per_second=h["cycles"] / cpu if cpu else None, jobs=h["jobs"])
    r = run_block(design, run.simulator, stream_vectors=0, bulk_vectors=run.vectors, seed=3)
    return dict(r, cycles=(r["bulk"] or {}).get("cycles"))


def simulation_speeds(config: str, simulators=None, previous=()) -> list[dict]:
    """Vectors/s of the bulk runs of a block and of the IK cores: the C++ harness on Verilator,
    and cocotb on both simulators. ``simulators``: only these run, the rows of the others taken
    from ``previous``."""
    rows = []
    kept = {_row_key(r): r for r in previous}
    for run in SIM_RUNS:
        if simulators is not None and run.simulator not in simulators and run.key in kept:
            rows.append(kept[run.key])
            continue
        load = os.getloadavg()[0]
        r = _simulate(run, config)
        rows.append({"block": run.block, "arch": run.arch, "dsp": run.dsp, "poses": run.poses,
                     "simulator": run.simulator, "vectors": r["vectors"],
                     "mismatches": r["mismatches"], "vectors_per_second": r["bulk_vectors_per_second"],
                     "build_seconds": r["build_seconds"], "latency_cycles": r["latency_cycles_portmap"],
                     "sim_cycles": r["cycles"], "cpu_vectors_per_second": r.get("cpu_vectors_per_second"),
                     "sim_cpu_vectors_per_second": r.get("sim_cpu_vectors_per_second"),
                     "sim_cpu_cycles_per_second": r.get("sim_cpu_cycles_per_second"), "jobs": r.get("jobs"),
                     # one-minute load average before and after the run (the machine is shared)
                     "load_average": max(load, os.getloadavg()[0]),
                     "cycles_per_result": r["cycles_per_result_portmap"]})
    return rows


def _driver_lines(args) -> list[str]:
    p_l, a_u, n_u, o_u, roll, back, down, q5 = args
    return [" ".join(["S", *map(str, p_l[i]), *map(str, a_u[i]), *map(str, n_u[i]), *map(str, o_u[i]),
                      str(int(roll[i])), str(int(back[i])), str(int(down[i])), str(q5[i])])
            for i in range(len(p_l))]


def cli_streaming(poses: int, config: str | None, solvers=("float", "fixed"), seed: int = 0) -> list[dict]:
    """``ik5r solve --all`` on a file of ``poses`` poses, in a child process: wall time, output
    rows and peak resident memory (``ru_maxrss`` of the child), per solver. The file is streamed in
    chunks, so the memory must not grow with its length (floor: under 1 GB for 1,000,000 poses)."""
    import os
    import sys

    from ik5r.core import csvio

    arm = load_arm()
    results = []
    with tempfile.TemporaryDirectory(prefix="ik5r-bench-") as tmp:
        path = Path(tmp) / "poses.csv"
        rng = np.random.default_rng(seed)
        with csvio.Writer(path, csvio.POSE_COLUMNS) as out:
            for lo in range(0, poses, csvio.CHUNK_ROWS):
                pose = reference.fk_pose(arm, reference.random_joints(arm, min(csvio.CHUNK_ROWS, poses - lo), rng))
                out.write([pose[:, j] for j in range(12)])
        for solver in solvers:
            target = Path(tmp) / f"{solver}.csv"
            cmd = [sys.executable, "-m", "ik5r.tools.cli", "solve", str(path), "--all", "--solver", solver,
                   "-o", str(target)] + (["--config", config] if config else [])
            t0 = time.perf_counter()
            child = subprocess.Popen(cmd)
            _, status, usage = os.wait4(child.pid, 0)
            child.returncode = os.waitstatus_to_exitcode(status)
            wall = time.perf_counter() - t0
            if child.returncode != 0:
                raise RuntimeError(f"{' '.join(cmd)} exited {child.returncode}")
            with open(target, "rb") as handle:
                rows = sum(1 for _ in handle) - 1
            results.append({"solver": solver, "poses": poses, "rows": rows, "wall_s": wall,
                            "poses_per_s_wall": poses / wall, "max_rss_mb": usage.ru_maxrss / 1024,
                            "command": "ik5r " + " ".join(cmd[3:])})
            target.unlink()
    return results


def run(poses: int = 1_000_000, config: str | None = None, repeat: int = 3, lm_count: int = 100,
        ikpy_count: int = 20, callgrind_count: int = 2000, seed: int = 0) -> dict:
    from ik5r.firmware_model import csolver, vector

    arm = load_arm()
    k = constants(load_config(config), arm)
    rng = np.random.default_rng(seed)
    p, n, o, a = reference.fk(arm, reference.random_joints(arm, poses, rng))
    args = fixed_inputs(k, p, n, o, a, rng)
    rows = {}
    wall, cpu = _timed(lambda: reference.ik(arm, p, a, n, o), repeat)
    rows["float64 reference (4 branches)"] = (wall, cpu)
    wall, cpu = _timed(lambda: vector.solve_batch(k, *args), repeat)
    rows["vectorised bit-accurate model"] = (wall, cpu)
    c_solver = csolver.solver(k)
    wall, cpu = _timed(lambda: c_solver.solve_batch(*args), repeat)
    rows["C solver (batched, host)"] = (wall, cpu)
    result = {"config": k.cfg.name, "poses": poses, "repeat": repeat, "solvers": {}}
    baselines = numerical_baselines(arm, p, n, o, a, lm_count, ikpy_count)
    for name, (wall, cpu) in rows.items():
        result["solvers"][name] = {"wall_s": wall, "cpu_s": cpu, "poses_per_s_wall": poses / wall,
                                   "poses_per_s_cpu": poses / cpu,
                                   **{f"x_{base}": poses / cpu * info["s_per_pose"]
                                      for base, info in baselines.items()}}
    for base, info in baselines.items():
        result["solvers"][base] = {"poses": info["poses"], "s_per_pose_cpu": info["s_per_pose"],
                                   "poses_per_s_cpu": 1 / info["s_per_pose"], "success": info["success"]}
    sample = tuple(arg[:callgrind_count] for arg in args)
    result["c_instructions"] = callgrind_instructions(k, _driver_lines(sample))
    result["simulation"] = simulation_speeds(k.cfg.name)
    result["cli"] = cli_streaming(poses, config)
    return result


#: The simulators of the table, as their rows name them.
SIMULATOR_NAMES = {"verilator-harness": "Verilator, C++ harness (file in, file out, full rate)",
                   "verilator": "Verilator, cocotb bulk", "icarus": "Icarus, cocotb bulk"}


def table(result: dict) -> str:
    lines = [f"| solver ({result['config']}, {result['poses']:,} poses) | poses/s (CPU) | poses/s (wall) "
             "| x ik_LM | x ikpy |", "| --- | ---: | ---: | ---: | ---: |"]
    for name, r in result["solvers"].items():
        cpu = f"{r['poses_per_s_cpu']:,.0f}"
        wall = f"{r['poses_per_s_wall']:,.0f}" if "poses_per_s_wall" in r else "–"
        ratio = [f"{r[key]:,.0f}" if key in r else "1 (baseline)" if name.startswith(base) else "–"
                 for key, base in (("x_rtb_ik_LM", "rtb"), ("x_ikpy", "ikpy"))]
        lines.append(f"| {name} | {cpu} | {wall} | {ratio[0]} | {ratio[1]} |")
    ci = result.get("c_instructions")
    core = next((r for r in result["simulation"] if r["block"] == Block.IK), None)
    if ci:
        lines.append("")
        lines.append(f"C solver: {ci['instructions_per_solve']:,.0f} instructions per solve "
                     f"(callgrind, {ci['solves']:,} solves, {ci['build']}); hardware IK core: "
                     f"{core['cycles_per_result']} cycle(s) per pose, latency {core['latency_cycles']} cycles")
    lines += ["", "| simulation (every output bit checked) | simulator | vectors | mismatches | vectors/s "
              "(wall) | vectors per CPU second (all processes) | vectors per simulator CPU second "
              "| cycles per simulator CPU second | load average | build (s) |",
              "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in result["simulation"]:
        sim = SIMULATOR_NAMES.get(r["simulator"], r["simulator"])
        cpu = f"{r['sim_cpu_vectors_per_second']:,.0f}" if r.get("sim_cpu_vectors_per_second") else "–"
        total = f"{r['cpu_vectors_per_second']:,.0f}" if r.get("cpu_vectors_per_second") else "–"
        cycles = f"{r['sim_cpu_cycles_per_second']:,.0f}" if r.get("sim_cpu_cycles_per_second") else "–"
        load = f"{r['load_average']:.1f}" if r.get("load_average") is not None else "–"
        jobs = f", {r['jobs']} processes" if r.get("jobs") else ""
        netlist = " (ECP5 primitives netlist)" if r.get("dsp", Dsp.GENERIC) != Dsp.GENERIC else ""
        netlist += f", {r['poses']} poses a program" if r.get("poses", 1) != 1 else ""
        lines.append(f"| {r['block']} {r.get('arch', Arch.PIPELINED)}{netlist} | {sim}{jobs} | {r['vectors']:,} | "
                     f"{r['mismatches']} | {r['vectors_per_second']:,.0f} | {total} | {cpu} | {cycles} | {load} | "
                     f"{r['build_seconds']:.0f} |")
    return "\n".join(lines + cli_table(result.get("cli") or []))


def cli_table(runs: list[dict]) -> list[str]:
    """Markdown lines of the ``ik5r solve --all`` streaming runs (none: no lines)."""
    if not runs:
        return []
    lines = ["", "| `ik5r solve --all` (CSV in, CSV out) | poses | rows written | poses/s (wall) | peak RSS (MB) |",
             "| --- | ---: | ---: | ---: | ---: |"]
    for r in runs:
        lines.append(f"| --solver {r['solver']} | {r['poses']:,} | {r['rows']:,} | {r['poses_per_s_wall']:,.0f} "
                     f"| {r['max_rss_mb']:,.0f} |")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ik5r.tools.bench", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--poses", type=int, default=1_000_000)
    parser.add_argument("--config", default=None)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("-o", "--output", default="build/bench")
    parser.add_argument("--only-cli", action="store_true",
                        help="only the `ik5r solve --all` streaming runs (memory and CLI throughput)")
    parser.add_argument("--only-sim", nargs="?", const="all", default=None, metavar="SIMS",
                        help="only the simulation runs (SIMS: a comma-separated list of simulators, the "
                             "other rows kept), put into the bench.json already in the output folder "
                             "(its other figures kept, from the run that wrote them)")
    args = parser.parse_args(argv)
    if args.only_sim:
        out = Path(args.output)
        result = json.loads((out / "bench.json").read_text())
        sims = None if args.only_sim == "all" else set(args.only_sim.split(","))
        result["simulation"] = simulation_speeds(result["config"], sims, result.get("simulation", ()))
        return _write(out, result)
    if args.only_cli:
        runs = cli_streaming(args.poses, args.config)
        Path(args.output).mkdir(parents=True, exist_ok=True)
        (Path(args.output) / "bench_cli.json").write_text(json.dumps(runs, indent=2) + "\n")
        print("\n".join(cli_table(runs)))
        return 0
    return _write(Path(args.output), run(args.poses, args.config, args.repeat))


def _write(out: Path, result: dict) -> int:
    out.mkdir(parents=True, exist_ok=True)
    text = table(result)
    (out / "bench.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / "bench.md").write_text(text + "\n")
    print(text)
    print(f"\nwritten: {out / 'bench.json'}, {out / 'bench.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
