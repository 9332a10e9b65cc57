"""``ik5r firmware``: the C solver cross-compiled for RISC-V and run on a simulated soft CPU.

Builds ``firmware_model/ik5r.c`` with the config's generated header and a bare-metal harness for
``--isa`` (riscv64-unknown-elf-gcc, ``-march=<isa> -mabi=ilp32 -O2``), simulates the SoC of
``ik5r.hdl.soc.system`` (a VexRiscv CPU from the pythondata-cpu-vexriscv wheel, on-chip RAM, MARK/STOP
registers) cycle by cycle with Verilator, and solves N random reachable poses plus the directed
edge set on it. Every raw joint word and status word is compared with the vectorised bit-accurate
model and with the C solver compiled for this host. Prints the mismatches and the clock cycles
and retired instructions per solve (measured: MARK writes between solves, each interval = read
the pose, ik5r_solve, write the result); ``--json FILE`` writes every figure.

CPUs: ``vexriscv`` (5 stages, bypassing, 4 KiB I- and D-cache, single-cycle multiplier, dynamic
branch prediction: the class of a Nios II/f; runs rv32im and rv32i code) and ``vexriscv_min``
(5 stages, no bypassing, no caches, no multiplier: the class of a Nios II/e; rv32i only). The
default is vexriscv for rv32im and vexriscv_min for rv32i.

``--peripheral compact|pipelined`` adds the IK core on the CPU's data bus (``ik5r.hdl.soc.periph``,
register map ``ik5r.core.regmap``) and runs the firmware ``rv32_periph_main.c``: every pose through
the driver's blocking call ``ik5r_hw_solve`` (timed from the CPU's side), its interrupt path and the
software ``ik5r_solve``; every word of the hardware paths is compared with the software path's
(``differing_words_hw_vs_sw``, ``differing_words_irq_vs_sw``), the model and the host C. The cycles
are then those of the call (``call_cycles``); ``bus_overhead_cycles`` = call cycles - the core's
latency (``core_latency_cycles``), ``bus_share`` its share of the call.

Exit status: 0 with no mismatch, 1 on any mismatch, 2 when the firmware or the simulator cannot
be built (missing cross compiler or Verilator) or the CPU traps, stops early or hangs (cycle limit).
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

from ik5r.core.fxconfig import DEFAULT_CONFIG
from ik5r.core.regmap import CORE_KINDS
from ik5r.tools.design import add_arm_argument


def register(subparsers) -> None:
    parser = subparsers.add_parser("firmware", help="the C solver on a simulated RISC-V soft CPU",
                                   description=__doc__)
    parser.add_argument("--cpu", default=None, metavar="NAME",
                        help="vexriscv or vexriscv_min (default: vexriscv for rv32im, "
                             "vexriscv_min for rv32i)")
    parser.add_argument("--isa", choices=("rv32im", "rv32i"), default="rv32im",
                        help="instruction set of the build (default: rv32im)")
    parser.add_argument("--config", default=None, metavar="CFG",
                        help=f"fixed-point config TOML or shipped name (default: {DEFAULT_CONFIG})")
    add_arm_argument(parser)
    parser.add_argument("--vectors", type=int, default=200, metavar="N",
                        help="random reachable poses (rows) besides the directed set (default: 200)")
    parser.add_argument("--seed", type=int, default=1, help="random seed (default: 1)")
    parser.add_argument("--no-directed", action="store_true", help="random poses only")
    parser.add_argument("--cycle-limit", type=int, default=None, metavar="CYCLES",
                        help="cycles per solve after which the CPU counts as hung (default: 1,000,000)")
    parser.add_argument("--peripheral", choices=tuple(map(str, CORE_KINDS)), default=None,
                        help="add the IK core on the CPU's bus (ik5r.hdl.soc.periph) and run the "
                             "firmware that solves every pose on it (ik5r_hw_solve) and in software "
                             "(ik5r_solve); cycles are then those of the hardware call")
    parser.add_argument("--json", default=None, metavar="FILE", help="write the figures as JSON")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(run=run)


def poses_for(k, vectors: int, seed: int, directed: bool):
    """``vectors`` random reachable pose rows (every branch and roll of random joints, cut to
    ``vectors``) followed by the directed set."""
    from ik5r.firmware_model import vectors as vec
    from ik5r.firmware_model.poses import concat

    rows = vec.random_poses(k, max(1, math.ceil(vectors / 8)), seed)[:vectors]
    return concat(rows, vec.directed_poses(k)) if directed else rows


def measure(k, *, cpu, isa, vectors, seed, directed=True, cycle_limit=None, progress=None,
            peripheral=None) -> dict:
    """Run the poses on the soft CPU, compare with the model and the host C; the figures."""
    import numpy as np

    from ik5r.firmware_model import vector
    from ik5r.firmware_model.csolver import solve_batch as c_solve
    from ik5r.hdl.soc.system import CPUS
    from ik5r.tools.softcpu import CYCLES_PER_SOLVE_LIMIT, SoftCpu

    poses = poses_for(k, vectors, seed, directed)
    start = time.perf_counter()
    soft = SoftCpu(k, isa=isa, cpu=cpu, cycles_per_solve_limit=cycle_limit or CYCLES_PER_SOLVE_LIMIT,
                   periph=peripheral)
    build_seconds = time.perf_counter() - start
    q, status = soft.solve_batch(*poses.args(), progress=progress)
    q_model, status_model = vector.solve_batch(k, *poses.args())
    q_c, status_c = c_solve(k, *poses.args())
    differs_model = (q != q_model).any(axis=1) | (status != status_model)
    differs_c = (q != q_c).any(axis=1) | (status != status_c)
    extra = {} if peripheral is None else _peripheral_figures(soft, q, status, q_model, status_model)
    if extra:
        differs_model |= extra.pop("_software_differs_model")
    bits = int(sum(bin(int(v)).count("1") for v in
                   np.concatenate([(q ^ q_model).ravel() & 0xFFFF_FFFF, (status ^ status_model)])))
    cycles = np.array(soft.stats.cycles)
    instructions = np.array(soft.stats.instructions)
    fw = soft.firmware
    return {
        "cpu": soft.cpu, "cpu_description": CPUS[soft.cpu][2], "isa": isa, "config": k.cfg.name,
        "arm": k.arm.name, "arm_sha256": k.arm.dh_sha256(),
        "vectors": len(poses), "random_vectors": min(vectors, len(poses)), "seed": seed,
        "directed": directed,
        "mismatches": int((differs_model | differs_c).sum()),
        "mismatches_vs_model": int(differs_model.sum()), "mismatches_vs_host_c": int(differs_c.sum()),
        "differing_bits_vs_model": bits,
        "cycles_per_solve": {"mean": float(cycles.mean()), "min": int(cycles.min()),
                             "max": int(cycles.max())},
        "instructions_per_solve": {"mean": float(instructions.mean()), "min": int(instructions.min()),
                                   "max": int(instructions.max())},
        "instructions_per_cycle": float(instructions.sum() / cycles.sum()),
        "mark_write_cycles": soft.stats.mark_cycles,
        "code_bytes": fw.code_bytes, "data_bytes": fw.data_bytes, "stack_bytes": fw.stack_bytes,
        "ram_bytes": 4 * fw.ram_words,
        "simulated_cycles": soft.stats.total_cycles,
        "simulated_instructions": soft.stats.total_instructions,
        "sim_seconds": round(soft.stats.sim_seconds, 2), "build_seconds": round(build_seconds, 2),
        "simulated_cycles_per_second": round(soft.stats.total_cycles / max(soft.stats.sim_seconds, 1e-9)),
        # Simulator processes run side by side (one per CPU): the rate per CPU second of them too.
        "sim_jobs": soft.jobs, "sim_cpu_seconds": round(soft.stats.sim_cpu_seconds, 2),
        "simulated_cycles_per_cpu_second": round(soft.stats.total_cycles / max(soft.stats.sim_cpu_seconds, 1e-9)),
        "toolchain": "riscv64-unknown-elf-gcc -march=" + isa + " -mabi=ilp32 -O2",
        "verilog_sha256": soft.verilog_sha256,      # the SoC simulated (softcpu.firmware_verilog_sha256)
        **extra,
    }


def _peripheral_figures(soft, q, status, q_model, status_model) -> dict:
    """Hardware path against the software path of the same firmware (every word), and the cost
    of the bus: call cycles less the core's own latency for the pose."""
    import numpy as np

    q_sw, status_sw = np.array(soft.stats.software_q).reshape(-1, 5), np.array(soft.stats.software_status)
    q_irq, status_irq = np.array(soft.stats.interrupt_q).reshape(-1, 5), np.array(soft.stats.interrupt_status)
    software = np.column_stack([q_sw, status_sw])
    words = np.column_stack([q, status]) != software
    irq_words = np.column_stack([q_irq, status_irq]) != software
    calls = np.array(soft.stats.cycles)
    core = soft.periph.core
    overhead = calls - core.latency
    return {"peripheral": soft.periph.kind, "differing_words_hw_vs_sw": int(words.sum()),
            "mismatches_hw_vs_sw": int(words.any(axis=1).sum()),
            "differing_words_irq_vs_sw": int(irq_words.sum()),
            "call_cycles": {"mean": float(calls.mean()), "median": float(np.median(calls)),
                            "min": int(calls.min()), "max": int(calls.max())},
            "core_latency_cycles": core.latency, "core_cycles_per_result": core.cycles_per_result,
            "bus_overhead_cycles": {"mean": float(overhead.mean()), "median": float(np.median(overhead)),
                                    "max": int(overhead.max())},
            "bus_share": float(overhead.mean() / calls.mean()),
            "_software_differs_model": (q_sw != q_model).any(axis=1) | (status_sw != status_model)}


def _progress(quiet: bool, label: str):
    if quiet or not sys.stderr.isatty():
        return None, None
    from tqdm import tqdm

    bar = tqdm(total=None, desc=label, unit="pose", file=sys.stderr)

    def update(done, total):
        bar.total = total
        bar.n = done
        bar.refresh()
    return update, bar


def run(args) -> int:
    from ik5r.core.errors import InputError
    from ik5r.core.arm import load_arm
    from ik5r.core.fxconfig import Constants, load_config
    from ik5r.tools.softcpu import SoftCpuError, default_cpu

    if args.vectors < 0 or (args.vectors == 0 and args.no_directed):
        raise InputError("--vectors", f"must be >= 1 (or 0 with the directed set), got {args.vectors}")
    if args.cycle_limit is not None and args.cycle_limit < 1:
        raise InputError("--cycle-limit", f"must be >= 1, got {args.cycle_limit}")
    k = Constants(load_config(args.config), load_arm(args.arm))   # refuses an arm the config cannot hold
    cpu = args.cpu or default_cpu(args.isa)
    update, bar = _progress(args.quiet, f"{cpu} {args.isa} {k.cfg.name}")
    try:
        r = measure(k, cpu=cpu, isa=args.isa, vectors=args.vectors, seed=args.seed,
                    directed=not args.no_directed, cycle_limit=args.cycle_limit, progress=update,
                    peripheral=args.peripheral)
    except SoftCpuError as exc:
        print(f"ik5r firmware: {exc}", file=sys.stderr)
        return 2
    finally:
        if bar is not None:
            bar.close()
    c, i = r["cycles_per_solve"], r["instructions_per_solve"]
    print(f"{r['cpu']} {r['isa']} {r['config']} arm {r['arm']}: {r['vectors']:,} poses, {r['mismatches']} mismatches "
          f"(vs model {r['mismatches_vs_model']}, vs host C {r['mismatches_vs_host_c']}); "
          f"cycles per solve mean {c['mean']:,.0f} max {c['max']:,}; instructions per solve "
          f"{i['mean']:,.0f} (IPC {r['instructions_per_cycle']:.2f}); code {r['code_bytes']:,} B, "
          f"data {r['data_bytes']:,} B; simulated {r['simulated_cycles']:,} cycles in "
          f"{r['sim_seconds']:.1f} s")
    if args.peripheral:
        o = r["bus_overhead_cycles"]
        print(f"peripheral {r['peripheral']}: {r['differing_words_hw_vs_sw']} differing words hardware vs "
              f"software ({r['differing_words_irq_vs_sw']} on the interrupt path); call cycles mean {r['call_cycles']['mean']:,.1f} max {r['call_cycles']['max']:,}; "
              f"core latency {r['core_latency_cycles']:,}; bus overhead mean {o['mean']:,.1f} max "
              f"{o['max']:,} ({100 * r['bus_share']:.1f}% of the call)")
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({**r, "measured_at": time.time()}, indent=1) + "\n")
    return 1 if r["mismatches"] or r.get("differing_words_hw_vs_sw") or r.get("differing_words_irq_vs_sw") else 0
