"""``ik5r verilog``: Verilog of the CORDIC/sqrt/acos blocks and their port maps (JSON).

Writes ``DIR/<module>.v`` and ``DIR/<module>.json`` per block and architecture, with
``<module>`` = ``ik5r_<block>_<arch>``. The output is deterministic (byte-identical between runs).
``--arm`` builds the IK core for that arm (its constants are in the Verilog; its name and a hash
of its DH numbers in the header and the port map); an arm the config cannot hold is refused.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ik5r.core.fxconfig import DEFAULT_CONFIG
from ik5r.core.modes import ARCH_NAMES, BLOCKS, DSPS, Arch, Block, CoreArch, Dsp
from ik5r.tools import cliopts
from ik5r.tools.design import add_arm_argument

BLOCK_CHOICES = (*BLOCKS, "all")
ARCH_CHOICES = (*ARCH_NAMES, "all")


def _tag_width(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if not 0 <= value <= 64:
        raise argparse.ArgumentTypeError(f"must be in [0, 64], got {value}")
    return value


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "verilog", help="Verilog of the hardware blocks and their port maps (JSON)",
        description=__doc__)
    parser.add_argument("-o", "--output", default="build/verilog", metavar="DIR",
                        help="output folder (default: build/verilog)")
    parser.add_argument("--config", default=None, metavar="CFG",
                        help=f"fixed-point config TOML or shipped name (default: {DEFAULT_CONFIG})")
    add_arm_argument(parser)
    parser.add_argument("--block", choices=BLOCK_CHOICES, default="all",
                        help="block to generate (default: all)")
    parser.add_argument("--arch", choices=ARCH_CHOICES, default=Arch.PIPELINED,
                        help="pipelined (1 result/cycle); iterative or compact: the small one (blocks: 1 "
                             "step/cycle; IK core: compact); all: both (default: pipelined)")
    parser.add_argument("--tag-width", type=_tag_width, default=0, metavar="N",
                        help="width of the tag field carried through each block (default: 0)")
    parser.add_argument("--dsp", choices=DSPS, default=Dsp.GENERIC,
                        help="primitives of the pipelined arch (with --arch all, the others stay generic): "
                             "generic operators (any FPGA), or ECP5 "
                             "MULT18X18D instances using their input and output registers and CCU2C "
                             "add/sub chains; with --block ik --arch compact: the compact core's "
                             "multiplier on MULT18X18D whose input registers are its limb registers "
                             "(module name ik5r_<block>_dspecp5_<arch>; same latency, same bits) "
                             "(default: generic)")
    cliopts.add_rotations_per_stage(parser)
    cliopts.add_max_dsp(parser)
    cliopts.add_dsp_output_regs(parser)
    cliopts.add_wide_product(parser)
    cliopts.add_poses(parser)
    parser.set_defaults(run=run)


def run(args) -> int:
    from ik5r.core.errors import InputError
    from ik5r.hdl.generate import BLOCKS, archs_of, resolve_arch
    from ik5r.tools.design import Design

    # The compact IK core maps its multiplier to primitives when asked by name (not by --arch all).
    compact_core = args.block == Block.IK and args.arch in (CoreArch.COMPACT, Arch.ITERATIVE)
    if args.dsp != Dsp.GENERIC and args.arch not in (Arch.PIPELINED, "all") and not compact_core:
        raise InputError("--dsp", f"{args.dsp} primitives apply to the pipelined architecture and the "
                                  f"compact IK core, not to --block {args.block} --arch {args.arch}")
    if args.arch not in (Arch.PIPELINED, "all"):
        cliopts.rotations_option(args, args.arch)       # exit 2 before anything is written
    cliopts.max_dsp_option(args, Arch.PIPELINED if args.arch == "all" else args.arch, args.dsp)
    if args.block != "all" and args.arch != "all":
        cliopts.wide_option(args, args.block, resolve_arch(args.block, args.arch))
        cliopts.poses_option(args, args.block, resolve_arch(args.block, args.arch))
    if args.dsp_output_regs:
        # The pipelined IK core's option (of --block all / --arch all, that core).
        cliopts.dsp_output_regs_option(args, Block.IK if args.block == "all" else args.block,
                                       Arch.PIPELINED if args.arch == "all" else args.arch, args.dsp)
    # The config and the arm, loaded once; an arm the config cannot hold is refused (exit 2).
    base = Design.resolve(Block.IK, CoreArch.PIPELINED, config=args.config, arm=args.arm)
    blocks = BLOCKS if args.block == "all" else (args.block,)
    out_dir = Path(args.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    for block in blocks:
        for arch in archs_of(block) if args.arch == "all" else (resolve_arch(block, args.arch),):
            # With --arch all, the small architectures are generic (they have no primitive mapping).
            dsp = args.dsp if arch == Arch.PIPELINED or compact_core else Dsp.GENERIC
            per_stage = 1
            if args.arch != "all" or arch == Arch.PIPELINED:
                per_stage = cliopts.rotations_option(args, arch).get("rotations_per_stage", 1)
            # --wide-product (the compact IK core's option) and --dsp-output-regs (the pipelined
            # one's, with ECP5 DSPs): of --block all / --arch all, that core.
            options = {"wide_product": True} if args.wide_product and (block, arch) == (Block.IK, CoreArch.COMPACT) else {}
            if args.poses != 1 and (block, arch) == (Block.IK, CoreArch.COMPACT):
                options["poses"] = args.poses
            if (block, arch, dsp) == (Block.IK, Arch.PIPELINED, Dsp.ECP5):
                options.update(cliopts.dsp_output_regs_option(args, block, arch, dsp))
            design = Design.resolve(block, arch, config=base.config, arm=base.arm, tag_width=args.tag_width,
                                    dsp=dsp, rotations_per_stage=per_stage, **options,
                                    **(cliopts.max_dsp_option(args, arch, dsp) if dsp == Dsp.ECP5 else {}))
            text, pmap = design.verilog()
            module = pmap["module"]
            (out_dir / f"{module}.v").write_text(text)
            (out_dir / f"{module}.json").write_text(json.dumps(pmap, indent=2) + "\n")
            print(f"{out_dir / module}.v  latency {pmap['latency_cycles']} cycles, "
                  f"{pmap['cycles_per_result']} cycle(s)/result")
    return 0
