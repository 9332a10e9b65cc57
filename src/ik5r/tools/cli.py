"""The ik5r command line: one verb per module of ik5r.tools.commands.

Every verb takes -q/--quiet and -v/--verbose; progress bars appear only on a terminal. Run
'ik5r VERB --help' for a verb's options.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from ik5r import __version__
from ik5r.core.errors import InputError

from . import cliopts

#: Verb modules, in the order ``ik5r --help`` lists them.
VERBS = ("fk", "solve", "report", "verilog", "sim", "synth", "sweep", "firmware", "board", "config", "arms")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ik5r", description=__doc__)
    parser.add_argument("--version", action="version", version=f"ik5r {__version__}")
    sub = parser.add_subparsers(dest="verb", required=True, metavar="VERB")
    for verb in VERBS:
        importlib.import_module(f"ik5r.tools.commands.{verb}").register(sub)
    for verb_parser in sub.choices.values():
        cliopts.add_common(verb_parser)
        cliopts.plain_help(verb_parser)
    for choice in sub._choices_actions:
        choice.help = cliopts.plain_text(choice.help)
    return parser


#: Arguments naming an output file or folder: checked before a verb starts its work.
OUTPUT_ARGUMENTS = ("output", "json", "cache", "synth_cache")


def check_outputs(args) -> None:
    """InputError unless every output path of ``args`` can be created: its nearest existing
    ancestor is a writable folder (a verb may create the folders below it)."""
    from pathlib import Path

    for name in OUTPUT_ARGUMENTS:
        value = getattr(args, name, None)
        if value is None or str(value) == "-":
            continue
        path = Path(value)
        ancestor = path.parent
        while not ancestor.exists() and ancestor != ancestor.parent:
            ancestor = ancestor.parent
        if not ancestor.is_dir():
            raise InputError(value, f"cannot be created: {str(ancestor)!r} is not a folder")
        if not os.access(ancestor, os.W_OK | os.X_OK):
            raise InputError(value, f"cannot be created: folder {str(ancestor)!r} is not writable")


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        check_outputs(args)
        return args.run(args)
    except InputError as exc:
        print(exc, file=sys.stderr)
        return 2
    except OSError as exc:
        if isinstance(exc, BrokenPipeError):
            return 1
        where = exc.filename if exc.filename is not None else f"ik5r {args.verb}"
        print(f"{where}: {exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
