"""``ik5r config``: write a fixed-point config for an arm, by the rules of the shipped configs.

The word width W gives every format as the shipped ``q18``/``q24``/``q32`` have it
(:func:`ik5r.tools.sweep.config_for`): unit vectors Q1.(W-2), angles Q2.(W-3), W CORDIC
iterations; the length format keeps as many integer bits as the arm's largest reachable length
needs, plus one guard bit and the sign (:func:`ik5r.core.armfit.integer_bits_for`: 8 for the arm
of record, as the shipped configs). The file's header names the arm it was made for.
"""

from __future__ import annotations

from pathlib import Path

from ik5r.tools.design import add_arm_argument


def register(subparsers) -> None:
    parser = subparsers.add_parser("config", help="write a fixed-point config TOML for an arm",
                                   description=__doc__)
    add_arm_argument(parser)
    parser.add_argument("--width", type=int, required=True, metavar="W", help="word width (9..32)")
    parser.add_argument("--internal-guard-bits", type=int, default=0, metavar="G",
                        help="extra fraction bits of the IK's internal format (q32w: 6; default: 0)")
    parser.add_argument("--name", default=None, help="config name (default: the output file's stem)")
    parser.add_argument("-o", "--output", required=True, metavar="FILE", help="the config TOML to write")
    parser.set_defaults(run=run)


def header(cfg, arm) -> str:
    """Comment lines: the arm, its largest bound, the length format's range and LSB."""
    from ik5r.core.armfit import needed_magnitude_bits

    bits, quantity, bound = needed_magnitude_bits(arm)
    m = cfg.width - 1 - cfg.frac_length
    return (f"# ik5r fixed-point config \"{cfg.name}\" for the arm \"{arm.name}\" (DH sha256 {arm.dh_sha256()}, "
            f"reach {arm.reach:.6g} cm),\n# written by: ik5r config --arm {arm.name} --width {cfg.width} "
            f"--internal-guard-bits {cfg.internal_guard_bits}\n"
            f"# Lengths: Q{m + 1}.{cfg.frac_length} (|length| < {2 ** m} cm, LSB {2.0 ** -cfg.frac_length:.3g} cm); "
            f"the arm's largest bound: {quantity} = {bound:.6g},\n# {bits} magnitude bits, + 1 guard bit "
            f"+ the sign. Made for this arm: another arm may not fit (ik5r refuses it).\n")


def run(args) -> int:
    from ik5r.core.arm import load_arm
    from ik5r.core.errors import InputError
    from ik5r.core.fxconfig import Constants, parse_config
    from ik5r.tools.sweep import config_for

    arm = load_arm(args.arm)
    if not 9 <= args.width <= 32:
        raise InputError("--width", f"must be in [9, 32], got {args.width}")
    if not 0 <= args.internal_guard_bits <= 8:
        raise InputError("--internal-guard-bits", f"must be in [0, 8], got {args.internal_guard_bits}")
    cfg = config_for(args.width, None, args.internal_guard_bits or None, arm)
    name = args.name or Path(args.output).stem
    doc = cfg.to_toml().replace(f'name = "{cfg.name}"', f'name = "{name}"', 1)
    import tomllib

    cfg = parse_config(tomllib.loads(doc), args.output)
    Constants(cfg, arm)   # the same checks as every fixed-point command (armfit, constants fit)
    Path(args.output).write_text(header(cfg, arm) + doc)
    print(f"{args.output}: config {name} for arm {arm.name}: {cfg.width}-bit words, lengths with "
          f"{cfg.frac_length} fraction bits (|length| < {2 ** (cfg.width - 1 - cfg.frac_length)} cm)")
    return 0
