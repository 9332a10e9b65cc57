"""ik5r sweep: word-length design-space sweep, accuracy against area and Fmax, on a Dask cluster.

For each word width (crossed with --iterations and --guard-bits when given) a config is derived from
the schema by the rule of ik5r.tools.sweep (it reproduces configs/q18, q24, q32); each point gets the error
of the fixed-point IK against float64 (vectorised bit-accurate model, --poses random poses) and,
unless --no-synth, the LUTs / FFs / DSPs / Fmax of each --blocks x --arch after Yosys + nextpnr.

Every point runs on a Dask distributed cluster: --scheduler tcp://HOST:PORT sends them to one you
started (see docs/cluster.md), else a LocalCluster of --jobs processes runs them here. A point whose
worker is lost is run again on another; finished points are cached in DIR/cache, so a re-run resumes.
Writes DIR/sweep.csv, DIR/sweep.json, DIR/error_vs_luts.png (Pareto front marked),
DIR/fmax_vs_width.png, DIR/error_vs_width.png and DIR/index.html.
"""

from __future__ import annotations

import argparse
import sys

from ik5r.core.modes import ARCH_NAMES, ARCHS, TARGETS, Block, CoreArch, Target
from ik5r.tools import cliopts


def _int_list(text: str) -> list[int]:
    values = []
    for part in (p.strip() for p in text.split(",")):
        lo, sep, hi = part.partition("..")
        try:
            values += list(range(int(lo), int(hi) + 1)) if sep else [int(part)] if part else []
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"must be integers or ranges A..B separated by commas, got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("empty list")
    return values


def _iterations(text: str):
    return None if text == "auto" else _int_list(text)


def _names(text: str) -> list[str]:
    return [part.strip() for part in text.split(",") if part.strip()]


def _add_axes(parser) -> None:
    parser.add_argument("--widths", type=_int_list, default=None, metavar="W,...",
                        help="word widths, e.g. 16,18,24 or 12..32 (default: 16,18,20,24,28,32)")
    parser.add_argument("--guard-bits", type=_int_list, default=None, metavar="G,...",
                        help="internal guard bits of the IK (ik.internal_guard_bits, 0..8) crossed "
                             "with the widths, e.g. 0..8 (default: 0, names without a g suffix)")
    parser.add_argument("--iterations", type=_iterations, default=None, metavar="N,...|auto",
                        help="CORDIC iteration counts crossed with the widths (default: auto = width)")
    parser.add_argument("--blocks", type=_names, default=None, metavar="B,...",
                        help="blocks to synthesise (default: ik when ik5r.hdl provides it, else atan2)")
    parser.add_argument("--arch", "--archs", dest="archs", type=_names, default=None, metavar="A,...",
                        help="pipelined,compact (iterative = compact) (default: compact for the IK "
                             "core alone, whose pipelined P&R takes far longer; else pipelined,iterative)")
    parser.add_argument("--no-synth", action="store_true",
                        help="error figures only: no synthesis (one point per config)")
    parser.add_argument("--poses", type=int, default=100_000, metavar="N",
                        help="random poses for the error figures (default: 100000)")
    parser.add_argument("--seed", type=int, default=0, help="pose seed (default: 0)")
    parser.add_argument("--arm", default=None, metavar="ARM",
                        help="arm TOML or shipped arm name (default: the arm of record); each width's "
                             "length format then holds that arm (ik5r config --arm)")


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "sweep", help="word-length sweep on a Dask cluster: IK error against LUTs / Fmax",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_axes(parser)
    parser.add_argument("-o", "--output", default="build/sweep", metavar="DIR",
                        help="output folder (default: build/sweep)")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="run the points on this Dask scheduler's workers (default: a "
                             "LocalCluster of --jobs processes)")
    parser.add_argument("--jobs", type=int, default=None, metavar="N",
                        help="worker processes of the LocalCluster (default: os.cpu_count())")
    parser.add_argument("--target", choices=TARGETS, default=Target.ECP5)
    parser.add_argument("--device", default=None, help="device (default: 85k / hx8k)")
    parser.add_argument("--speed", type=int, default=None, help="ECP5 speed grade (default: 6)")
    parser.add_argument("--freq", type=float, default=150.0, metavar="MHZ",
                        help="clock constraint for P&R (default: 150)")
    parser.add_argument("--placer", choices=("heap", "sa", "static"), default=None,
                        help="nextpnr placer (default: heap on ECP5, sa on iCE40)")
    parser.add_argument("--no-pnr", action="store_true", help="Yosys only (no Fmax)")
    parser.add_argument("--synth-cache", default="build/synth", metavar="DIR",
                        help="synthesis cache on each worker's machine (default: build/synth)")
    parser.add_argument("--timeout", type=float, default=None, metavar="S",
                        help="give up a tool run after S seconds")
    cliopts.add_common(parser)
    parser.set_defaults(run=run)


def _check(args) -> tuple[list[str], list[str], list[int]]:
    from ik5r.core.errors import InputError
    from ik5r.hdl.generate import BLOCKS
    from ik5r.tools.sweep_record import DEFAULT_WIDTHS

    blocks = args.blocks or [Block.IK]
    for block in blocks:
        if block not in BLOCKS:
            raise InputError("--blocks", f"block {block!r} not available (have {', '.join(BLOCKS)})")
    archs = args.archs or ([CoreArch.COMPACT] if blocks == [Block.IK] else list(ARCHS))
    for arch in archs:
        if arch not in ARCH_NAMES:
            raise InputError("--arch", f"must be one of {', '.join(ARCH_NAMES)}, got {arch!r}")
    widths = args.widths or list(DEFAULT_WIDTHS)
    for w in widths:
        if not 10 <= w <= 32:
            raise InputError("--widths", f"widths must be in [10, 32], got {w}")
    for g in args.guard_bits or []:
        if not 0 <= g <= 8:
            raise InputError("--guard-bits", f"must be in [0, 8], got {g}")
    if args.poses < 1:
        raise InputError("--poses", "must be at least 1")
    if args.jobs is not None and args.jobs < 1:
        raise InputError("--jobs", "must be at least 1")
    return blocks, archs, widths


def _print_table(points: list[dict]) -> None:
    print(f"{'point':10} {'block':6} {'arch':10} {'pos max cm':>11} {'pos RMS cm':>11} "
          f"{'joint max':>10} {'LUTs':>7} {'FFs':>7} {'DSP':>4} {'Fmax':>7} {'Pareto':>6}")
    for p in points:
        g = lambda v, f: format("–", ">" + f.rstrip("dfg").split(".")[0]) if v is None else format(v, f)  # noqa: E731
        print(f"{p['name']:10} {p['block'] or '–':6} {p['arch'] or '–':10} "
              f"{g(p.get('position_err_max_cm'), '11.3g')} {g(p.get('position_err_rms_cm'), '11.3g')} "
              f"{g(p.get('joint_err_max_rad'), '10.3g')} {g(p.get('luts'), '7d')} {g(p.get('ffs'), '7d')} "
              f"{g(p.get('dsps'), '4d')} {g(p.get('fmax_mhz'), '7.1f')} {'*' if p.get('pareto') else '':>6}")


def run(args) -> int:
    from ik5r.tools.sweep import run_sweep
    from ik5r.tools.sweep_record import SweepOptions
    from ik5r.tools.synth import SynthOptions

    from ik5r.core.arm import is_seed_arm, load_arm

    blocks, archs, widths = _check(args)
    arm = load_arm(args.arm)
    arm = None if is_seed_arm(arm) else arm
    opts = SynthOptions(target=args.target, device=args.device, speed=args.speed,
                        freq_mhz=args.freq, placer=args.placer, pnr=not args.no_pnr)
    options = SweepOptions(widths=widths, iterations=args.iterations, guard_bits=args.guard_bits,
                           blocks=blocks, archs=archs, synth=not args.no_synth, poses=args.poses,
                           seed=args.seed, synth_options=opts, synth_cache=str(args.synth_cache),
                           timeout=args.timeout)
    result = run_sweep(options, arm=arm, out_dir=args.output, jobs=args.jobs, scheduler=args.scheduler,
                       progress=cliopts.show_progress(args), log=lambda m: cliopts.say(args, m),
                       note=(lambda m: cliopts.say(args, m)) if cliopts.verbosity(args) >= 1 else None)
    _print_table(result.points)
    if not args.no_synth:
        front = [p for p in result.points if p.get("pareto")]
        names = ", ".join(f"{p['name']} {p['block']} {p['arch']}" for p in front)
        print(f"Pareto front (position error max vs LUTs): {names or 'none'}")
    for failure in result.failures:
        print(f"failed: {' '.join(failure['point'])}: {failure['error'].splitlines()[0]}", file=sys.stderr)
    return 1 if result.failures else 0
