"""numpy versions of the block-level functions of the bit-accurate model (``ik5r.firmware.model``).

Same arithmetic, element-wise on int64 arrays, for checking millions of hardware outputs in a few
seconds. Every intermediate is bounded below 2**63 for widths up to 32 (see the comments); the
testbench still runs the scalar model itself on the edge set and on a random sample of every run
and fails if the two ever disagree, so this file can not silently become the specification.
"""

from __future__ import annotations

import numpy as np

from ik5r.fxconfig import INV_GAIN_FRAC, Constants

I64 = np.int64


def rshift_round(value, shift, nearest: bool):
    """value * 2**-shift rounded half up / floored; ``shift`` a scalar or an array, > 0."""
    value = np.asarray(value, dtype=I64)
    shift = np.asarray(shift, dtype=I64)
    if nearest:
        value = value + (I64(1) << (shift - 1))
    return value >> shift


def saturate(value, k: Constants):
    value = np.asarray(value, dtype=I64)
    sat = (value > k.word_max) | (value < k.word_min)
    return np.clip(value, k.word_min, k.word_max), sat


def bit_length(value):
    """Bit length of non-negative int64 values below 2**53 (exact through frexp)."""
    return np.frexp(np.asarray(value, dtype=np.float64))[1].astype(I64)


def cordic_atan2(y, x, k: Constants):
    """Vectorised ``model.cordic_atan2``: returns (angle_a, magnitude, zero)."""
    c = k.cfg
    y = np.asarray(y, dtype=I64)
    x = np.asarray(x, dtype=I64)
    zero = (x == 0) & (y == 0)
    neg = x < 0
    up = y >= 0
    xs = np.where(neg, np.where(up, y, -y), x)
    ys = np.where(neg, np.where(up, -x, x), y)
    z = np.where(neg, np.where(up, k.half_pi_z, -k.half_pi_z), 0).astype(I64)
    norm = np.maximum(0, c.width - 1 - bit_length(xs | np.where(ys < 0, ~ys, ys)))
    xs = xs << (norm + c.guard_bits)            # top bit at width - 2 + guard: < 2**37
    ys = ys << (norm + c.guard_bits)
    for i, step in enumerate(k.atan_table):
        pos = ys >= 0
        dx, dy = ys >> i, xs >> i
        xs, ys, z = (np.where(pos, xs + dx, xs - dx), np.where(pos, ys - dy, ys + dy),
                     np.where(pos, z + step, z - step))
    angle = rshift_round(z, c.angle_guard_bits, c.round_nearest)
    # (xs >> guard) < 1.65 * sqrt(2) * 2**31, inv_gain < 0.61 * 2**31: product < 2**63.
    magnitude = rshift_round((xs >> c.guard_bits) * I64(k.inv_gain), INV_GAIN_FRAC + norm, c.round_nearest)
    magnitude, _ = saturate(magnitude, k)
    angle = np.where(zero, 0, angle)
    magnitude = np.where(zero, 0, magnitude)
    return angle, magnitude, zero


def cordic_rotate(x, y, angle_a, k: Constants):
    """Vectorised ``model.cordic_rotate``: returns (x', y', saturated)."""
    c = k.cfg
    x = np.asarray(x, dtype=I64)
    y = np.asarray(y, dtype=I64)
    z = np.asarray(angle_a, dtype=I64) << c.angle_guard_bits
    hi, lo = z > k.half_pi_z, z < -k.half_pi_z
    x, y = np.where(hi, -y, np.where(lo, y, x)), np.where(hi, x, np.where(lo, -x, y))
    z = np.where(hi, z - k.half_pi_z, np.where(lo, z + k.half_pi_z, z))
    shift = INV_GAIN_FRAC - c.guard_bits
    xs = rshift_round(x * I64(k.inv_gain), shift, c.round_nearest)   # |x| <= 2**31: < 2**62
    ys = rshift_round(y * I64(k.inv_gain), shift, c.round_nearest)
    for i, step in enumerate(k.atan_table):
        pos = z >= 0
        dx, dy = ys >> i, xs >> i
        xs, ys, z = (np.where(pos, xs - dx, xs + dx), np.where(pos, ys + dy, ys - dy),
                     np.where(pos, z - step, z + step))
    xo, sx = saturate(rshift_round(xs, c.guard_bits, c.round_nearest), k)
    yo, sy = saturate(rshift_round(ys, c.guard_bits, c.round_nearest), k)
    return xo, yo, sx | sy


def isqrt(radicand, bits: int, nearest: bool):
    """Vectorised ``model.isqrt`` (bits <= 62): the recurrence sees radicand mod 2**bits."""
    assert bits <= 62
    rad = np.asarray(radicand, dtype=I64).astype(np.uint64) & np.uint64((1 << bits) - 1)
    root = np.floor(np.sqrt(rad.astype(np.float64))).astype(np.uint64)   # < 2**31
    for _ in range(3):                              # float rounding: fix up by +-1
        root = np.where(root * root > rad, root - np.uint64(1), root)
        root = np.where((root + np.uint64(1)) * (root + np.uint64(1)) <= rad, root + np.uint64(1), root)
    if nearest:
        root = np.where(rad - root * root > root, root + np.uint64(1), root)
    return root.astype(I64)


def sqrt_word(x, frac: int, k: Constants):
    c = k.cfg
    bits = c.width + frac + ((c.width + frac) & 1)
    return isqrt(np.asarray(x, dtype=I64) << frac, bits, c.round_nearest)


def cordic_acos(x_u, k: Constants):
    """Vectorised ``model.cordic_acos``: returns (angle_a, sine_u, saturated)."""
    c = k.cfg
    x_u = np.asarray(x_u, dtype=I64)
    sat = (x_u > k.one_u) | (x_u < -k.one_u)
    x_u = np.clip(x_u, -k.one_u, k.one_u)
    product = (k.one_u - x_u) * (k.one_u + x_u)          # < 2**(2 * frac_unit + 1) <= 2**61
    sine = isqrt(product, 2 * c.frac_unit + 2, c.round_nearest)
    angle, _, _ = cordic_atan2(sine, x_u, k)
    return angle, sine, sat
