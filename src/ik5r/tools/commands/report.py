"""ik5r report: the quantisation report (fixed point and float32 against float64) into a folder.

The page (DIR/index.html, DIR/report.json) has the error figures and plots, the worst poses of each
measure as CSV (worst_position.csv, ...: feed one to 'ik5r solve --solver fixed --all'), the
hardware figures of the config from the committed synthesis records, and its provenance (ik5r
version, git commit, tool versions, config hash). With --hdl it also writes the Verilog of every
block and the IK core with their port maps, simulates them under cocotb against the bit-accurate
model, and adds the bit-accuracy section (C, scalar model, vectorised model, HDL): 'make demo' is
this. With --configs q18,q24,... it writes one page comparing the configs instead.
"""

from __future__ import annotations

import argparse

from ik5r.core.fxconfig import DEFAULT_CONFIG
from ik5r.tools import cliopts


def _count(text: str) -> int:
    try:
        value = int(text.replace("_", "").replace(",", ""))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _names(text: str) -> list[str]:
    names = [part.strip() for part in text.split(",") if part.strip()]
    if not names:
        raise argparse.ArgumentTypeError("empty list")
    return names


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "report", help="the report: error against float64, worst poses, hardware figures (HTML + JSON)",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--vectors", type=_count, default=1_000_000, metavar="N",
                        help="random poses, q uniform in the joint limits (default: 1,000,000)")
    parser.add_argument("--config", default=None, metavar="NAME|PATH",
                        help=f"fixed-point config: a shipped name (q18, q24, q32, q32w) or a TOML file "
                             f"(default: {DEFAULT_CONFIG})")
    parser.add_argument("--configs", type=_names, default=None, metavar="NAME,...",
                        help="compare these configs on one page instead (error against bits)")
    parser.add_argument("--arm", default=None, metavar="ARM", help="arm TOML (default: the arm of record)")
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="random seed (default: 0)")
    parser.add_argument("--worst", type=_count, default=20, metavar="N",
                        help="worst poses per measure in the CSV files (default: 20)")
    hdl = parser.add_argument_group("hardware simulation (--hdl)")
    hdl.add_argument("--hdl", action="store_true",
                     help="also simulate the IK core and the blocks under cocotb (bit-accuracy section)")
    hdl.add_argument("--hdl-poses", type=_count, default=None, metavar="N",
                     help="random poses through the simulated IK core (default: min(N of --vectors, 10000))")
    hdl.add_argument("--block-vectors", type=_count, default=None, metavar="N",
                     help="random vectors per block (default: min(N of --vectors, 5000))")
    hdl.add_argument("--simulator", choices=("icarus", "verilator"), default="verilator",
                     help="HDL simulator (default: verilator)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR",
                        help="output folder (index.html, report.json, PNGs, CSVs)")
    cliopts.add_common(parser)
    parser.set_defaults(run=run)


def _run_comparison(args) -> int:
    from ik5r.tools.report.compare import build_comparison, summary_lines

    doc = build_comparison(args.output, args.configs, vectors=args.vectors, arm=args.arm, seed=args.seed,
                           progress=cliopts.show_progress(args), log=lambda m: cliopts.say(args, m, 1))
    if cliopts.verbosity(args) >= 0:
        print("\n".join(summary_lines(doc)))
    print(f"report: {args.output}/index.html")
    return 0


def run(args) -> int:
    from ik5r.tools.report.hdl import build_full_report, hdl_summary

    if args.configs:
        return _run_comparison(args)
    from ik5r.core.arm import load_arm
    from ik5r.core.fxconfig import Constants, load_config

    # Bad config or arm files, or an arm the config cannot hold, fail here, in one line, before
    # any work or progress notes.
    config = load_config(args.config)
    arm = load_arm(args.arm)
    Constants(config, arm)
    doc, summary, bit = build_full_report(
        args.output, vectors=args.vectors, config=config, arm=arm, seed=args.seed,
        hdl=args.hdl, hdl_poses=args.hdl_poses or min(args.vectors, 10_000),
        block_vectors=args.block_vectors or min(args.vectors, 5_000), simulator=args.simulator,
        worst=args.worst, progress=cliopts.show_progress(args), log=lambda m: cliopts.say(args, m))
    if cliopts.verbosity(args) >= 0:
        print(summary)
    else:
        print(summary.splitlines()[-1])
    if bit is not None:
        ok = bit["total_mismatches"] == 0
        lines = hdl_summary(bit)
        print(cliopts.colour(lines[0], ok) if cliopts.verbosity(args) < 0 else
              "\n".join([cliopts.colour(lines[0], ok), *lines[1:]]))
        return 0 if ok else 1
    return 0
