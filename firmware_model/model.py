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
vocabulary of :mod:`ik5r.fixedpoint`, shared with the HDL.
"""

from __future__ import annotations

from dataclasses import dataclass

from ik5r.fixedpoint import mul_const, opposite, rshift_round, saturate, wrap_angle  # noqa: F401 (the C's helpers)
from ik5r.fxconfig import Constants
from ik5r.status import BAD_ORIENTATION, INVALID, SATURATED, SINGULAR_BASE, SINGULAR_ELBOW, UNREACHABLE


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


def check_word(value: int, k: Constants) -> int:
    """The top bits of a unit word of format ``k`` (floor): the operand of an orientation check."""
    return value >> k.check_shift


def beyond(value: int, centre: int, k: Constants) -> bool:
    """|value - centre| > the orientation tolerance (products of check words, Q(2 check_frac))."""
    return value > centre + k.check_tol_c2 or value < centre - k.check_tol_c2


def frame_is_bad(n_u, o_u, a_u, k: Constants) -> bool:
    """n, o, a (words of format ``k``) not a right-handed orthonormal frame within the orientation
    tolerance: |n.n - 1|, |o.o - 1|, |n.o| or a component of n x o - a above it."""
    n = [check_word(v, k) for v in n_u]
    o = [check_word(v, k) for v in o_u]
    a = [check_word(v, k) << k.check_frac for v in a_u]
    one = k.check_one_c2
    nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2]
    oo = o[0] * o[0] + o[1] * o[1] + o[2] * o[2]
    no = n[0] * o[0] + n[1] * o[1] + n[2] * o[2]
    cross = (n[1] * o[2] - n[2] * o[1], n[2] * o[0] - n[0] * o[2], n[0] * o[1] - n[1] * o[0])
    return (beyond(nn, one, k) or beyond(oo, one, k) or beyond(no, 0, k)
            or any(beyond(c - ai, 0, k) for c, ai in zip(cross, a)))


def off_plane(ax: int, ay: int, c1_u: int, s1_u: int, ki: Constants) -> bool:
    """The approach's component normal to the arm's plane, ay c1 - ax s1 (check words of the
    internal format), beyond the orientation tolerance."""
    normal = check_word(ay, ki) * check_word(c1_u, ki) - check_word(ax, ki) * check_word(s1_u, ki)
    return beyond(normal, 0, ki)


@dataclass(frozen=True)
class Pose:
    """One pose in raw words: position (length format), approach a and optionally n, o (unit)."""

    p_l: tuple[int, int, int]
    a_u: tuple[int, int, int]
    n_u: tuple[int, int, int] | None = None
    o_u: tuple[int, int, int] | None = None


def ik_solve(pose: Pose, shoulder_back: bool, elbow_down: bool, q5_default_a: int,
             k: Constants) -> tuple[tuple[int, int, int, int, int], int]:
    """The fixed-point IK of one pose for one branch: ((q1..q5) angle words, status bits).

    Branch: shoulder_back puts the tool point behind joint 1 (q1 + pi); elbow_down takes
    q3 = -acos(c3) instead of +acos(c3). q5_default_a is used when n, o are absent.
    Every quantity below is in the internal format of ``ki = k.internal``.
    """
    c = k.cfg
    ki = k.internal
    guard = c.internal_guard_bits
    nearest = c.round_nearest
    status = 0
    # Input words to internal words: exact (guard more fraction bits, the same real range).
    px, py, pz = (v << guard for v in pose.p_l)
    ax, ay, az = (v << guard for v in pose.a_u)

    # Joint 1: the arm's plane contains the tool point, or the approach if the point is on the axis.
    # px^2 + py^2 reaches 2**(2 width - 1) (px = py = word_min): the C sums it in 128 bits.
    rho_l = isqrt(px * px + py * py, 2 * ki.cfg.width, nearest)
    rho_l, sat = saturate(rho_l, ki)
    status |= sat
    if rho_l != 0:
        theta1_a, _, _ = cordic_atan2(py, px, ki)
    else:
        theta1_a, _, vertical = cordic_atan2(ay, ax, ki)
        if vertical:
            status |= SINGULAR_BASE
    if shoulder_back:
        q1_a = opposite(theta1_a, ki)
        r_l = -rho_l
    else:
        q1_a = theta1_a
        r_l = rho_l
    c1_u, s1_u, sat = cordic_rotate(ki.one_u, 0, q1_a, ki)
    status |= sat

    # Tool pitch phi = q2 + q3 + q4 from the approach projected onto the arm's plane.
    fu = ki.cfg.frac_unit
    a_radial_u, sat = saturate(rshift_round(ax * c1_u + ay * s1_u, fu, nearest), ki)
    status |= sat
    pitch_a, _, no_direction = cordic_atan2(a_radial_u, az, ki)
    if no_direction:
        status |= INVALID
    if off_plane(ax, ay, c1_u, s1_u, ki):
        status |= BAD_ORIENTATION
    phi_a = opposite(pitch_a, ki)

    # Wrist centre (joint 4 axis) in the arm's plane: subtract R(phi) (a4, d5).
    off_x_l, off_y_l, sat = cordic_rotate(ki.a4_l, ki.d5_l, phi_a, ki)
    status |= sat
    xw_l, sat = saturate(r_l - ki.a1_l - off_x_l, ki)
    status |= sat
    yw_l, sat = saturate(ki.d1_l - pz - off_y_l, ki)
    status |= sat

    # Elbow: law of cosines, clipped to the reachable annulus.
    # xw^2 + yw^2 reaches 2**(2 width - 1) (xw = yw = word_min): the C subtracts first, in 128 bits.
    # Beyond the annulus by more than the reach tolerance: unreachable; within it: clipped only
    # (a straight or folded elbow, flagged singular below).
    num_l2 = (xw_l * xw_l - ki.links_sq_l2) + yw_l * yw_l
    if num_l2 > ki.reach_limit_l2 or num_l2 < -ki.reach_limit_l2:
        status |= UNREACHABLE
    num_l2 = max(-ki.twice_a2a3_l2, min(ki.twice_a2a3_l2, num_l2))
    if guard == 0:
        c3_u = max(-ki.one_u, min(ki.one_u, mul_const(num_l2, ki.c3_from_l2, nearest)))
        elbow_a, s3_u, _ = cordic_acos(c3_u, ki)
    else:
        # 1 - c3 = (2 a2 a3 - num) / (2 a2 a3) and 1 + c3 = (2 a2 a3 + num) / (2 a2 a3) straight
        # from the law of cosines: near the straight (folded) elbow 1 - c3 (1 + c3) is small and
        # keeps its relative precision, which 1 - c3 formed from a rounded c3 would not.
        two_u = 2 * ki.one_u
        one_minus_c3_u = min(two_u, mul_const(ki.twice_a2a3_l2 - num_l2, ki.c3_complement_from_l2, nearest))
        one_plus_c3_u = min(two_u, mul_const(ki.twice_a2a3_l2 + num_l2, ki.c3_complement_from_l2, nearest))
        c3_u = ki.one_u - one_minus_c3_u
        elbow_a, s3_u = acos_of_complements(one_minus_c3_u, one_plus_c3_u, ki)
    if s3_u <= ki.singular_s3_u:
        status |= SINGULAR_ELBOW
    q3_a = -elbow_a if elbow_down else elbow_a

    # Shoulder: q2 = atan2(yw, xw) -+ atan2(a3 sin|q3|, a2 + a3 cos q3).
    gamma_a, _, _ = cordic_atan2(yw_l, xw_l, ki)
    beta_a, _, _ = cordic_atan2(mul_const(s3_u, ki.a3_from_u, nearest),
                                ki.a2_l + mul_const(c3_u, ki.a3_from_u, nearest), ki)
    q2_a = wrap_angle(gamma_a + beta_a if elbow_down else gamma_a - beta_a, ki)
    q4_a = wrap_angle(wrap_angle(phi_a - q2_a, ki) - q3_a, ki)

    # Joint 5: tool roll from n and o, else the caller's value.
    if pose.n_u is not None and pose.o_u is not None:
        nx, ny, _ = (v << guard for v in pose.n_u)
        ox, oy, _ = (v << guard for v in pose.o_u)
        s5_u, sat_s = saturate(rshift_round(nx * s1_u - ny * c1_u, fu, nearest), ki)
        c5_u, sat_c = saturate(rshift_round(ox * s1_u - oy * c1_u, fu, nearest), ki)
        status |= sat_s | sat_c
        q5_a, _, no_roll = cordic_atan2(s5_u, c5_u, ki)
        if no_roll:
            status |= INVALID
        if frame_is_bad(pose.n_u, pose.o_u, pose.a_u, k):
            status |= BAD_ORIENTATION
    else:
        q5_a = q5_default_a << guard

    # Joint angles back to words (rounded, saturated: the last overflow check).
    joints = []
    for q, off in zip((q1_a, q2_a, q3_a, q4_a, q5_a), ki.offset_a):
        joint_a, sat = saturate(rshift_round(wrap_angle(q - off, ki), guard, nearest), k)
        joints.append(joint_a)
        status |= sat
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
