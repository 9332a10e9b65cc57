"""``ik5r sweep``: word-length design-space sweep, accuracy against area and Fmax.

For each word width (and optionally each CORDIC iteration count) a config is derived from the
schema by the rule of :mod:`ik5r.sweep` (it reproduces configs/q18, q24, q32); each point gets the
error of the fixed-point IK against float64 (vectorised bit-accurate model, ``--poses`` random
poses) and the LUTs / FFs / DSPs / Fmax of each ``--blocks`` x ``--archs`` after Yosys + nextpnr.
Points run in parallel (``--jobs``, default: all cores); finished ones are cached in DIR/cache, so
a re-run resumes. Writes DIR/sweep.csv, DIR/sweep.json, DIR/error_vs_luts.png (Pareto front
marked), DIR/fmax_vs_width.png and DIR/index.html.
"""

from __future__ import annotations

import argparse
import sys


def _int_list(text: str) -> list[int]:
    try:
        values = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a comma-separated list of integers, got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("empty list")
    return values


def _iterations(text: str):
    return None if text == "auto" else _int_list(text)


def _names(text: str) -> list[str]:
    return [part.strip() for part in text.split(",") if part.strip()]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "sweep", help="word-length sweep: IK error against LUTs / Fmax", description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--widths", type=_int_list, default=None, metavar="W,...",
                        help="word widths (default: 16,18,20,24,28,32)")
    parser.add_argument("--iterations", type=_iterations, default=None, metavar="N,...|auto",
                        help="CORDIC iteration counts crossed with the widths (default: auto = width)")
    parser.add_argument("--blocks", type=_names, default=None, metavar="B,...",
                        help="blocks to synthesise (default: ik when ik5r.hdl provides it, else atan2)")
    parser.add_argument("--archs", type=_names, default=None, metavar="A,...",
                        help="pipelined,iterative|compact (default: compact for the IK core alone, "
                             "whose pipelined P&R takes far longer; else pipelined,iterative)")
    parser.add_argument("-o", "--output", default="build/sweep", metavar="DIR",
                        help="output folder (default: build/sweep)")
    parser.add_argument("--jobs", type=int, default=None, metavar="N",
                        help="parallel processes (default: os.cpu_count())")
    parser.add_argument("--poses", type=int, default=100_000, metavar="N",
                        help="random poses for the error figures (default: 100000)")
    parser.add_argument("--seed", type=int, default=0, help="pose seed (default: 0)")
    parser.add_argument("--target", choices=("ecp5", "ice40"), default="ecp5")
    parser.add_argument("--device", default=None, help="device (default: 85k / hx8k)")
    parser.add_argument("--speed", type=int, default=None, help="ECP5 speed grade (default: 6)")
    parser.add_argument("--freq", type=float, default=150.0, metavar="MHZ",
                        help="clock constraint for P&R (default: 150)")
    parser.add_argument("--placer", choices=("heap", "sa", "static"), default="heap",
                        help="nextpnr placer (default: heap)")
    parser.add_argument("--no-pnr", action="store_true", help="Yosys only (no Fmax)")
    parser.add_argument("--synth-cache", default="build/synth", metavar="DIR",
                        help="synthesis cache (default: build/synth)")
    parser.add_argument("--timeout", type=float, default=None, metavar="S",
                        help="give up a tool run after S seconds")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(run=run)


def run(args) -> int:
    from ik5r.errors import InputError
    from ik5r.hdl.generate import BLOCKS
    from ik5r.hdl.modes import ARCH_NAMES, ARCHS
    from ik5r.sweep import DEFAULT_WIDTHS, run_sweep
    from ik5r.synth import SynthOptions

    blocks = args.blocks or (["ik"] if "ik" in BLOCKS else ["atan2"])
    for block in blocks:
        if block not in BLOCKS:
            raise InputError("--blocks", f"block {block!r} not available (have {', '.join(BLOCKS)})")
    archs = args.archs or (["compact"] if blocks == ["ik"] else list(ARCHS))
    for arch in archs:
        if arch not in ARCH_NAMES:
            raise InputError("--archs", f"must be pipelined, iterative or compact, got {arch!r}")
    widths = args.widths or list(DEFAULT_WIDTHS)
    for w in widths:
        if not 10 <= w <= 32:
            raise InputError("--widths", f"widths must be in [10, 32], got {w}")
    if args.poses < 1:
        raise InputError("--poses", "must be at least 1")
    opts = SynthOptions(target=args.target, device=args.device, speed=args.speed,
                        freq_mhz=args.freq, placer=args.placer, pnr=not args.no_pnr)
    result = run_sweep(widths, args.iterations, blocks, archs, args.output, args.jobs, args.poses,
                       args.seed, opts, args.synth_cache, args.timeout,
                       progress=not args.no_progress, log=lambda m: print(m, file=sys.stderr))
    front = [p for p in result["points"] if p.get("pareto")]
    print(f"{'point':8} {'block':6} {'arch':10} {'pos max cm':>11} {'pos RMS cm':>11} "
          f"{'joint max':>10} {'LUTs':>7} {'FFs':>7} {'DSP':>4} {'Fmax':>7} {'Pareto':>6}")
    for p in result["points"]:
        g = lambda v, f: "–" if v is None else format(v, f)  # noqa: E731
        print(f"{p['name']:8} {p['block']:6} {p['arch']:10} {g(p.get('position_err_max_cm'), '11.3g')} "
              f"{g(p.get('position_err_rms_cm'), '11.3g')} {g(p.get('joint_err_max_rad'), '10.3g')} "
              f"{g(p.get('luts'), '7d')} {g(p.get('ffs'), '7d')} {g(p.get('dsps'), '4d')} "
              f"{g(p.get('fmax_mhz'), '7.1f')} {'*' if p.get('pareto') else '':>6}")
    names = ", ".join(f"{p['name']} {p['block']} {p['arch']}" for p in front)
    print(f"Pareto front (position error max vs LUTs): {names or 'none'}")
    return 1 if result["meta"]["failures"] else 0
