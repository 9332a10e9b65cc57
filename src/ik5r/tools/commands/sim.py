"""``ik5r sim``: run a hardware block under cocotb against the bit-accurate model.

Generates the block's Verilog (``ik5r.hdl.generate``), builds it with Icarus or Verilator under
``build/sim/<block>_<arch>_<config>[_arm-<arm>]_<sim>/`` and runs two cocotb tests (``src/ik5r/tools/testbench/stream_tb.py``):

* a cocotb-driven stream run (``--stream-vectors`` + the edge set) with random idle cycles,
  random back-pressure with long stalls and a reset in the middle of traffic, which also measures
  latency and cycles per result;
* a fast bulk run of ``--vectors`` random vectors + the block's directed edge set (zero, full
  scale, most negative word, +-1 for acos, ...) streamed by a generated Verilog wrapper, with a
  progress bar.

Every output field is compared bit for bit with ``ik5r.firmware_model.model`` and the tag for order and
loss; errors against float64 numpy (atan2: np.arctan2, sqrt: np.sqrt, acos: np.arccos, rotate: a
float rotation, ik: the float reference ``ik5r.core.reference.ik``'s same branch, worst joint, over
poses both solve with no status bit) are reported in output LSB. Exit status 1 on any mismatch.

``--block ik`` is the IK core (``hdl/pipelined/core.py``): random reachable poses (one in ten rows random
words) plus the directed set, checked against the vectorised model ``vector.solve_batch``
(itself checked against ``model.ik_solve`` on the edge set and a sample).

``--block ik --arch compact --serial 16`` simulates the compact core's word-serial wrapper with
16-bit beats (as placed on the iCE40 UP5K) in the cocotb-driven stream run only (it has no bulk
run): poses go in as beats, results are reassembled from beats (``src/ik5r/tools/testbench/serial.py``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from ik5r.core.fxconfig import DEFAULT_CONFIG
from ik5r.core.modes import ARCH_NAMES, BLOCKS, DSPS, Arch, Block, CoreArch, Dsp
from ik5r.tools import cliopts
from ik5r.tools.design import add_arm_argument


def _count(text: str) -> int:
    try:
        value = int(float(text)) if "e" in text.lower() else int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def _beat_bits(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if not 1 <= value <= 32:
        raise argparse.ArgumentTypeError(f"must be in [1, 32], got {value}")
    return value


def _blocks() -> tuple[str, ...]:
    return BLOCKS


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "sim", help="simulate a hardware block under cocotb against the bit-accurate model",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--block", required=True, choices=_blocks(), help="block to simulate")
    parser.add_argument("--arch", choices=ARCH_NAMES, default=Arch.PIPELINED,
                        help="architecture (default: pipelined); for the IK core (--block ik) "
                             "'compact' is its iterative elaboration, the same as 'iterative'")
    parser.add_argument("--vectors", type=_count, default=10000, metavar="N",
                        help="random vectors of the bulk run, plus the edge set (default: 10000)")
    parser.add_argument("--stream-vectors", type=_count, default=None, metavar="N",
                        help="random vectors of the cocotb-driven run with idles, back-pressure and a "
                             "mid-traffic reset, plus the edge set (default: min(N, 1000); 0 skips it)")
    parser.add_argument("--simulator", choices=("icarus", "verilator"), default=None,
                        help="simulator (default: $SIM or icarus)")
    parser.add_argument("--seed", type=int, default=1, help="random seed (default: 1)")
    parser.add_argument("--config", default=None, metavar="CFG",
                        help=f"fixed-point config TOML or shipped name (default: {DEFAULT_CONFIG})")
    add_arm_argument(parser)
    parser.add_argument("--json", default=None, metavar="FILE", help="write the result JSON here")
    parser.add_argument("--pattern", choices=("random", "full"), default="random",
                        help="bulk run: random valid/ready patterns with long stalls, or full rate "
                             "(default: random)")
    parser.add_argument("--waves", action="store_true", help="record FST waves (also WAVES=1)")
    parser.add_argument("--tag-width", type=int, default=8, metavar="N", help="tag field width (default: 8)")
    parser.add_argument("--dsp", choices=DSPS, default=Dsp.GENERIC,
                        help="primitives of the pipelined arch: generic operators, or ECP5 "
                             "MULT18X18D (with their registers) and CCU2C instances (simulated "
                             "with their models in hdl/sim/) (default: generic)")
    parser.add_argument("--serial", type=_beat_bits, default=None, metavar="B",
                        help="--block ik --arch compact only: simulate its word-serial wrapper with "
                             "B-bit beats (16 as placed on the iCE40 UP5K), in the stream run only: "
                             "--stream-vectors random poses (default: min(--vectors, 1000)) plus the "
                             "directed set")
    cliopts.add_rotations_per_stage(parser)
    cliopts.add_dsp_output_regs(parser)
    cliopts.add_wide_product(parser)
    cliopts.add_poses(parser)
    parser.add_argument("--harness", action="store_true",
                        help="the bulk run on the Verilator C++ harness fed from a file (much faster than "
                             "cocotb; the cocotb stream run, with its protocol checks, still runs first)")
    cliopts.add_common(parser)
    parser.set_defaults(run=run)


def run(args) -> int:
    from ik5r.tools.design import Design
    from ik5r.tools.testbench.runner import default_simulator, run_block

    if args.serial is not None and (args.block != Block.IK or args.arch not in (CoreArch.COMPACT, Arch.ITERATIVE)):
        print("ik5r sim: --serial is the compact IK core's wrapper: use it with --block ik --arch compact",
              file=sys.stderr)
        return 2
    sim = args.simulator or default_simulator()
    stream_vectors = min(args.vectors, 1000) if args.stream_vectors is None else args.stream_vectors
    if args.serial is not None and args.poses != 1:
        print("ik5r sim: --poses is the struct-stream compact core's option, not its word-serial wrapper's",
              file=sys.stderr)
        return 2
    if args.serial is not None and not stream_vectors:
        print("ik5r sim: --serial runs the stream run only: --stream-vectors must be > 0", file=sys.stderr)
        return 2
    from ik5r.hdl.generate import resolve_arch

    per_stage = cliopts.rotations_option(args, resolve_arch(args.block, args.arch)).get("rotations_per_stage", 1)
    arch = resolve_arch(args.block, args.arch)
    options = {**cliopts.wide_option(args, args.block, arch), **cliopts.poses_option(args, args.block, arch),
               **cliopts.dsp_output_regs_option(args, args.block, arch, args.dsp)}
    if args.harness and (args.serial is not None or sim != "verilator"):
        print("ik5r sim: --harness is a Verilator bulk run: use it with --simulator verilator, without --serial",
              file=sys.stderr)
        return 2
    waves = True if args.waves else None
    # InputError (exit 2) on a bad config or arm, or an arm the config cannot hold.
    design = Design.resolve(args.block, args.arch, config=args.config, arm=args.arm, tag_width=args.tag_width,
                            dsp=args.dsp, serial=args.serial,
                            rotations_per_stage=per_stage, **options)
    t0 = time.perf_counter()
    result = run_block(design, sim, stream_vectors=stream_vectors, seed=args.seed,
                       bulk_vectors=0 if args.serial or args.harness else max(args.vectors, 1),
                       pattern=args.pattern, waves=waves, progress=cliopts.show_progress(args),
                       chunk=max(50000, args.vectors // 10))
    if args.harness:
        result = _with_harness(result, args, design)
    wall = time.perf_counter() - t0
    doc = _record(result, args, wall)
    text = json.dumps(doc, indent=2)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(text + "\n")
    verdict = "OK" if doc["mismatches"] == 0 else "MISMATCH"
    print(f"{verdict}: {doc['block']} {doc['arch']} {doc['config']} arm {doc['arm']} on {sim}: {doc['vectors']} vectors, "
          f"{doc['mismatches']} mismatches, max error {doc['max_error_lsb']} LSB, "
          f"rms {doc['rms_error_lsb']} LSB, latency {doc['latency_cycles']}, "
          f"cycles/result {doc['cycles_per_result']}, {_rate(doc)}, wall {wall:.1f} s")
    if doc["first_mismatch"]:
        print("first mismatch:", json.dumps(doc["first_mismatch"]), file=sys.stderr)
    return 0 if doc["mismatches"] == 0 else 1


def _record(result: dict, args, wall: float) -> dict:
    """The JSON record of one ``ik5r sim`` run: ``run_block``'s result, the options and the wall
    time of the whole run."""
    bulk = result.get("bulk") or {}
    return {
        "block": result["block"], "arch": result["arch"], "config": result["config"], "arm": result["arm"],
        "simulator": result["simulator"], "seed": args.seed, "dsp": args.dsp, "serial": args.serial,
        "vectors": result["vectors"], "mismatches": result["mismatches"],
        "first_mismatch": result["first_mismatch"], "field_mismatches": result["field_mismatches"],
        "tag_errors": result["tag_errors"], "stale_outputs": result["stale_outputs"],
        "max_error_lsb": result["max_error_lsb"], "rms_error_lsb": result["rms_error_lsb"],
        "latency_cycles": result["latency_cycles"], "cycles_per_result": result["cycles_per_result"],
        "latency_cycles_portmap": result["latency_cycles_portmap"],
        "cycles_per_result_portmap": result["cycles_per_result_portmap"],
        "wall_seconds": wall,
        # Throughput of the bulk run (stimulus, simulation, capture and bit-exact check of every
        # vector); the end-to-end figure also counts generation, build and the stream run.
        "vectors_per_second": bulk.get("vectors_per_second"),
        "end_to_end_vectors_per_second": result["vectors"] / wall if wall else None,
        "build_seconds": result["build_seconds"], "stream": result["stream"], "bulk": result["bulk"],
        "build_dir": result["build_dir"], "waves": result["waves"], "log": result["log"],
    }


def _with_harness(result: dict, args, design) -> dict:
    """The stream run's result with the harness's bulk run of the same design (arm, config and
    options) merged in as the bulk part."""
    from ik5r.tools.testbench.harness import run_harness

    bulk = run_harness(design, vectors=args.vectors, seed=args.seed, pattern=args.pattern)
    merged = dict(result)
    for key in ("vectors", "mismatches", "tag_errors", "stale_outputs", "hold_violations"):
        merged[key] = (result.get(key) or 0) + (bulk.get(key) or 0)
    merged["first_mismatch"] = result["first_mismatch"] or bulk["first_mismatch"]
    merged["field_mismatches"] = {name: result["field_mismatches"].get(name, 0) + count
                                  for name, count in bulk["field_mismatches"].items()}
    errors = [v for v in (result["max_error_lsb"], bulk["max_error_lsb"]) if v is not None]
    merged["max_error_lsb"] = max(errors) if errors else None
    merged["bulk"] = dict(bulk["harness"], simulator="verilator-harness", error_items=bulk["error_items"],
                          rms_error_lsb=bulk["rms_error_lsb"])
    merged["build_seconds"] = result["build_seconds"] + bulk["build_seconds"]
    return merged


def _rate(doc: dict) -> str:
    """Vectors per second of the bulk run, or of the stream run when there is no bulk run."""
    stream = doc["stream"] or {}
    if doc["vectors_per_second"] is None and stream.get("wall_seconds"):
        return f"{stream['vectors'] / stream['wall_seconds']:.0f} vectors/s (stream)"
    return f"{doc['vectors_per_second'] or 0:.0f} vectors/s (bulk)"
