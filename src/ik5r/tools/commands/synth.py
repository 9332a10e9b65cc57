"""``ik5r synth``: area and Fmax of a block after Yosys synthesis and nextpnr place-and-route.

ECP5 (default LFE5U-85F, speed 6, CABGA381, out of context) or iCE40. Prints one line per block
and architecture: LUT4 sites (TRELLIS_COMB / ICESTORM_LC), flip-flops, carry cells, DSPs, block
RAMs, Fmax of ``clk``, latency, cycles per result and results per second (Fmax / cycles per
result). ``--json FILE`` writes every figure (also the critical path and the tool versions).
Results are cached under ``build/synth/`` (keyed by the Verilog, the tool versions and the flags).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

from ik5r.core.fxconfig import DEFAULT_CONFIG
from ik5r.core.modes import ARCH_NAMES, BLOCKS, DSPS, TARGETS, Arch, Block, CoreArch, Target
from ik5r.tools import cliopts
from ik5r.tools.design import add_arm_argument

BLOCK_CHOICES = (*BLOCKS, "cpu", "all")
ARCH_CHOICES = (*ARCH_NAMES, "all")


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "synth", help="LUTs, FFs, DSPs and Fmax of a block (Yosys + nextpnr)", description=__doc__)
    parser.add_argument("--block", choices=BLOCK_CHOICES, default=Block.ATAN2,
                        help="block (default: atan2; all: every available block; cpu: the soft "
                             "CPU SoC running the C solver, see --cpu)")
    parser.add_argument("--cpu", default=None, metavar="NAME",
                        help="with --block cpu: vexriscv (rv32im) or vexriscv_min (rv32i) "
                             "(default: both); NAME+compact or NAME+pipelined: the SoC with the IK "
                             "peripheral and the firmware that calls it")
    parser.add_argument("--arch", choices=ARCH_CHOICES, default=Arch.PIPELINED,
                        help="architecture (default: pipelined; iterative and compact are the "
                             "same choice: one item in flight; all: both)")
    parser.add_argument("--config", default=None, metavar="CFG",
                        help=f"fixed-point config TOML or shipped name (default: {DEFAULT_CONFIG})")
    add_arm_argument(parser)
    parser.add_argument("--target", choices=TARGETS, default=Target.ECP5,
                        help="FPGA family (default: ecp5)")
    parser.add_argument("--device", default=None,
                        help="device: ecp5 12k|25k|45k|85k|um-85k|..., ice40 hx8k|up5k|... "
                             "(default: 85k / hx8k)")
    parser.add_argument("--package", default=None, help="package (default: CABGA381 / the largest)")
    parser.add_argument("--speed", type=int, default=None, help="ECP5 speed grade 6|7|8 (default: 6)")
    parser.add_argument("--freq", type=float, default=150.0, metavar="MHZ",
                        help="clock constraint for timing-driven P&R (default: 150)")
    parser.add_argument("--placer", choices=("heap", "sa", "static"), default=None,
                        help="nextpnr placer (default: heap on ECP5, sa on iCE40)")
    parser.add_argument("--router", choices=("router1", "router2"), default="router1",
                        help="nextpnr router (default: router1; a router2 run is a design point of its own)")
    parser.add_argument("--seed", type=int, default=1, help="nextpnr seed (default: 1)")
    parser.add_argument("--threads", type=int, default=2, help="nextpnr --threads (default: 2)")
    parser.add_argument("--no-pnr", action="store_true", help="Yosys only: cell counts, no Fmax")
    parser.add_argument("--dsp", choices=DSPS, default=None,
                        help="primitives: ECP5 MULT18X18D instances with their input and output "
                             "registers and CCU2C add/sub chains, or generic operators mapped by "
                             "Yosys (default: ecp5 on ECP5 for the pipelined arch, generic on iCE40; the "
                             "compact IK core's multiplier takes MULT18X18D only when --dsp ecp5 is given)")
    cliopts.add_rotations_per_stage(parser)
    cliopts.add_max_dsp(parser)
    cliopts.add_dsp_output_regs(parser)
    cliopts.add_wide_product(parser)
    cliopts.add_poses(parser)
    parser.add_argument("--cache", default="build/synth", metavar="DIR",
                        help="cache folder (default: build/synth)")
    parser.add_argument("--force", action="store_true", help="ignore cached results")
    parser.add_argument("--timeout", type=float, default=None, metavar="S",
                        help="give up a tool run after S seconds")
    parser.add_argument("--json", default=None, metavar="FILE", help="write the figures as JSON (one result: its dict; several: {\"results\": [...]})")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    parser.set_defaults(run=run)


def _available_blocks() -> tuple[str, ...]:
    from ik5r.hdl.generate import BLOCKS
    return tuple(BLOCKS)


def _blocks_and_cpus(args) -> tuple[tuple, tuple]:
    """The blocks ``--block`` names (``cpu``: the soft CPU) and the CPUs ``--cpu`` names (all when
    not given); InputError (exit 2) on a block ``ik5r.hdl.generate`` does not have, an unknown
    CPU, or ``--dsp-output-regs`` asked of anything but the pipelined IK core."""
    from ik5r.core.errors import InputError

    if args.dsp_output_regs and (args.block, args.arch) != (Block.IK, CoreArch.PIPELINED):
        # Before anything runs (not at the first other block of --block all).
        raise InputError("--dsp-output-regs", f"applies to the pipelined IK core (--block ik --arch pipelined), "
                                              f"not to --block {args.block} --arch {args.arch}")
    available = _available_blocks()
    if args.block == "all":
        return available, ()
    if args.block == "cpu":
        from ik5r.hdl.soc.system import CPUS
        if args.cpu is not None and args.cpu.partition("+")[0] not in CPUS:
            raise InputError("--cpu", f"must be one of {', '.join(CPUS)} (+compact or +pipelined: with "
                                      f"the IK peripheral), got {args.cpu!r}")
        return ("cpu",), (args.cpu,) if args.cpu else tuple(CPUS)
    if args.block not in available:
        raise InputError("--block", f"block {args.block!r} is not available in ik5r.hdl.generate "
                                    f"(have {', '.join(available)})")
    return (args.block,), ()


def _synthesize_one(synthesize, design, opts, args, log, status):
    """One design through the flow, nextpnr's phase on the status line (cleared after)."""
    try:
        return synthesize(design, opts, cache_dir=args.cache, force=args.force, log=log,
                          timeout=args.timeout, progress=status and status.show)
    finally:
        if status:
            status.clear()


def run(args) -> int:
    from ik5r.hdl.generate import archs_of
    from ik5r.tools.design import Design
    from ik5r.tools.synth import SynthOptions, synthesize
    from ik5r.tools.synth_progress import StatusLine, critical_path_line, format_table

    blocks, cpus = _blocks_and_cpus(args)
    # The config and the arm, loaded once; an arm the config cannot hold is refused here (exit 2).
    base = Design.resolve(Block.IK, CoreArch.PIPELINED, config=args.config, arm=args.arm)
    opts = SynthOptions(target=args.target, device=args.device, package=args.package,
                        speed=args.speed, freq_mhz=args.freq, placer=args.placer, router=args.router,
                        seed=args.seed, threads=args.threads, pnr=not args.no_pnr, dsp=args.dsp,
                        rotations_per_stage=args.rotations_per_stage, max_dsp=args.max_dsp,
                        wide_product=args.wide_product, dsp_output_regs=args.dsp_output_regs, poses=args.poses).resolved()

    # Where nextpnr is (hours on the 85k), in one line rewritten in place: on a terminal only.
    status = StatusLine(sys.stderr) if cliopts.show_progress(args) else None

    def log(message):
        if status:
            status.clear()
        if not args.quiet:
            print(f"[{time.strftime('%H:%M:%S')}] {message}", file=sys.stderr, flush=True)

    results = []
    failed = 0
    for block in blocks:
        if block == "cpu":
            archs = cpus
        else:
            archs = archs_of(block) if args.arch == "all" else (args.arch,)
        for arch in archs:
            start = time.perf_counter()
            design = Design.resolve(block, arch, config=base.config, arm=base.arm)
            try:
                result = _synthesize_one(synthesize, design, opts, args, log, status)
            except (RuntimeError, OSError) as exc:  # also SoftCpuError
                print(f"error: {block} {arch}: {exc}", file=sys.stderr)
                failed += 1
                continue
            except subprocess.TimeoutExpired:
                print(f"error: {block} {arch}: a tool run took longer than --timeout {args.timeout:g} s "
                      "and was stopped", file=sys.stderr)
                failed += 1
                continue
            result["wall_seconds"] = round(time.perf_counter() - start, 2)
            results.append(result)
    if results:
        print(f"{opts.target} {opts.device}"
              f"{' speed ' + str(opts.speed) if opts.speed else ''} {opts.package}, "
              f"clock constraint {opts.freq_mhz:g} MHz, placer {opts.placer}, {opts.router}")
        print(format_table(results))
        for line in filter(None, map(critical_path_line, results)):
            print(line)
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        doc = results[0] if len(results) == 1 else {"results": results}
        path.write_text(json.dumps(doc, indent=2) + "\n")
    return 1 if failed else 0
