"""The fixed-point vocabulary of ik5r (bottom layer): rounding shifts, saturation, constant
multiplies and angle wraps on Python integers.

The firmware model (``ik5r.firmware.model``, the specification the C and the HDL are checked
against) is written in these words, and the HDL uses them to size its datapath at construction
time, so neither layer imports the other. ``>>`` on a negative Python int floors, exactly like the
C's arithmetic right shift (docs/algorithm.md, "C semantics"). The numpy counterparts, with a
wide (limb) path for the internal format, are in ``ik5r.firmware.vector``.

Names follow the C: ``_a`` angle Q(frac.angle) radians; ``k`` the constants of the format.
"""

from __future__ import annotations

from .fxconfig import ConstMul, Constants
from .status import SATURATED

__all__ = ["rshift_round", "saturate", "mul_const", "wrap_angle", "opposite"]


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
