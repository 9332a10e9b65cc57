"""Bit-accurate numpy-vectorised model of the C solver: the same outputs as ``model.py``, bit for bit.

Every function mirrors the scalar function of the same name in :mod:`ik5r.firmware.model` (the
specification) over int64 numpy arrays, one element per call of the scalar function. Where the
scalar model relies on Python's unbounded integers, the bound of every product and sum is noted
(for the widest config, width = 32, frac.unit = 30, 32 CORDIC iterations and 4 guard bits; the
narrower configs have smaller values) and the two places that can reach 2**63 are computed in
uint64 or reordered.

numpy's ``>>`` on int64 is an arithmetic shift, i.e. it floors like Python's; ``&`` works on the
two's complement like Python's infinite one, so bit extraction agrees for any int64.

Inputs must be words (signed ``width``-bit integers): that is the C solver's interface (int32_t
words) and what the bounds below assume; :func:`solve_batch` checks it and raises ``ValueError``.

The IK runs on the internal format ``k.internal`` (see ``model.py``). When that is wider than a
word (``ik.internal_guard_bits`` > 0: words of up to 40 bits), products of two values exceed int64:
they are formed exactly as *wide* pairs (hi, lo) of int64 arrays, value = hi * 2**32 + lo with
0 <= lo < 2**32 (limb arithmetic: :func:`wide_mul`, :func:`wide_add`, :func:`wide_sub`,
:func:`wide_rshift_round`), for operands below 2**46 in magnitude. The word configs keep the plain
int64 arithmetic (faster), whose bounds are noted below.
"""

from __future__ import annotations

import numpy as np

from ik5r.fxconfig import MAX_WIDTH, Constants
from ik5r.status import BAD_ORIENTATION, INVALID, SATURATED, SINGULAR_BASE, SINGULAR_ELBOW, UNREACHABLE

I64 = np.int64
U64 = np.uint64
#: Poses per chunk of :func:`solve_batch`: the working set (~30 int64 arrays) stays in L2/L3.
CHUNK = 32768
#: Low limb of a wide pair.
LIMB_BITS = 32
LIMB_MASK = (1 << LIMB_BITS) - 1


def _arr(value) -> np.ndarray:
    """An int64 array (uint64 arrays are kept: they carry radicands up to 2**64 - 1)."""
    value = np.asarray(value)
    if value.dtype == U64:
        return value
    if value.dtype.kind not in "biu" and value.size:
        raise TypeError(f"integer array expected, got {value.dtype}")
    return value.astype(I64, copy=False)


# --------------------------------------------------------------------------------------------
# Helpers


def rshift_round(value, shift, nearest: bool) -> np.ndarray:
    """value * 2**-shift, rounded half up (nearest) or floored (truncate); shift scalar or array.

    The caller guarantees value + 2**(shift - 1) fits its dtype (bounds noted at each call).
    A wide pair goes to :func:`wide_rshift_round` (shift scalar, >= 0).
    """
    if isinstance(value, tuple):
        return wide_rshift_round(value, shift, nearest)
    value = _arr(value)
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
    value = _arr(value)
    flags = np.where((value > k.word_max) | (value < k.word_min), SATURATED, 0).astype(I64)
    return np.clip(value, k.word_min, k.word_max).astype(I64), flags


def mul_const(value, m, nearest: bool) -> np.ndarray:
    """value * c for a ConstMul m; value an int64 array or a wide pair.

    Mantissas below 2**31 (word configs): the caller keeps rshift(value, pre) below 2**31 in
    magnitude, so the product is below 2**62. Wider mantissas (internal format): the product is
    formed wide (pre-shifted operand and mantissa below 2**46)."""
    operand = rshift_round(value, m.pre, nearest)
    if abs(m.mant) < 1 << 31:
        return rshift_round(operand * m.mant, m.post, nearest)
    return wide_rshift_round(wide_mul(operand, m.mant), m.post, nearest)


def wrap_angle(angle_a, k: Constants) -> np.ndarray:
    """Bring an angle within one turn of zero back to [-pi, pi] (one correction)."""
    angle_a = _arr(angle_a)
    two_pi = 2 * k.pi_a
    return np.where(angle_a > k.pi_a, angle_a - two_pi,
                    np.where(angle_a < -k.pi_a, angle_a + two_pi, angle_a))


def opposite(angle_a, k: Constants) -> np.ndarray:
    """The angle of the opposite vector: atan2(-y, -x) from atan2(y, x)."""
    angle_a = _arr(angle_a)
    return np.where(angle_a > 0, angle_a - k.pi_a, angle_a + k.pi_a)


def bit_length(value) -> np.ndarray:
    """Exact ``int.bit_length`` of non-negative int64 (or any uint64) values.

    Below 2**53 (the CORDIC's case: at most 2**32) the conversion to float64 is exact, and so is
    frexp's exponent, which is then the bit length (frexp(0) = (0, 0)). Larger values go through an
    exact binary search on the integers.
    """
    v = _arr(value)
    if v.size == 0 or v.max() < (1 << 53):
        return np.frexp(v.astype(np.float64))[1].astype(I64)
    return _bit_length_search(v)


def _bit_length_search(value) -> np.ndarray:
    """Exact bit length by binary search with shifts and comparisons (any uint64)."""
    v = _arr(value).astype(U64)
    n = np.zeros(v.shape, dtype=I64)
    for s in (32, 16, 8, 4, 2, 1):
        big = v >= U64(1 << s)
        v = np.where(big, v >> U64(s), v)
        n += big * s
    return n + (v != 0)


def _bit_length_ones_abs(x, y) -> np.ndarray:
    """Bit length of x | ones'-complement-abs(y), x >= 0."""
    y = _arr(y)
    return bit_length(_arr(x) | np.where(y < 0, ~y, y))


# --------------------------------------------------------------------------------------------
# Wide (limb) arithmetic: exact products and sums beyond int64


def wide_products(k: Constants) -> bool:
    """Whether products of two values of k's format exceed int64 (only a format wider than the
    widest word config, i.e. an internal format, has them)."""
    return k.cfg.width > MAX_WIDTH


def wide_from(value):
    """An int64 array, or a Python int below 2**94 in magnitude (a constant), as a wide pair."""
    if isinstance(value, int):
        return np.int64(value >> LIMB_BITS), np.int64(value & LIMB_MASK)
    value = _arr(value)
    return value >> LIMB_BITS, value & LIMB_MASK


def wide_mul(a, b):
    """The exact product a * b as a wide pair, |a|, |b| < 2**46 (int64 arrays or ints).

    a = ah 2**32 + al, b = bh 2**32 + bl with 0 <= al, bl < 2**32 and |ah|, |bh| < 2**14:
    al * bl < 2**64 is formed in uint64; the other partial products and their sum stay below 2**61.
    """
    a, b = _arr(a), _arr(b)
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


def _mul_round(a, b, shift: int, nearest: bool, wide: bool) -> np.ndarray:
    """rshift_round(a * b, shift): in int64 (the caller's bound) or, when ``wide``, exactly."""
    if wide:
        return wide_rshift_round(wide_mul(a, b), shift, nearest)
    return rshift_round(_arr(a) * b, shift, nearest)


def _dot_round(a1, b1, a2, b2, shift: int, nearest: bool, wide: bool) -> np.ndarray:
    """rshift_round(a1 * b1 + a2 * b2, shift): in int64 (the caller's bound) or exactly."""
    if wide:
        return wide_rshift_round(wide_add(wide_mul(a1, b1), wide_mul(a2, b2)), shift, nearest)
    return rshift_round(_arr(a1) * b1 + _arr(a2) * b2, shift, nearest)


# --------------------------------------------------------------------------------------------
# CORDIC


def _atan2_core(y, x, k: Constants):
    """Vectoring CORDIC shared by :func:`cordic_atan2` and the solver.

    Returns (angle_a, xs after the iterations, norm, zero).
    Bounds (width 32): after the coarse rotation xs in [0, 2**31], |ys| <= 2**31; after the
    normalisation |xs|, |ys| < 2**31 still (or unchanged when norm = 0), so the vector's length is
    <= 2**31.5 and, with the guard bits and the CORDIC gain K < 1.65, |xs|, |ys| < 2**36.3 through
    the iterations; |z| <= half_pi_z + sum(atan_table) < 2**34.
    """
    c = k.cfg
    y = _arr(y)
    x = _arr(x)
    zero = (x == 0) & (y == 0)
    neg_x = x < 0
    y_neg = y < 0
    # Coarse rotation by -+90 degrees into the right half-plane (widens by one bit).
    xs = np.where(neg_x, np.where(y_neg, -y, y), x)
    ys = np.where(neg_x, np.where(y_neg, x, -x), y)
    z = np.where(neg_x, np.where(y_neg, -k.half_pi_z, k.half_pi_z), 0).astype(I64)
    norm = np.maximum(0, c.width - 1 - _bit_length_ones_abs(xs, ys))
    shift = norm + c.guard_bits
    xs = xs << shift
    ys = ys << shift
    tx = np.empty_like(xs)
    ty = np.empty_like(xs)
    d = np.empty_like(xs)
    for i, step_z in enumerate(k.atan_table):
        # d = +1 where ys >= 0 (rotate clockwise), -1 where ys < 0.
        np.right_shift(ys, 63, out=d)
        np.bitwise_or(d, 1, out=d)
        np.right_shift(ys, i, out=tx)
        np.right_shift(xs, i, out=ty)
        tx *= d
        ty *= d
        xs += tx
        ys -= ty
        d *= step_z
        z += d
    angle_a = rshift_round(z, c.angle_guard_bits, c.round_nearest)
    angle_a = np.where(zero, 0, angle_a)
    return angle_a, xs, norm, zero


def cordic_atan2(y, x, k: Constants) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Full-circle atan2 of two words by CORDIC vectoring.

    Returns (angle_a, magnitude (saturated word), zero) with zero where x == y == 0 (angle and
    magnitude 0 there).
    """
    c = k.cfg
    angle_a, xs, norm, zero = _atan2_core(y, x, k)
    # Words: (xs >> guard) <= 2**32.3 (length <= 2**31.5 times K); times inv_gain < 2**30.3:
    # < 2**62.5 (exactly sqrt(2) * 2**62 at most, less the CORDIC's shrinkage); the rounding bias
    # 2**(30 + norm) is <= 2**60 and only large when norm is, so the sum stays < 2**62.7.
    shift = k.inv_gain_frac + norm
    if wide_products(k):
        # Per-element shifts: one wide product, rounded per distinct norm.
        product = wide_mul(xs >> c.guard_bits, k.inv_gain)
        magnitude = np.zeros_like(xs)
        for value in np.unique(shift):
            rows = shift == value
            magnitude[rows] = wide_rshift_round((product[0][rows], product[1][rows]), int(value),
                                                c.round_nearest)
    else:
        magnitude = rshift_round((xs >> c.guard_bits) * k.inv_gain, shift, c.round_nearest)
    magnitude, _ = saturate(magnitude, k)
    return angle_a, np.where(zero, 0, magnitude), zero


def cordic_rotate(x, y, angle_a, k: Constants) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotate the vector (x, y) of words by angle_a. Returns (x', y', SATURATED or 0).

    Bounds: |x|, |y| <= 2**31 after the quadrant swap; x * inv_gain < 2**61.3; the compensated
    |xs|, |ys| < 2**(31.5 + guard) / K and after the iterations < 2**35.5; |z| < 2**35 for any word
    angle (angle_a << angle_guard_bits).
    """
    c = k.cfg
    nearest = c.round_nearest
    angle_a = _arr(angle_a)
    x, y, _ = np.broadcast_arrays(_arr(x), _arr(y), angle_a)
    z = angle_a << c.angle_guard_bits
    hi = z > k.half_pi_z
    lo = z < -k.half_pi_z
    x, y = np.where(hi, -y, np.where(lo, y, x)), np.where(hi, x, np.where(lo, -x, y))
    z = np.where(hi, z - k.half_pi_z, np.where(lo, z + k.half_pi_z, z))
    shift = k.inv_gain_frac - c.guard_bits
    xs = _mul_round(x, k.inv_gain, shift, nearest, wide_products(k))
    ys = _mul_round(y, k.inv_gain, shift, nearest, wide_products(k))
    tx = np.empty_like(xs)
    ty = np.empty_like(xs)
    d = np.empty_like(xs)
    for i, step_z in enumerate(k.atan_table):
        # d = +1 where z >= 0 (rotate counter-clockwise), -1 where z < 0.
        np.right_shift(z, 63, out=d)
        np.bitwise_or(d, 1, out=d)
        np.right_shift(ys, i, out=tx)
        np.right_shift(xs, i, out=ty)
        tx *= d
        ty *= d
        xs -= tx
        ys += ty
        d *= step_z
        z -= d
    xo, sat_x = saturate(rshift_round(xs, c.guard_bits, nearest), k)
    yo, sat_y = saturate(rshift_round(ys, c.guard_bits, nearest), k)
    return xo, yo, sat_x | sat_y


# --------------------------------------------------------------------------------------------
# Square roots


def isqrt(radicand, bits: int, nearest: bool) -> np.ndarray:
    """Square root by the digit recurrence, element-wise over int64 or uint64 radicands.

    Like the scalar model, only the low ``bits`` bits (bits <= 64) of the two's-complement
    radicand are read, so int64 values (negative ones too) and uint64 values up to 2**64 - 1 give
    the scalar model's result. root < 2**32 and rem <= 2 * root, so rem << 2 | 3 < 2**35.
    A wide pair (non-negative, below 2**84) is read likewise.
    """
    if isinstance(radicand, tuple):
        return _isqrt_wide(radicand, bits, nearest)
    if not 0 < bits <= 64 or bits % 2:
        raise ValueError(f"bits must be even and in [2, 64], got {bits}")
    rad = _arr(radicand)
    rad = rad.view(U64) if rad.dtype == I64 else rad
    return _digit_recurrence(lambda i: ((rad >> U64(2 * i)) & U64(3)).view(I64), rad.shape, bits, nearest)


def _isqrt_wide(radicand, bits: int, nearest: bool) -> np.ndarray:
    """isqrt of a non-negative wide pair below 2**bits (bits <= 84: root < 2**42, rem < 2**45)."""
    if not 0 < bits <= 84 or bits % 2:
        raise ValueError(f"bits must be even and in [2, 84], got {bits}")
    hi, lo = radicand

    def digit(i):
        return (lo >> (2 * i)) & 3 if 2 * i < LIMB_BITS else (hi >> (2 * i - LIMB_BITS)) & 3
    return _digit_recurrence(digit, hi.shape, bits, nearest)


def _digit_recurrence(digit, shape, bits: int, nearest: bool) -> np.ndarray:
    """The root of the digit recurrence, digit(i) = bits 2i, 2i + 1 of the radicand (int64)."""
    root = np.zeros(shape, dtype=I64)
    rem = np.zeros(shape, dtype=I64)
    trial = np.empty_like(root)
    ge = np.empty(shape, dtype=bool)
    for i in range(bits // 2 - 1, -1, -1):
        rem <<= 2
        rem |= digit(i)
        np.left_shift(root, 2, out=trial)
        trial |= 1
        root <<= 1
        np.greater_equal(rem, trial, out=ge)
        rem -= trial * ge
        root |= ge
    if nearest:
        root += rem > root
    return root


def sqrt_word(x, frac: int, k: Constants) -> np.ndarray:
    """Square root of a non-negative word with ``frac`` fraction bits, same format.

    x << frac < 2**(width - 1 + frac) <= 2**61; bits <= 64 as the scalar model.
    """
    c = k.cfg
    bits = c.width + frac + ((c.width + frac) & 1)
    return isqrt(_arr(x) << frac, bits, c.round_nearest)


def acos_of_complements(one_minus_u, one_plus_u, k: Constants) -> tuple[np.ndarray, np.ndarray]:
    """acos(x) as atan2(sqrt((1 - x)(1 + x)), x) from 1 - x and 1 + x (each in [0, 2]).

    Returns (angle_a, sine_u). Words: the product is at most 2**(2 * frac_unit + 2) <= 2**62.
    """
    c = k.cfg
    one_minus_u, one_plus_u = _arr(one_minus_u), _arr(one_plus_u)
    product_u2 = wide_mul(one_minus_u, one_plus_u) if wide_products(k) else one_minus_u * one_plus_u
    sine_u = isqrt(product_u2, 2 * c.frac_unit + 4, c.round_nearest)
    angle_a = _atan2_core(sine_u, k.one_u - one_minus_u, k)[0]
    return angle_a, sine_u


def cordic_acos(x_u, k: Constants) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """acos of a unit-format word as atan2(sqrt((1 - x)(1 + x)), x).

    Returns (angle_a, sine_u, SATURATED or 0 where the input was outside [-1, 1]).
    """
    x_u = _arr(x_u)
    flags = np.where((x_u > k.one_u) | (x_u < -k.one_u), SATURATED, 0).astype(I64)
    x_u = np.clip(x_u, -k.one_u, k.one_u)
    angle_a, sine_u = acos_of_complements(k.one_u - x_u, k.one_u + x_u, k)
    return angle_a, sine_u, flags


# --------------------------------------------------------------------------------------------
# The solver


def _check_words(name: str, value: np.ndarray, k: Constants) -> None:
    if value.size and (value.min() < k.word_min or value.max() > k.word_max):
        raise ValueError(f"{name}: values outside the {k.cfg.width}-bit word range")


def _solve_chunk(k: Constants, p_l, a_u, n_u, o_u, roll, back, down, q5_default_a):
    c = k.cfg
    ki = k.internal          # the format the IK runs on (k itself without internal guard bits)
    guard = c.internal_guard_bits
    wide = wide_products(ki)
    nearest = c.round_nearest
    fu = ki.cfg.frac_unit
    # Input words to internal words: exact (|word| <= 2**31, shifted by at most 8 bits).
    px, py, pz = (p_l[:, i] << guard for i in range(3))
    ax, ay, az = (a_u[:, i] << guard for i in range(3))

    # Joint 1. Words: px*px, py*py <= 2**62 each (|word| <= 2**31); the sum reaches 2**63 for
    # px = py = word_min, one past int64: summed in uint64 (< 2**64).
    if wide:
        radicand = wide_add(wide_mul(px, px), wide_mul(py, py))
    else:
        radicand = (px * px).view(U64) + (py * py).view(U64)
    rho_l, status = saturate(isqrt(radicand, 2 * ki.cfg.width, nearest), ki)
    on_axis = rho_l == 0          # isqrt(r) >= 1 for r >= 1: only px == py == 0
    # The point's atan2, or the approach's on the axis (one CORDIC for both cases).
    theta1_a, vertical = _atan2_angle(np.where(on_axis, ay, py), np.where(on_axis, ax, px), ki)
    status |= np.where(vertical, SINGULAR_BASE, 0)   # zero implies on_axis, as in the model
    q1_a = np.where(back, opposite(theta1_a, ki), theta1_a)
    r_l = np.where(back, -rho_l, rho_l)
    c1_u, s1_u, sat = cordic_rotate(ki.one_u, 0, q1_a, ki)
    status |= sat

    # Pitch. Words: |c1|, |s1| <= one_u + a few LSB, (c1, s1) a unit vector: |ax c1 + ay s1| <=
    # |(ax, ay)| * |(c1, s1)| <= 2**31.5 * 2**30 (+ tiny) < 2**61.6; + 2**29 rounding bias.
    a_radial_u, sat = saturate(_dot_round(ax, c1_u, ay, s1_u, fu, nearest, wide), ki)
    status |= sat
    pitch_a, no_direction = _atan2_angle(a_radial_u, az, ki)
    status |= np.where(no_direction, INVALID, 0)
    status |= np.where(_off_plane(ax, ay, c1_u, s1_u, ki), BAD_ORIENTATION, 0)
    phi_a = opposite(pitch_a, ki)

    # Wrist centre: words, differences of three words < 2**(width + 1).
    off_x_l, off_y_l, sat = cordic_rotate(ki.a4_l, ki.d5_l, phi_a, ki)
    status |= sat
    xw_l, sat = saturate(r_l - ki.a1_l - off_x_l, ki)
    status |= sat
    yw_l, sat = saturate(ki.d1_l - pz - off_y_l, ki)
    status |= sat

    # Elbow.
    if guard == 0:
        # xw^2 + yw^2 reaches 2**63 (both word_min): summed as (xw^2 - links_sq) + yw^2, which
        # is the model's d_sq - links_sq exactly: xw^2 - links_sq in (-2**56, 2**62], + yw^2 <= 2**62
        # stays < 2**63 - links_sq (links_sq_l2 > 0).
        num_l2 = xw_l * xw_l - ki.links_sq_l2 + yw_l * yw_l
        reach = int(ki.reach_limit_l2)
        out_of_reach = (num_l2 > reach) | (num_l2 < -reach)
        num_l2 = np.clip(num_l2, -ki.twice_a2a3_l2, ki.twice_a2a3_l2)
        # |num_l2| <= twice_a2a3_l2: rshift by pre < 2**31 (ConstMul contract), product < 2**62.
        c3_u = np.clip(mul_const(num_l2, ki.c3_from_l2, nearest), -ki.one_u, ki.one_u)
        elbow_a, s3_u, _ = cordic_acos(c3_u, ki)
    else:
        # Wide: num = xw^2 - links_sq + yw^2 (< 2**81), clipped to [-2 a2 a3, 2 a2 a3]; then
        # 1 -+ c3 from 2 a2 a3 -+ num, as the model.
        num_l2 = wide_add(wide_sub(wide_mul(xw_l, xw_l), wide_from(int(ki.links_sq_l2))), wide_mul(yw_l, yw_l))
        twice = wide_from(int(ki.twice_a2a3_l2))
        minus_twice = wide_sub(wide_from(0), twice)
        too_far, too_near = wide_less(twice, num_l2), wide_less(num_l2, minus_twice)
        reach = wide_from(int(ki.reach_limit_l2))
        out_of_reach = wide_less(reach, num_l2) | wide_less(num_l2, wide_sub(wide_from(0), reach))
        num_l2 = tuple(np.where(too_far, t, np.where(too_near, m, v))
                       for t, m, v in zip(twice, minus_twice, num_l2))
        two_u = 2 * ki.one_u
        one_minus_c3_u = np.minimum(two_u, mul_const(wide_sub(twice, num_l2), ki.c3_complement_from_l2, nearest))
        one_plus_c3_u = np.minimum(two_u, mul_const(wide_add(twice, num_l2), ki.c3_complement_from_l2, nearest))
        c3_u = ki.one_u - one_minus_c3_u
        elbow_a, s3_u = acos_of_complements(one_minus_c3_u, one_plus_c3_u, ki)
    status |= np.where(out_of_reach, UNREACHABLE, 0)
    status |= np.where(s3_u <= ki.singular_s3_u, SINGULAR_ELBOW, 0)
    q3_a = np.where(down, -elbow_a, elbow_a)

    # Shoulder. Words: s3_u, |c3_u| <= one_u = 2**30 < 2**31 (a3_from_u.pre = 0): products < 2**61.3.
    gamma_a = _atan2_angle(yw_l, xw_l, ki)[0]
    beta_a = _atan2_angle(mul_const(s3_u, ki.a3_from_u, nearest),
                          ki.a2_l + mul_const(c3_u, ki.a3_from_u, nearest), ki)[0]
    q2_a = wrap_angle(np.where(down, gamma_a + beta_a, gamma_a - beta_a), ki)
    q4_a = wrap_angle(wrap_angle(phi_a - q2_a, ki) - q3_a, ki)

    # Joint 5 (same bound as a_radial: < 2**61.6). Rows without n, o compute with zeros and are
    # replaced by the default, their flags masked.
    nx, ny = (n_u[:, i] << guard for i in range(2))
    ox, oy = (o_u[:, i] << guard for i in range(2))
    s5_u, sat_s = saturate(_dot_round(nx, s1_u, -ny, c1_u, fu, nearest, wide), ki)
    c5_u, sat_c = saturate(_dot_round(ox, s1_u, -oy, c1_u, fu, nearest, wide), ki)
    q5_a, no_roll = _atan2_angle(s5_u, c5_u, ki)
    roll_flags = sat_s | sat_c | np.where(no_roll, INVALID, 0)
    roll_flags |= np.where(_frame_is_bad(n_u, o_u, a_u, k), BAD_ORIENTATION, 0)
    status |= np.where(roll, roll_flags, 0)
    q5_a = np.where(roll, q5_a, q5_default_a << guard)

    # Joint angles back to words, rounded and saturated.
    joints = []
    for q, off in zip((q1_a, q2_a, q3_a, q4_a, q5_a), ki.offset_a):
        joint_a, sat = saturate(rshift_round(wrap_angle(q - off, ki), guard, nearest), k)
        joints.append(joint_a)
        status |= sat
    return np.stack(joints, axis=1), status


def _beyond(value, centre, k: Constants):
    return (value > centre + k.check_tol_c2) | (value < centre - k.check_tol_c2)


def _off_plane(ax, ay, c1_u, s1_u, ki: Constants):
    """model.off_plane: ay c1 - ax s1 on check words (products < 2**34) beyond the tolerance."""
    shift = ki.check_shift
    return _beyond((ay >> shift) * (c1_u >> shift) - (ax >> shift) * (s1_u >> shift), 0, ki)


def _frame_is_bad(n_u, o_u, a_u, k: Constants):
    """model.frame_is_bad on (N, 3) word arrays (products of check words < 2**34)."""
    shift = k.check_shift
    n = [n_u[:, i] >> shift for i in range(3)]
    o = [o_u[:, i] >> shift for i in range(3)]
    a = [(a_u[:, i] >> shift) << k.check_frac for i in range(3)]
    bad = _beyond(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], k.check_one_c2, k)
    bad |= _beyond(o[0] * o[0] + o[1] * o[1] + o[2] * o[2], k.check_one_c2, k)
    bad |= _beyond(n[0] * o[0] + n[1] * o[1] + n[2] * o[2], 0, k)
    bad |= _beyond(n[1] * o[2] - n[2] * o[1] - a[0], 0, k)
    bad |= _beyond(n[2] * o[0] - n[0] * o[2] - a[1], 0, k)
    bad |= _beyond(n[0] * o[1] - n[1] * o[0] - a[2], 0, k)
    return bad


def _atan2_angle(y, x, k: Constants):
    """(angle_a, zero): cordic_atan2 without the magnitude (which the solver never uses)."""
    angle_a, _, _, zero = _atan2_core(y, x, k)
    return angle_a, zero


def solve_batch(k: Constants, p_l, a_u, n_u, o_u, has_roll, shoulder_back, elbow_down, q5_default_a):
    """ik_solve over a batch, the common signature of the three solvers (model, vector, C).

    p_l, a_u, n_u, o_u: (N, 3) integer arrays (words; n_u, o_u rows are read only where
    has_roll, and n_u / o_u may be None when no row has a roll); has_roll, shoulder_back,
    elbow_down: (N,) bools; q5_default_a: (N,) ints. Returns (q_a (N, 5) int64, status (N,) int64).
    """
    p_l = _arr(p_l).reshape(-1, 3)
    a_u = _arr(a_u).reshape(-1, 3)
    count = len(p_l)
    roll = np.asarray(has_roll, dtype=bool).reshape(count)
    back = np.asarray(shoulder_back, dtype=bool).reshape(count)
    down = np.asarray(elbow_down, dtype=bool).reshape(count)
    q5d = _arr(q5_default_a).reshape(count)
    if (n_u is None or o_u is None) and roll.any():
        raise ValueError("has_roll rows need n_u and o_u")
    zeros = np.zeros((count, 3), dtype=I64)
    # Rows without roll never read n, o (as in the model): zero them, so garbage cannot matter.
    n_u = zeros if n_u is None else np.where(roll[:, None], _arr(n_u).reshape(count, 3), 0)
    o_u = zeros if o_u is None else np.where(roll[:, None], _arr(o_u).reshape(count, 3), 0)
    if a_u.shape != p_l.shape:
        raise ValueError("p_l and a_u must have the same shape (N, 3)")
    for name, value in (("p_l", p_l), ("a_u", a_u), ("n_u", n_u), ("o_u", o_u), ("q5_default_a", q5d)):
        _check_words(name, value, k)
    q_a = np.empty((count, 5), dtype=I64)
    status = np.empty(count, dtype=I64)
    for start in range(0, count, CHUNK):
        sl = slice(start, start + CHUNK)
        q_a[sl], status[sl] = _solve_chunk(k, np.ascontiguousarray(p_l[sl]), np.ascontiguousarray(a_u[sl]),
                                           n_u[sl], o_u[sl], roll[sl], back[sl], down[sl], q5d[sl])
    return q_a, status
