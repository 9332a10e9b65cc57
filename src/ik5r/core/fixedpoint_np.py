"""The fixed-point vocabulary of :mod:`ik5r.core.fixedpoint` over numpy int64 arrays: the same names,
the same results element by element (bottom layer).

numpy's ``>>`` on int64 is an arithmetic shift, i.e. it floors like Python's; ``&`` works on the
two's complement like Python's infinite one, so bit extraction agrees for any int64.

Python integers are unbounded; int64 is not. For a format ``k`` of at most ``MAX_WIDTH`` bits (the
word configs) every product of two values and every sum the IK forms fits int64 (the bounds are
noted where the vectorised model uses them, ``ik5r.firmware_model.vector``), and the *exact* words
(``exact_mul``, ``sum_of_squares``, ``mul_round``, ``dot_round``, ...) are the plain int64
operations; one sum reaches 2**63 and is formed in uint64 (:func:`sum_of_squares`). A wider format
(an internal one, ``ik.internal_guard_bits`` > 0: values of up to 40 bits) forms its products
exactly as *wide* pairs (hi, lo) of int64 arrays, value = hi * 2**32 + lo with 0 <= lo < 2**32
(limb arithmetic: :func:`wide_mul`, :func:`wide_add`, :func:`wide_sub`, :func:`wide_rshift_round`),
for operands below 2**46 in magnitude. The exact words take ``k`` and choose; the words that take a
product (``rshift_round``, ``mul_const``, ``exact_add``, ...) accept either kind.
"""

from __future__ import annotations

import numpy as np

from .fxconfig import MAX_WIDTH, Constants
from .status import SATURATED

I64 = np.int64
U64 = np.uint64
#: Low limb of a wide pair.
LIMB_BITS = 32
LIMB_MASK = (1 << LIMB_BITS) - 1


def as_array(value) -> np.ndarray:
    """An int64 array (uint64 arrays are kept: they carry radicands up to 2**64 - 1)."""
    value = np.asarray(value)
    if value.dtype == U64:
        return value
    if value.dtype.kind not in "biu" and value.size:
        raise TypeError(f"integer array expected, got {value.dtype}")
    return value.astype(I64, copy=False)


# --- the C's helpers ---------------------------------------------------------------------------


def rshift_round(value, shift, nearest: bool) -> np.ndarray:
    """value * 2**-shift, rounded half up (nearest) or floored (truncate); shift scalar or array.

    The caller guarantees value + 2**(shift - 1) fits its dtype (bounds noted at each call).
    A wide pair goes to :func:`wide_rshift_round` (shift scalar, >= 0).
    """
    if isinstance(value, tuple):
        return wide_rshift_round(value, shift, nearest)
    value = as_array(value)
    if np.ndim(shift) == 0:
        shift = int(shift)
        if shift <= 0:
            return value << -shift
        if nearest:
            value = value + (1 << (shift - 1))
        return value >> shift
    shift = np.asarray(shift, dtype=I64)
    right = np.maximum(shift, 0)
    left = np.maximum(-shift, 0)
    if nearest:
        # 1 << (right - 1) where right > 0, else 0 (a shift by -1 is avoided).
        value = value + ((right > 0).astype(I64) << np.maximum(right - 1, 0))
    return (value >> right) << left


def saturate(value, k: Constants) -> tuple[np.ndarray, np.ndarray]:
    """Clip to the word range; returns (value, SATURATED or 0) per element."""
    value = as_array(value)
    flags = np.where((value > k.word_max) | (value < k.word_min), SATURATED, 0).astype(I64)
    return np.clip(value, k.word_min, k.word_max).astype(I64), flags


def mul_const(value, m, nearest: bool) -> np.ndarray:
    """value * c for a ConstMul m; value an int64 array or a wide pair.

    Mantissas below 2**31 (word configs): the ConstMul keeps rshift(value, pre) below 2**31 in
    magnitude, so the product is below 2**62. Wider mantissas (internal format): the product is
    formed wide (pre-shifted operand and mantissa below 2**46)."""
    operand = rshift_round(value, m.pre, nearest)
    if abs(m.mant) < 1 << 31:
        return rshift_round(operand * m.mant, m.post, nearest)
    return wide_rshift_round(wide_mul(operand, m.mant), m.post, nearest)


def wrap_angle(angle_a, k: Constants) -> np.ndarray:
    """Bring an angle within one turn of zero back to [-pi, pi] (one correction)."""
    angle_a = as_array(angle_a)
    two_pi = 2 * k.pi_a
    return np.where(angle_a > k.pi_a, angle_a - two_pi,
                    np.where(angle_a < -k.pi_a, angle_a + two_pi, angle_a))


def opposite(angle_a, k: Constants) -> np.ndarray:
    """The angle of the opposite vector: atan2(-y, -x) from atan2(y, x)."""
    angle_a = as_array(angle_a)
    return np.where(angle_a > 0, angle_a - k.pi_a, angle_a + k.pi_a)


# --- the words of a batch ----------------------------------------------------------------------


def select(cond, if_true, if_false) -> np.ndarray:
    """if_true where cond, else if_false."""
    return np.where(cond, if_true, if_false)


def flag(cond, bit: int) -> np.ndarray:
    """The status bit where cond, else 0."""
    return np.where(cond, bit, 0)


def clip(value, low, high) -> np.ndarray:
    return np.clip(value, low, high)


def minimum(a, b) -> np.ndarray:
    return np.minimum(a, b)


def any_of(cond) -> bool:
    """Whether cond holds anywhere (the batch skips work no element needs)."""
    return bool(np.any(cond))


# --- bit length ----------------------------------------------------------------------------------


def bit_length(value) -> np.ndarray:
    """Exact ``int.bit_length`` of non-negative int64 (or any uint64) values.

    Below 2**53 (the CORDIC's case: at most 2**32) the conversion to float64 is exact, and so is
    frexp's exponent, which is then the bit length (frexp(0) = (0, 0)). Larger values go through an
    exact binary search on the integers.
    """
    v = as_array(value)
    if v.size == 0 or v.max() < (1 << 53):
        return np.frexp(v.astype(np.float64))[1].astype(I64)
    return bit_length_search(v)


def bit_length_search(value) -> np.ndarray:
    """Exact bit length by binary search with shifts and comparisons (any uint64)."""
    v = as_array(value).astype(U64)
    n = np.zeros(v.shape, dtype=I64)
    for s in (32, 16, 8, 4, 2, 1):
        big = v >= U64(1 << s)
        v = np.where(big, v >> U64(s), v)
        n += big * s
    return n + (v != 0)


# --- wide (limb) arithmetic: exact products and sums beyond int64 --------------------------------


def wide_products(k: Constants) -> bool:
    """Whether products of two values of k's format exceed int64 (only a format wider than the
    widest word config, i.e. an internal format, has them)."""
    return k.cfg.width > MAX_WIDTH


def wide_from(value):
    """An int64 array, or a Python int below 2**94 in magnitude (a constant), as a wide pair."""
    if isinstance(value, int):
        value = int(value)
        return np.int64(value >> LIMB_BITS), np.int64(value & LIMB_MASK)
    value = as_array(value)
    return value >> LIMB_BITS, value & LIMB_MASK


def wide_mul(a, b):
    """The exact product a * b as a wide pair, |a|, |b| < 2**46 (int64 arrays or ints).

    a = ah 2**32 + al, b = bh 2**32 + bl with 0 <= al, bl < 2**32 and |ah|, |bh| < 2**14:
    al * bl < 2**64 is formed in uint64; the other partial products and their sum stay below 2**61.
    """
    a, b = as_array(a), as_array(b)
    ah, al = a >> LIMB_BITS, a & LIMB_MASK
    bh, bl = b >> LIMB_BITS, b & LIMB_MASK
    low = al.view(U64) * bl.view(U64)
    hi = ((ah * bh) << LIMB_BITS) + ah * bl + al * bh + (low >> U64(LIMB_BITS)).view(I64)
    return hi, (low & U64(LIMB_MASK)).view(I64)


def wide_add(x, y):
    """x + y of two wide pairs."""
    lo = x[1] + y[1]
    return x[0] + y[0] + (lo >> LIMB_BITS), lo & LIMB_MASK


def wide_sub(x, y):
    """x - y of two wide pairs (the borrow is the floor of the low difference)."""
    lo = x[1] - y[1]
    return x[0] - y[0] + (lo >> LIMB_BITS), lo & LIMB_MASK


def wide_less(x, y) -> np.ndarray:
    """x < y of two wide pairs (lo normalised to [0, 2**32): lexicographic)."""
    return (x[0] < y[0]) | ((x[0] == y[0]) & (x[1] < y[1]))


def wide_rshift_round(x, shift: int, nearest: bool) -> np.ndarray:
    """rshift_round of a wide pair by a scalar shift >= 0, whose result fits int64."""
    hi, lo = x
    if nearest and shift > 0:
        bias = shift - 1
        if bias >= LIMB_BITS:
            hi = hi + (1 << (bias - LIMB_BITS))
        else:
            lo = lo + (1 << bias)
            hi, lo = hi + (lo >> LIMB_BITS), lo & LIMB_MASK
    if shift >= LIMB_BITS:
        return hi >> (shift - LIMB_BITS)
    return (hi << (LIMB_BITS - shift)) + (lo >> shift)


# --- exact products: int64 for the word formats, wide pairs beyond -----------------------------


def exact_mul(a, b, k: Constants):
    """The exact product of two values of format k: int64 (word formats) or a wide pair."""
    if wide_products(k):
        return wide_mul(a, b)
    return as_array(a) * b


def exact_const(value: int, k: Constants):
    """A constant (e.g. a squared length) as an exact product of format k."""
    return wide_from(int(value)) if wide_products(k) else int(value)


def exact_add(x, y):
    return wide_add(x, y) if isinstance(x, tuple) else x + y


def exact_sub(x, y):
    return wide_sub(x, y) if isinstance(x, tuple) else x - y


def exact_less(x, y) -> np.ndarray:
    return wide_less(x, y) if isinstance(x, tuple) else x < y


def exact_clip(value, bound):
    """An exact product clipped to [-bound, bound] (bound an exact_const)."""
    if not isinstance(value, tuple):
        return np.clip(value, -bound, bound)
    minus_bound = wide_sub(wide_from(0), bound)
    above, below = wide_less(bound, value), wide_less(value, minus_bound)
    return tuple(np.where(above, b, np.where(below, m, v)) for b, m, v in zip(bound, minus_bound, value))


def sum_of_squares(x, y, k: Constants):
    """x**2 + y**2 of two words of format k: the radicand of a length.

    Word formats: x*x, y*y <= 2**62 each (|word| <= 2**31); the sum reaches 2**63 for
    x = y = word_min, one past int64: summed in uint64 (< 2**64). Wider: a wide pair.
    """
    if wide_products(k):
        return wide_add(wide_mul(x, x), wide_mul(y, y))
    return (x * x).view(U64) + (y * y).view(U64)


def mul_round(a, b, shift: int, nearest: bool, k: Constants) -> np.ndarray:
    """rshift_round(a * b, shift): in int64 (the caller's bound) or, wide, exactly."""
    if wide_products(k):
        return wide_rshift_round(wide_mul(a, b), shift, nearest)
    return rshift_round(as_array(a) * b, shift, nearest)


def dot_round(a1, b1, a2, b2, shift: int, nearest: bool, k: Constants) -> np.ndarray:
    """rshift_round(a1 * b1 + a2 * b2, shift): in int64 (the caller's bound) or, wide, exactly."""
    if wide_products(k):
        return wide_rshift_round(wide_add(wide_mul(a1, b1), wide_mul(a2, b2)), shift, nearest)
    return rshift_round(as_array(a1) * b1 + as_array(a2) * b2, shift, nearest)
