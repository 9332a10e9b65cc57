"""``ik5r report``: the quantisation report (fixed point and float32 against float64) into a folder."""

from __future__ import annotations

import argparse

from ik5r.fxconfig import DEFAULT_CONFIG


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "report", help="quantisation report: fixed point and float32 against float64 (HTML + JSON)",
        description=__doc__)
    parser.add_argument("--vectors", type=_positive, default=1_000_000, metavar="N",
                        help="random poses, q uniform in the joint limits (default: 1,000,000)")
    parser.add_argument("--config", default=None, metavar="CFG",
                        help=f"fixed-point config TOML or shipped name (default: {DEFAULT_CONFIG})")
    parser.add_argument("--arm", default=None, metavar="ARM", help="arm TOML (default: the arm of record)")
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="random seed (default: 0)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("-o", "--output", required=True, metavar="DIR",
                        help="output folder (index.html, report.json, PNGs)")
    parser.set_defaults(run=run)


def run(args) -> int:
    from ..report import build_report

    _, summary = build_report(args.output, vectors=args.vectors, config=args.config, arm=args.arm,
                              seed=args.seed, progress=not args.no_progress)
    print(summary)
    return 0
