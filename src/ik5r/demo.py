"""``make demo``: the main job of ik5r, end to end, in a few minutes.

1. Verilog of every block and of the IK core (both architectures) into ``build/verilog/``;
2. the IK core under cocotb (random idles, back-pressure, mid-traffic reset) on ``--poses`` random
   reachable poses plus the directed edge set, every output bit against the bit-accurate model,
   and each block on a smaller run;
3. C solver vs scalar model vs vectorised model on the same kind of poses;
4. the quantisation report (fixed point and float32 against float64) and the bit-accuracy section
   into ``build/report/index.html`` and ``report.json``, and a summary on the terminal.

    python -m ik5r.demo [--config q32w] [--poses 10000] [--simulator verilator]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from ik5r.fxconfig import DEFAULT_CONFIG

BLOCKS = ("atan2", "rotate", "sqrt", "acos")


def _verilog(k, out_dir: Path) -> list[str]:
    from ik5r.hdl.generate import archs_of, generate

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for block in (*BLOCKS, "ik"):
        for arch in archs_of(block):
            text, pmap = generate(block, arch, k, 0)
            (out_dir / f"{pmap['module']}.v").write_text(text)
            (out_dir / f"{pmap['module']}.json").write_text(json.dumps(pmap, indent=2) + "\n")
            written.append(pmap["module"])
    return written


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ik5r.demo", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", default=DEFAULT_CONFIG)
    parser.add_argument("--poses", type=int, default=10_000, help="random poses through the HDL core")
    parser.add_argument("--block-vectors", type=int, default=5_000, help="random vectors per block")
    parser.add_argument("--report-vectors", type=int, default=1_000_000, help="poses of the quantisation report")
    parser.add_argument("--simulator", default="verilator", choices=("icarus", "verilator"))
    parser.add_argument("-o", "--output", default="build")
    args = parser.parse_args(argv)

    from ik5r.firmware.vectors import concat, edge_poses, random_poses
    from ik5r.fxconfig import constants, load_config
    from ik5r.hdl.tb.runner import run_block
    from ik5r.report import bitaccuracy, build_report

    t0 = time.perf_counter()
    out = Path(args.output)
    k = constants(load_config(args.config))
    steps = []

    def step(text):
        steps.append((text, time.perf_counter()))
        print(f"[{time.perf_counter() - t0:6.1f} s] {text}", flush=True)

    step(f"Verilog of every block and the IK core ({k.cfg.name}) -> {out / 'verilog'}")
    modules = _verilog(k, out / "verilog")
    step(f"IK core under cocotb on {args.simulator}: {args.poses:,} random reachable poses + the edge set")
    sims = [run_block("ik", "pipelined", k.cfg.name, args.simulator, stream_vectors=min(args.poses, 500),
                      bulk_vectors=args.poses, seed=1, progress=True)]
    for block in BLOCKS:
        step(f"{block} under cocotb on {args.simulator}: {args.block_vectors:,} vectors + the edge set")
        sims.append(run_block(block, "pipelined", k.cfg.name, args.simulator,
                              stream_vectors=min(args.block_vectors, 500), bulk_vectors=args.block_vectors,
                              seed=1))
    step("C solver vs scalar model vs vectorised model")
    poses = concat(random_poses(k, max(args.poses // 8, 1), seed=1), edge_poses(k))
    software = bitaccuracy.software_agreement(k, poses)
    section = bitaccuracy.section(k, software, sims)
    step(f"quantisation report on {args.report_vectors:,} poses -> {out / 'report'}")
    _, summary = build_report(out / "report", vectors=args.report_vectors, config=k.cfg, seed=0,
                              progress=True, extra_sections=[section])
    core = sims[0]
    print()
    print(summary)
    print()
    print("\n".join(bitaccuracy.summary_lines(section.data)))
    print()
    print(f"IK core (pipelined, {k.cfg.name}): latency {core['latency_cycles']} cycles, "
          f"{core['cycles_per_result']} cycle(s) per pose; {len(modules)} Verilog modules in {out / 'verilog'}")
    print(f"report: {(out / 'report' / 'index.html').resolve()}  (JSON: report.json beside it)")
    print(f"demo wall time: {time.perf_counter() - t0:.0f} s")
    return 0 if section.data["total_mismatches"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
