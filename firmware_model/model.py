"""Bit-accurate scalar model of the C solver ``ik5r.c``: one Python function per C function.

This is the specification of the fixed-point IK. Python integers are unbounded, so every place
where the C relies on a width (int32 words, int64 products and CORDIC state) is bounded here by
construction and checked by the tests, never by wrapping. ``>>`` on a negative Python int floors,
exactly like the C's arithmetic right shift (see docs/algorithm.md, "C semantics").

Names follow the C: ``_l`` length Q(frac.length), ``_u`` unit-vector Q(frac.unit),
``_a`` angle Q(frac.angle) radians, ``_z`` CORDIC angle Q(frac.angle + angle_guard_bits),
``_l2`` squared length Q(2 * frac.length).

Every function takes the constants ``k`` of the format it works on. The building blocks called on
their own work on the config's words; :func:`ik_solve` runs on the internal format
``k.internal`` (``ik.internal_guard_bits`` more fraction bits in every quantity, the word width
and the CORDIC iterations widened alike; ``k`` itself when that is 0): it shifts its input words
up, and rounds the joint angles back to words, saturated. The helpers the C has too
(``rshift_round``, ``saturate``, ``mul_const``, ``wrap_angle``, ``opposite``) are the fixed-point
vocabulary of :mod:`ik5r.core.fixedpoint`, shared with the HDL. The IK body is written once, in that
vocabulary, in :mod:`ik5r.core.ik` (with the orientation checks ``check_word``, ``beyond``,
``off_plane``, ``frame_is_bad``, re-exported here); :func:`ik_solve` runs it on Python integers
and this module's CORDIC and square-root kernels (:data:`KERNELS`), the vectorised model on arrays.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

from ik5r.core import fixedpoint
from ik5r.core.fixedpoint import mul_const, opposite, rshift_round, saturate, wrap_angle  # noqa: F401 (the C's helpers)
from ik5r.core.fxconfig import Constants
from ik5r.core.status import SATURATED

from ik5r.core import ik
from ik5r.core.ik import beyond, check_word, frame_is_bad, off_plane  # noqa: F401 (the C's helpers)


def _bit_length_ones_abs(x: int, y: int) -> int:
    """Bit length of x | ones'-complement-abs(y), x >= 0: what the HDL's priority encoder sees."""
    return (x | (~y if y < 0 else y)).bit_length()


def cordic_atan2(y: int, x: int, k: Constants) -> tuple[int, int, bool]:
    """Full-circle atan2 of two words by CORDIC vectoring.

    Returns (angle_a, magnitude in the inputs' format (saturated), zero) where zero means
    x == y == 0 and angle 0.
    """
    c = k.cfg
    if x == 0 and y == 0:
        return 0, 0, True
    # Coarse rotation by -+90 degrees into the right half-plane (widens by one bit).
    if x < 0:
        if y >= 0:
            xs, ys, z = y, -x, k.half_pi_z
        else:
            xs, ys, z = -y, x, -k.half_pi_z
    else:
        xs, ys, z = x, y, 0
    # Normalise: largest component's top bit to bit width-2 (block floating point).
    norm = max(0, c.width - 1 - _bit_length_ones_abs(xs, ys))
    xs <<= norm + c.guard_bits
    ys <<= norm + c.guard_bits
    for i, step_z in enumerate(k.atan_table):
        if ys >= 0:
            xs, ys, z = xs + (ys >> i), ys - (xs >> i), z + step_z
        else:
            xs, ys, z = xs - (ys >> i), ys + (xs >> i), z - step_z
    angle_a = rshift_round(z, c.angle_guard_bits, c.round_nearest)
    # Magnitude: drop the guard bits, undo the gain K, then undo the normalisation.
    magnitude = rshift_round(
        (xs >> c.guard_bits) * k.inv_gain, k.inv_gain_frac + norm, c.round_nearest)
    magnitude, _ = saturate(magnitude, k)
    return angle_a, magnitude, False


def cordic_rotate(x: int, y: int, angle_a: int, k: Constants) -> tuple[int, int, int]:
    """Rotate the vector (x, y) of words by angle_a (|angle_a| <= pi + a few LSB).

    The CORDIC gain is compensated on the input. Returns (x', y', SATURATED or 0).
    """
    c = k.cfg
    z = angle_a << c.angle_guard_bits
    if z > k.half_pi_z:
        x, y, z = -y, x, z - k.half_pi_z
    elif z < -k.half_pi_z:
        x, y, z = y, -x, z + k.half_pi_z
    shift = k.inv_gain_frac - c.guard_bits
    xs = rshift_round(x * k.inv_gain, shift, c.round_nearest)
    ys = rshift_round(y * k.inv_gain, shift, c.round_nearest)
    for i, step_z in enumerate(k.atan_table):
        if z >= 0:
            xs, ys, z = xs - (ys >> i), ys + (xs >> i), z - step_z
        else:
            xs, ys, z = xs + (ys >> i), ys - (xs >> i), z + step_z
    xo, sat_x = saturate(rshift_round(xs, c.guard_bits, c.round_nearest), k)
    yo, sat_y = saturate(rshift_round(ys, c.guard_bits, c.round_nearest), k)
    return xo, yo, sat_x | sat_y


def isqrt(radicand: int, bits: int, nearest: bool) -> int:
    """Square root of an unsigned integer below 2**bits by digit recurrence (bits even)."""
    root = rem = 0
    for i in range(bits // 2 - 1, -1, -1):
        rem = (rem << 2) | ((radicand >> (2 * i)) & 3)
        trial = (root << 2) | 1
        root <<= 1
        if rem >= trial:
            rem -= trial
            root |= 1
    if nearest and rem > root:
        root += 1
    return root


def sqrt_word(x: int, frac: int, k: Constants) -> int:
    """Square root of a non-negative word with ``frac`` fraction bits, same format."""
    c = k.cfg
    bits = c.width + frac + ((c.width + frac) & 1)
    return isqrt(x << frac, bits, c.round_nearest)


def acos_of_complements(one_minus_u: int, one_plus_u: int, k: Constants) -> tuple[int, int]:
    """acos(x) as atan2(sqrt((1 - x)(1 + x)), x), given 1 - x and 1 + x (unit format, each in
    [0, 2]). Returns (angle_a, sine_u = sin(angle))."""
    c = k.cfg
    # The product of two numbers in [0, 2] with 2*frac_unit fraction bits: at most 2**(2*frac_unit + 2).
    product_u2 = one_minus_u * one_plus_u
    sine_u = isqrt(product_u2, 2 * c.frac_unit + 4, c.round_nearest)
    angle_a, _, _ = cordic_atan2(sine_u, k.one_u - one_minus_u, k)
    return angle_a, sine_u


def cordic_acos(x_u: int, k: Constants) -> tuple[int, int, int]:
    """acos of a unit-format word as atan2(sqrt((1 - x)(1 + x)), x).

    Input outside [-1, 1] is clipped and flagged. Returns (angle_a, sine_u = sin(angle), flags).
    """
    flags = 0
    if x_u > k.one_u:
        x_u, flags = k.one_u, SATURATED
    elif x_u < -k.one_u:
        x_u, flags = -k.one_u, SATURATED
    angle_a, sine_u = acos_of_complements(k.one_u - x_u, k.one_u + x_u, k)
    return angle_a, sine_u, flags


@dataclass(frozen=True)
class Pose:
    """One pose in raw words: position (length format), approach a and optionally n, o (unit)."""

    p_l: tuple[int, int, int]
    a_u: tuple[int, int, int]
    n_u: tuple[int, int, int] | None = None
    o_u: tuple[int, int, int] | None = None


def atan2_angle(y: int, x: int, k: Constants) -> tuple[int, bool]:
    """(angle_a, zero): cordic_atan2 without the magnitude (which the IK never uses)."""
    angle_a, _, zero = cordic_atan2(y, x, k)
    return angle_a, zero


#: The kernels :func:`ik5r.core.ik.solve` runs on, on Python integers (the vectorised model
#: has the same names over arrays).
KERNELS = SimpleNamespace(atan2_angle=atan2_angle, cordic_rotate=cordic_rotate, isqrt=isqrt,
                          cordic_acos=cordic_acos, acos_of_complements=acos_of_complements)
_NO_FRAME = (0, 0, 0)


def ik_solve(pose: Pose, shoulder_back: bool, elbow_down: bool, q5_default_a: int,
             k: Constants) -> tuple[tuple[int, int, int, int, int], int]:
    """The fixed-point IK of one pose for one branch: ((q1..q5) angle words, status bits).

    Branch: shoulder_back puts the tool point behind joint 1 (q1 + pi); elbow_down takes
    q3 = -acos(c3) instead of +acos(c3). q5_default_a is used when n, o are absent. The body is
    :func:`ik5r.core.ik.solve` (shared with the vectorised model) on :mod:`ik5r.core.fixedpoint`.
    """
    roll = pose.n_u is not None and pose.o_u is not None
    joints, status = ik.solve(fixedpoint, KERNELS, k, pose.p_l, pose.a_u,
                              pose.n_u if roll else _NO_FRAME, pose.o_u if roll else _NO_FRAME,
                              roll, shoulder_back, elbow_down, q5_default_a)
    return tuple(joints), status


def solve_batch(k: Constants, p_l, a_u, n_u, o_u, has_roll, shoulder_back, elbow_down, q5_default_a):
    """ik_solve over a batch, the common signature of the three solvers (model, vector, C).

    p_l, a_u, n_u, o_u: (N, 3) integer arrays; has_roll, shoulder_back, elbow_down: (N,) bools;
    q5_default_a: (N,) ints. Returns (q_a (N, 5) int64, status (N,) int64).
    """
    import numpy as np

    count = len(p_l)
    q_a = np.zeros((count, 5), dtype=np.int64)
    status = np.zeros(count, dtype=np.int64)
    for i in range(count):
        roll = bool(has_roll[i])
        pose = Pose(tuple(int(v) for v in p_l[i]), tuple(int(v) for v in a_u[i]),
                    tuple(int(v) for v in n_u[i]) if roll else None,
                    tuple(int(v) for v in o_u[i]) if roll else None)
        joints, status[i] = ik_solve(pose, bool(shoulder_back[i]), bool(elbow_down[i]), int(q5_default_a[i]), k)
        q_a[i] = joints
    return q_a, status
