"""Generate ``ik5r_config.h``, the C solver's view of a fixed-point config and an arm.

The config TOML and the arm TOML are the single source of truth: every width, fraction-bit count,
iteration count, the rounding mode and every derived integer constant of
:class:`ik5r.core.fxconfig.Constants` (plus the status bits of :mod:`ik5r.core.status`) reach ``ik5r.c``
only through this header, so nothing is typed twice in C.

Constants are emitted generically from ``vars(k)`` (in their definition order): an ``int`` becomes
``#define IK5R_<NAME> INT64_C(...)``, a :class:`ik5r.core.fxconfig.ConstMul` becomes
``IK5R_<NAME>_PRE/_MANT/_POST`` and a tuple becomes a ``static const int64_t ik5r_<name>[]`` table
(compiled only where ``IK5R_DEFINE_TABLES`` is defined, i.e. in ``ik5r.c``, so that other
translation units including ``ik5r.h`` get no unused-variable warnings). A constant added to
``Constants`` later appears here with no change to this file. The constants of the internal format
the IK runs on (``k.internal``, equal to the word constants when ``ik.internal_guard_bits`` is 0)
follow with the prefix ``IK5R_IK_`` (tables ``ik5r_ik_<name>``), its config fields too.

Before emitting, :func:`check_bounds` verifies the static bounds the C relies on for this config
(the operands of every 128-bit product, the beta atan2 arguments and the joint offsets fit their
words): the C then has no undefined behaviour for any word input.

Usage: ``python -m ik5r.firmware_model.codegen [--config q32] [--arm ARM.toml] [-o ik5r_config.h]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ik5r.core import status as st
from ik5r.core.fxconfig import MAX_WIDTH, Constants, ConstMul, WideInt, constants, load_config

HEADER_NAME = "ik5r_config.h"
INT64_MAX = (1 << 63) - 1
INT64_MIN = -(1 << 63)

#: FixedConfig fields emitted as plain ints (rounding is emitted as IK5R_ROUND_NEAREST 0/1).
_CFG_FIELDS = ("width", "frac_length", "frac_unit", "frac_angle", "iterations", "guard_bits",
               "angle_guard_bits", "internal_guard_bits")
#: Widest internal word the C's CORDIC state and 64x64 -> 128-bit products are written for.
MAX_INTERNAL_WIDTH = 40


def _c_int(value: int) -> str:
    """An int64_t constant expression for ``value`` (INT64_MIN cannot be a literal)."""
    value = int(value)
    if not INT64_MIN <= value <= INT64_MAX:
        raise ValueError(f"constant {value} does not fit int64")
    if value == INT64_MIN:
        return "(-INT64_C(9223372036854775807) - 1)"
    return f"INT64_C({value})"


def _rshift_round(value: int, shift: int, nearest: bool) -> int:
    if shift <= 0:
        return value << -shift
    return (value + (1 << (shift - 1) if nearest else 0)) >> shift


def _mul_const(value: int, m: ConstMul, nearest: bool) -> int:
    return _rshift_round(_rshift_round(value, m.pre, nearest) * m.mant, m.post, nearest)


def _check_const_mul(name: str, m: ConstMul, x_max: int, nearest: bool) -> None:
    """|x| <= x_max (x a 128-bit value): the pre-shifted operand and the mantissa are int64_t, the
    product plus its rounding term fits 128 bits and the result int64_t (ik5r.c's mul_const)."""
    if not (0 <= m.pre <= 126 and 0 <= m.post <= 126 and abs(m.mant) <= INT64_MAX):
        raise ValueError(f"{name}: shifts/mantissa out of the C's range: {m}")
    if x_max >= 1 << 127:
        raise ValueError(f"{name}: operand bound {x_max} does not fit 128 bits")
    operand = (abs(x_max) >> m.pre) + 1
    product = operand * abs(m.mant) + (1 << m.post)
    if operand > INT64_MAX or product >= 1 << 127 or product >> m.post > INT64_MAX:
        raise ValueError(f"{name}: |x| <= {x_max} times {m} can overflow the C's int64_t/128-bit words")


def check_bounds(k: Constants) -> None:
    """Static bounds of ``ik5r.c`` for this config and arm; ValueError names the one violated.

    The building blocks work on the config's words (int32_t), the IK on the internal format's
    words (int64_t, at most MAX_INTERNAL_WIDTH bits: CORDIC state and angle accumulator stay below
    2**50); every product of two values is formed in 128 bits.
    """
    c, ki = k.cfg, k.internal
    ci = ki.cfg
    if not 8 <= c.width <= MAX_WIDTH:
        raise ValueError(f"width {c.width} outside [8, {MAX_WIDTH}]")
    if not ci.width <= MAX_INTERNAL_WIDTH or ci.iterations > 48:
        raise ValueError(f"internal width {ci.width} / iterations {ci.iterations} beyond "
                         f"{MAX_INTERNAL_WIDTH} / 48")
    if c.width + c.frac_unit + 2 > 64 or 2 * c.frac_unit + 4 > 64:
        raise ValueError("unit format too wide for the word square roots (64-bit radicands)")
    nearest = c.round_nearest
    _check_const_mul("c3_from_l2", ki.c3_from_l2, ki.twice_a2a3_l2, nearest)
    _check_const_mul("c3_complement_from_l2", ki.c3_complement_from_l2, 2 * ki.twice_a2a3_l2, nearest)
    _check_const_mul("a3_from_u", ki.a3_from_u, 2 * ki.one_u, nearest)
    # beta = atan2(a3 s3, a2 + a3 c3) with 0 <= s3 <= 2 one_u, |c3| <= one_u: arguments are words.
    for c3 in (-ki.one_u, ki.one_u):
        x = ki.a2_l + _mul_const(c3, ki.a3_from_u, nearest)
        if not ki.word_min <= x <= ki.word_max:
            raise ValueError(f"a2 + a3 cos q3 = {x} does not fit a {ci.width}-bit word")
    if _mul_const(2 * ki.one_u, ki.a3_from_u, nearest) > ki.word_max:
        raise ValueError(f"2 a3 does not fit a {ci.width}-bit word")
    # Joint outputs wrap(q - offset) with |q| <= pi + eps stay words when |offset| <= pi.
    for i, off in enumerate(ki.offset_a):
        if abs(off) > ki.pi_a:
            raise ValueError(f"theta_offset of joint {i + 1} is beyond +-pi: {off}")
    if not 1 <= ki.links_sq_l2 < 1 << 100 or not 0 <= ki.twice_a2a3_l2 < 1 << 100:
        raise ValueError("squared link lengths out of [1, 2**100)")


def _emit_constants(k: Constants, prefix: str, out: list[str], tables: list) -> None:
    """``#define IK5R_<prefix><NAME>`` lines for every derived constant of ``k``."""
    for name, value in vars(k).items():
        if name in ("cfg", "arm", "internal"):
            continue
        macro = f"IK5R_{prefix}{name.upper()}"
        if isinstance(value, bool):
            raise TypeError(f"unexpected bool constant {name}")
        if isinstance(value, WideInt):
            two_complement = int(value) % (1 << 128)
            out.append(f"#define {macro}_HI UINT64_C({two_complement >> 64})")
            out.append(f"#define {macro}_LO UINT64_C({two_complement & ((1 << 64) - 1)})")
        elif isinstance(value, int):
            out.append(f"#define {macro} {_c_int(value)}")
        elif isinstance(value, ConstMul):
            out.append(f"#define {macro}_PRE {int(value.pre)}")
            out.append(f"#define {macro}_MANT {_c_int(value.mant)}")
            out.append(f"#define {macro}_POST {int(value.post)}")
        elif isinstance(value, tuple) and all(isinstance(v, int) for v in value):
            out.append(f"#define {macro}_LEN {len(value)}")
            tables.append((f"ik5r_{prefix.lower()}{name}", macro, value))
        else:
            raise TypeError(f"cannot emit constant {name} of type {type(value).__name__}")


def generate_header(k: Constants) -> str:
    """The text of ``ik5r_config.h`` for ``k``: deterministic (no paths, no time stamps)."""
    check_bounds(k)
    c, arm = k.cfg, k.arm
    source = Path(str(c.source)).name
    out = [
        f"/* {HEADER_NAME} -- GENERATED by ik5r.firmware_model.codegen from the fixed-point config",
        f" * \"{c.name}\" ({source}) and the arm \"{arm.name}\". DO NOT EDIT: change the TOML and",
        " * regenerate (python -m ik5r.firmware_model.codegen). The config and the arm are the single",
        " * source of truth of every number below. */",
        "#ifndef IK5R_CONFIG_H",
        "#define IK5R_CONFIG_H",
        "",
        "#include <stdint.h>",
        "",
        f'#define IK5R_CONFIG_NAME "{c.name}"',
        f'#define IK5R_ARM_NAME "{arm.name}"',
        f'#define IK5R_ARM_SHA256 "{arm.dh_sha256()}"  /* DH numbers and limits, as in the Verilog header */',
        "",
        "/* Fixed-point configuration. */",
    ]
    for name in _CFG_FIELDS:
        out.append(f"#define IK5R_{name.upper()} {int(getattr(c, name))}")
    out.append(f"#define IK5R_ROUND_NEAREST {1 if c.round_nearest else 0}")
    out.append("")
    out.append("/* Derived integer constants (ik5r.core.fxconfig.Constants); suffix = Q format. */")
    tables: list = []
    _emit_constants(k, "", out, tables)
    out.append("")
    out.append("/* IK5R_IK_*: the internal format the IK runs on (k.internal; the word format when")
    out.append(" * IK5R_INTERNAL_GUARD_BITS is 0), its config fields and derived constants. */")
    for name in _CFG_FIELDS[:-1]:
        out.append(f"#define IK5R_IK_{name.upper()} {int(getattr(k.internal.cfg, name))}")
    _emit_constants(k.internal, "IK_", out, tables)
    out.append("")
    out.append("/* 0 when every joint counts the DH way and every limit is a full turn: the output loop's")
    out.append(" * sense and limit tests then fold away (the arms of record cost nothing for them). */")
    out.append(f"#define IK5R_HAS_REVERSED {1 if any(s < 0 for s in k.sense) else 0}")
    out.append(f"#define IK5R_HAS_LIMITS {1 if k.limited else 0}")
    out.append("")
    out.append("/* Status bits (ik5r.core.status), one set per pose. */")
    out.append(f"#define IK5R_STATUS_OK {st.OK}u")
    for bit, name in st.NAMES.items():
        out.append(f"#define IK5R_STATUS_{name.upper()} 0x{bit:02x}u")
    out.append("")
    out.append("/* Tables: defined only in the translation unit that uses them (ik5r.c). */")
    out.append("#ifdef IK5R_DEFINE_TABLES")
    for name, macro, values in tables:
        out.append(f"static const int64_t {name}[{macro}_LEN] = {{")
        for start in range(0, len(values), 4):
            chunk = ", ".join(_c_int(v) for v in values[start:start + 4])
            sep = "," if start + 4 < len(values) else ""
            out.append(f"    {chunk}{sep}")
        out.append("};")
    out.append("#endif /* IK5R_DEFINE_TABLES */")
    out.append("")
    out.append("#endif /* IK5R_CONFIG_H */")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ik5r.firmware_model.codegen", description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=None, help="config TOML or shipped name (default q32w)")
    parser.add_argument("--arm", default=None, help="arm TOML (default: the arm of record)")
    parser.add_argument("-o", "--output", default="-", help=f"output file (default stdout), e.g. {HEADER_NAME}")
    args = parser.parse_args(argv)
    from ik5r.core.arm import load_arm

    text = generate_header(constants(load_config(args.config), load_arm(args.arm) if args.arm else None))
    if args.output == "-":
        sys.stdout.write(text)
    else:
        Path(args.output).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
