"""The ``ik5r`` command line: one verb per module of ``ik5r.commands``."""

from __future__ import annotations

import argparse
import importlib
import sys

from .errors import InputError

#: Verb modules, in the order ``ik5r --help`` lists them.
VERBS = ("fk", "solve", "report", "verilog", "sim", "synth", "sweep", "firmware")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ik5r", description=__doc__)
    sub = parser.add_subparsers(dest="verb", required=True, metavar="VERB")
    for verb in VERBS:
        importlib.import_module(f"ik5r.commands.{verb}").register(sub)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except InputError as exc:
        print(exc, file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
