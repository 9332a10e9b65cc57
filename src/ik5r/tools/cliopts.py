"""What every verb of the command line shares: -q/-v, the progress-bar and colour policy, plain help.

``ik5r.tools.cli`` calls :func:`add_common` and :func:`plain_help` on every verb's parser after the verb
registered it, so a verb gets ``-q/--quiet`` and ``-v/--verbose`` without code of its own; a verb
reads them back through :func:`verbosity`, :func:`show_progress` and :func:`say`.

Progress bars go to standard error, and only when it is a terminal (a redirected log gets none) and
neither --quiet nor --no-progress was given. Colour is used only on a terminal, never with
``NO_COLOR`` set (https://no-color.org) or ``TERM=dumb``.
"""

from __future__ import annotations

import argparse
import os
import re
import sys

from ik5r.core.modes import DSP_OUTPUT_REGS, Arch, Block, CoreArch, Dsp

_MARKUP = (
    (re.compile(r":[a-z]+:`~?\.*([^`]+)`"), r"\1"),   # :mod:`ik5r.tools.sweep`, :func:`~.x` -> the name
    (re.compile(r"``([^`]+)``"), r"\1"),                 # ``ik5r fk`` -> ik5r fk
)


def plain_text(text: str | None) -> str | None:
    """Help text without reStructuredText markup."""
    if not text:
        return text
    for pattern, repl in _MARKUP:
        text = pattern.sub(repl, text)
    return text


def _readable_type(func):
    """An argparse type whose own name is internal: its errors name the option, not the function."""
    def convert(text):
        try:
            return func(text)
        except (ValueError, TypeError):
            raise argparse.ArgumentTypeError(f"invalid value {text!r}") from None
    convert.__name__ = "value"
    return convert


def plain_help(parser: argparse.ArgumentParser) -> None:
    """Strip markup from the description and option help; hide internal type-function names."""
    parser.description = plain_text(parser.description)
    parser.epilog = plain_text(parser.epilog)
    for action in parser._actions:
        action.help = plain_text(action.help)
        kind = action.type
        if callable(kind) and getattr(kind, "__name__", "").startswith("_"):
            action.type = _readable_type(kind)


def add_common(parser: argparse.ArgumentParser) -> None:
    """-q/--quiet, -v/--verbose and --no-progress, each unless the verb defines it already."""
    have = parser._option_string_actions
    if "-q" not in have and "--quiet" not in have:
        parser.add_argument("-q", "--quiet", action="store_true",
                            help="print only results and errors: no progress, no notes")
    if "-v" not in have and "--verbose" not in have:
        parser.add_argument("-v", "--verbose", action="count", default=0,
                            help="say more (repeat for more detail)")
    if "--no-progress" not in have:
        parser.add_argument("--no-progress", action="store_true",
                            help="no progress bar (there is none unless standard error is a terminal)")


def verbosity(args) -> int:
    """-1 with --quiet, else the number of -v given (0 by default)."""
    return -1 if getattr(args, "quiet", False) else int(getattr(args, "verbose", 0) or 0)


def show_progress(args=None, stream=None) -> bool:
    """Progress bars: on a terminal only, and not with --quiet or --no-progress."""
    stream = stream or sys.stderr
    if args is not None and (getattr(args, "quiet", False) or getattr(args, "no_progress", False)):
        return False
    return bool(getattr(stream, "isatty", lambda: False)())


def use_colour(stream=None) -> bool:
    """Colour only on a terminal, and never with NO_COLOR set or TERM=dumb."""
    stream = stream or sys.stdout
    if os.environ.get("NO_COLOR", "") != "" or os.environ.get("TERM") == "dumb":
        return False
    return bool(getattr(stream, "isatty", lambda: False)())


def colour(text: str, good: bool, stream=None) -> str:
    """``text`` in green (good) or red, when :func:`use_colour` allows."""
    if not use_colour(stream):
        return text
    return f"\033[{'32' if good else '31'}m{text}\033[0m"


def say(args, message: str, level: int = 0) -> None:
    """A note on standard error, shown when the verbosity is at least ``level``."""
    if verbosity(args) >= level:
        print(message, file=sys.stderr, flush=True)


#: Micro-rotations per pipeline stage the pipelined blocks and IK core offer.
ROTATIONS_PER_STAGE = (1, 2, 4)


def add_rotations_per_stage(parser) -> None:
    """``--rotations-per-stage N`` (verilog, sim, synth)."""
    parser.add_argument("--rotations-per-stage", type=int, choices=ROTATIONS_PER_STAGE, default=1, metavar="N",
                        help="pipelined arch: CORDIC micro-rotations (and square-root digits) per pipeline "
                             "stage, 1, 2 or 4: the same steps in fewer, longer stages, so fewer cycles of "
                             "latency and the same bits (module name ..._rotations_per_stageN_...; default: 1)")


def add_max_dsp(parser) -> None:
    """``--max-dsp N`` (verilog, synth)."""
    parser.add_argument("--max-dsp", type=int, default=None, metavar="N",
                        help="pipelined arch with ECP5 DSPs: at most N MULT18X18D; the partial products "
                             "beyond the cap are built in LUTs (shift-and-add, one stage, same latency, "
                             "same bits; narrow ones always are). Default: no cap")


def max_dsp_option(args, arch: str, dsp: str) -> dict:
    """The generator option of ``--max-dsp`` (none when not given); exit 2 when it is asked of a
    design without ECP5 DSPs to count, or is negative."""
    from ik5r.core.errors import InputError

    cap = getattr(args, "max_dsp", None)
    if cap is None:
        return {}
    if cap < 0:
        raise InputError("--max-dsp", f"must be >= 0, got {cap}")
    if arch != Arch.PIPELINED or dsp != Dsp.ECP5:
        raise InputError("--max-dsp", f"applies to the pipelined architecture with --dsp ecp5, not to {arch} with {dsp}")
    return {"max_dsp": cap}


def add_dsp_output_regs(parser) -> None:
    """``--dsp-output-regs N`` (verilog, sim, synth)."""
    parser.add_argument("--dsp-output-regs", type=int, choices=DSP_OUTPUT_REGS, default=0, metavar="N",
                        help="pipelined IK core with ECP5 DSPs: N registers in the fabric after each "
                             "MULT18X18D's own output register (0, 1 or 2), so that a DSP's output has a "
                             "clock of its own to reach the adders: a higher Fmax for N more cycles per "
                             "product on the way, the same bits (module name ..._dsp_output_regsN_...; "
                             "default: 0)")


def dsp_output_regs_option(args, block: str, arch: str, dsp: str) -> dict:
    """The generator option of ``--dsp-output-regs`` (none at 0); exit 2 when it is asked of
    anything but the pipelined IK core with ECP5 DSPs."""
    from ik5r.core.errors import InputError

    regs = getattr(args, "dsp_output_regs", 0)
    if not regs:
        return {}
    if (block, arch, dsp) != (Block.IK, Arch.PIPELINED, Dsp.ECP5):
        raise InputError("--dsp-output-regs", f"applies to the pipelined IK core with --dsp ecp5, "
                                              f"not to {block} {arch} with {dsp}")
    return {"dsp_output_regs": regs}


def add_wide_product(parser) -> None:
    """``--wide-product`` (verilog, sim, synth)."""
    parser.add_argument("--wide-product", action="store_true",
                        help="compact IK core: each product step multiplies a 16-bit limb by 31 bits (two "
                             "DSPs instead of one): fewer clocks per pose, the same bits (module name "
                             "..._wide_product1_...)")


def wide_option(args, block: str, arch: str) -> dict:
    """The generator option of ``--wide-product`` (none when not given); exit 2 when it is asked
    of anything but the compact IK core."""
    from ik5r.core.errors import InputError

    if not getattr(args, "wide_product", False):
        return {}
    if block != Block.IK or arch != CoreArch.COMPACT:
        raise InputError("--wide-product", f"applies to the compact IK core, not to {block} {arch}")
    return {"wide_product": True}


def add_poses(parser) -> None:
    """``--poses`` (verilog, sim, synth)."""
    parser.add_argument("--poses", type=int, choices=(1, 2), default=1,
                        help="compact IK core: poses a program; 2 computes two poses on the shared units "
                             "(more poses a second, a longer latency; the same bits; module name "
                             "..._poses2_...)")


def poses_option(args, block: str, arch: str) -> dict:
    """The generator option of ``--poses`` (none at 1); exit 2 when it is asked of anything but
    the compact IK core."""
    from ik5r.core.errors import InputError

    poses = getattr(args, "poses", 1)
    if poses == 1:
        return {}
    if block != Block.IK or arch != CoreArch.COMPACT:
        raise InputError("--poses", f"applies to the compact IK core, not to {block} {arch}")
    return {"poses": poses}


def rotations_option(args, arch: str) -> dict:
    """The generator option of ``--rotations-per-stage`` for ``arch`` (none at 1); exit 2 when it
    is asked of an architecture that has no pipeline stages to fill."""
    from ik5r.core.errors import InputError

    per_stage = getattr(args, "rotations_per_stage", 1)
    if per_stage == 1:
        return {}
    if arch != Arch.PIPELINED:
        raise InputError("--rotations-per-stage", f"applies to the pipelined architecture, not to {arch}")
    return {"rotations_per_stage": per_stage}
