"""Bit-accurate numpy-vectorised model of the C solver: the same outputs as ``model.py``, bit for bit.

Every function mirrors the scalar function of the same name in :mod:`ik5r.firmware_model.model` (the
specification) over int64 numpy arrays, one element per call of the scalar function; the IK body
itself is one, :func:`ik5r.core.ik.solve`, run here on :mod:`ik5r.core.fixedpoint_np` (the numpy
twin of the fixed-point vocabulary, re-exported here) and this module's CORDIC and square-root
kernels. Where the scalar model relies on Python's unbounded integers, the bound of every product
and sum is noted (for the widest config, width = 32, frac.unit = 30, 32 CORDIC iterations and 4
guard bits; the narrower configs have smaller values); the internal format of a config with
internal guard bits (words of up to 40 bits) forms its products as wide pairs
(:mod:`ik5r.core.fixedpoint_np`).

Inputs must be words (signed ``width``-bit integers): that is the C solver's interface (int32_t
words) and what the bounds below assume; :func:`solve_batch` checks it and raises ``ValueError``.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ik5r.core import fixedpoint_np
from ik5r.core.fixedpoint_np import (
    I64,
    LIMB_BITS,
    LIMB_MASK,
    U64,
    bit_length,
    dot_round,
    mul_const,
    mul_round,
    opposite,
    rshift_round,
    saturate,
    wide_add,
    wide_from,
    wide_less,
    wide_mul,
    wide_products,
    wide_rshift_round,
    wide_sub,
    wrap_angle,
)
from ik5r.core.fixedpoint_np import as_array as _arr
from ik5r.core.fixedpoint_np import bit_length_search as _bit_length_search
from ik5r.core.fxconfig import Constants
from ik5r.core.status import SATURATED

from ik5r.core import ik

#: Poses per chunk of :func:`solve_batch`: the working set (~30 int64 arrays) stays in L2/L3.
CHUNK = 32768


def _bit_length_ones_abs(x, y) -> np.ndarray:
    """Bit length of x | ones'-complement-abs(y), x >= 0."""
    y = _arr(y)
    return bit_length(_arr(x) | np.where(y < 0, ~y, y))


# --------------------------------------------------------------------------------------------
# CORDIC


def _iterate(xs, ys, z, atan_table, vectoring: bool) -> None:
    """The CORDIC iterations, in place on int64 arrays: vectoring (atan2) steers ys to 0 by
    d = sign(ys), rotation steers z to 0 by d = sign(z) (sign(0) = +1); the micro-rotation turns
    the vector by -d atan(2**-i) (vectoring) or +d atan(2**-i) (rotation) and z follows."""
    steer = ys if vectoring else z
    # Vectoring: xs += d (ys >> i), ys -= d (xs >> i), z += d step; rotation: the signs swapped.
    turn_x, turn_y = (np.add, np.subtract) if vectoring else (np.subtract, np.add)
    tx = np.empty_like(xs)
    ty = np.empty_like(xs)
    d = np.empty_like(xs)
    for i, step_z in enumerate(atan_table):
        np.right_shift(steer, 63, out=d)
        np.bitwise_or(d, 1, out=d)
        np.right_shift(ys, i, out=tx)
        np.right_shift(xs, i, out=ty)
        tx *= d
        ty *= d
        turn_x(xs, tx, out=xs)
        turn_y(ys, ty, out=ys)
        d *= step_z
        turn_x(z, d, out=z)


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
    _iterate(xs, ys, z, k.atan_table, vectoring=True)
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
    xs = mul_round(x, k.inv_gain, shift, nearest, k)
    ys = mul_round(y, k.inv_gain, shift, nearest, k)
    _iterate(xs, ys, z, k.atan_table, vectoring=False)
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


def atan2_angle(y, x, k: Constants):
    """(angle_a, zero): cordic_atan2 without the magnitude (which the IK never uses)."""
    angle_a, _, _, zero = _atan2_core(y, x, k)
    return angle_a, zero


#: The kernels :func:`ik5r.core.ik.solve` runs on, over arrays (the names of ``model.KERNELS``).
KERNELS = SimpleNamespace(atan2_angle=atan2_angle, cordic_rotate=cordic_rotate, isqrt=isqrt,
                          cordic_acos=cordic_acos, acos_of_complements=acos_of_complements)


def _check_words(name: str, value: np.ndarray, k: Constants) -> None:
    if value.size and (value.min() < k.word_min or value.max() > k.word_max):
        raise ValueError(f"{name}: values outside the {k.cfg.width}-bit word range")


def _solve_chunk(k: Constants, p_l, a_u, n_u, o_u, roll, back, down, q5_default_a):
    """:func:`ik5r.core.ik.solve` on (N, 3) word arrays: ((N, 5) angle words, (N,) status)."""
    def columns(words):
        return tuple(words[:, i] for i in range(3))
    joints, status = ik.solve(fixedpoint_np, KERNELS, k, columns(p_l), columns(a_u), columns(n_u),
                              columns(o_u), roll, back, down, q5_default_a)
    return np.stack(joints, axis=1), status


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
