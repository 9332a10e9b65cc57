"""The fixed-point vocabulary of ik5r (bottom layer): rounding shifts, saturation, constant
multiplies and angle wraps on Python integers.

The firmware model (``ik5r.firmware_model.model``, the specification the C and the HDL are checked
against) is written in these words, and the HDL uses them to size its datapath at construction
time, so neither layer imports the other. ``>>`` on a negative Python int floors, exactly like the
C's arithmetic right shift (docs/algorithm.md, "C semantics").

:mod:`ik5r.core.fixedpoint_np` has the same words over numpy int64 arrays, with a wide (limb) path for
products beyond int64; the IK body (``ik5r.core.ik``) is written once against these names and
runs on either module. Besides the C's helpers the vocabulary has the words a batch needs where the
scalar code would branch (``select``, ``flag``, ``clip``, ``minimum``, ``any_of``) and the *exact*
products (``exact_mul``, ``exact_const``, ``exact_add``, ``exact_sub``, ``exact_less``,
``exact_clip``, ``sum_of_squares``, ``mul_round``, ``dot_round``): plain Python integers here,
int64, uint64 or wide pairs there, as the format ``k`` needs.

Names follow the C: ``_a`` angle Q(frac.angle) radians; ``k`` the constants of the format.
"""

from __future__ import annotations

from .fxconfig import Constants, ConstMul
from .status import SATURATED

__all__ = ["rshift_round", "saturate", "mul_const", "wrap_angle", "opposite", "select", "flag", "clip",
           "minimum", "any_of", "exact_mul", "exact_const", "exact_add", "exact_sub", "exact_less",
           "exact_clip", "sum_of_squares", "mul_round", "dot_round"]


def rshift_round(value: int, shift: int, nearest: bool) -> int:
    """value * 2**-shift, rounded half up (nearest) or floored (truncate)."""
    if shift <= 0:
        return value << -shift
    if nearest:
        value += 1 << (shift - 1)
    return value >> shift


def saturate(value: int, k: Constants) -> tuple[int, int]:
    """Clip to the word range; returns (value, SATURATED or 0)."""
    if value > k.word_max:
        return k.word_max, SATURATED
    if value < k.word_min:
        return k.word_min, SATURATED
    return value, 0


def mul_const(value: int, m: ConstMul, nearest: bool) -> int:
    """value * c for a ConstMul m (pre-shift, 31-bit mantissa, post-shift)."""
    return rshift_round(rshift_round(value, m.pre, nearest) * m.mant, m.post, nearest)


def wrap_angle(angle_a: int, k: Constants) -> int:
    """Bring an angle within one turn of zero back to [-pi, pi] (one correction)."""
    if angle_a > k.pi_a:
        return angle_a - 2 * k.pi_a
    if angle_a < -k.pi_a:
        return angle_a + 2 * k.pi_a
    return angle_a


def opposite(angle_a: int, k: Constants) -> int:
    """The angle of the opposite vector: atan2(-y, -x) from atan2(y, x), with no negation of a word."""
    return angle_a - k.pi_a if angle_a > 0 else angle_a + k.pi_a


# --- the words of a batch: what the scalar code would write as a branch -----------------------


def select(cond: bool, if_true: int, if_false: int) -> int:
    """if_true where cond, else if_false."""
    return if_true if cond else if_false


def flag(cond: bool, bit: int) -> int:
    """The status bit where cond, else 0."""
    return bit if cond else 0


def clip(value: int, low: int, high: int) -> int:
    """value clipped to [low, high]."""
    return max(low, min(high, value))


def minimum(a: int, b: int) -> int:
    return min(a, b)


def any_of(cond: bool) -> bool:
    """Whether cond holds anywhere (a batch skips work no element needs)."""
    return bool(cond)


# --- exact products: Python integers are unbounded, so these are the plain operations ---------


def exact_mul(a: int, b: int, k: Constants) -> int:
    """The exact product of two values of format k."""
    return a * b


def exact_const(value: int, k: Constants) -> int:
    """A constant (e.g. a squared length) as an exact product of format k."""
    return int(value)


def exact_add(x: int, y: int) -> int:
    return x + y


def exact_sub(x: int, y: int) -> int:
    return x - y


def exact_less(x: int, y: int) -> bool:
    return x < y


def exact_clip(value: int, bound: int) -> int:
    """An exact product clipped to [-bound, bound] (bound an exact_const)."""
    return max(-bound, min(bound, value))


def sum_of_squares(x: int, y: int, k: Constants) -> int:
    """x**2 + y**2 of two words of format k: the radicand of a length."""
    return x * x + y * y


def mul_round(a: int, b: int, shift: int, nearest: bool, k: Constants) -> int:
    """rshift_round(a * b, shift) of two values of format k."""
    return rshift_round(a * b, shift, nearest)


def dot_round(a1: int, b1: int, a2: int, b2: int, shift: int, nearest: bool, k: Constants) -> int:
    """rshift_round(a1 * b1 + a2 * b2, shift) of values of format k."""
    return rshift_round(a1 * b1 + a2 * b2, shift, nearest)
