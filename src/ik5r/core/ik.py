"""The fixed-point IK of ``ik5r.c``, written once (bottom layer): the scalar and the vectorised
firmware models run it on numbers, the compact HDL core traces it into its program
(``ik5r.hdl.graph.trace``).

Every function takes ``fx``, the fixed-point vocabulary (:mod:`ik5r.core.fixedpoint` on Python
integers, :mod:`ik5r.core.fixedpoint_np` on numpy arrays: the same names), and ``fw``, the model's
CORDIC and square-root kernels (:mod:`ik5r.firmware_model.model` or :mod:`ik5r.firmware_model.vector`, or the
symbolic ones of ``ik5r.hdl.graph.trace``:
``atan2_angle``, ``cordic_rotate``, ``isqrt``, ``cordic_acos``, ``acos_of_complements``). A value
is one integer (the scalar model, one pose) or one array element per pose (the vectorised model);
where the scalar C branches per pose, the body selects (``fx.select``, ``fx.flag``), which is the
same value for one pose. The orientation checks (``check_word``, ``beyond``, ``off_plane``,
``frame_is_bad``) use only ``>>``, ``*``, ``+``, ``-``, comparisons and ``|``, which Python
integers and int64 arrays evaluate alike (their products stay below 2**34; the sign test of
``_plane_direction``, check words times internal words, below 2**55).

Names follow the C: ``_l`` length Q(frac.length), ``_u`` unit-vector Q(frac.unit), ``_a`` angle
Q(frac.angle) radians, ``_l2`` squared length Q(2 * frac.length). Every quantity of :func:`solve`
is in the internal format ``ki = k.internal`` (see ``model.py``).
"""

from __future__ import annotations

from ik5r.core.fxconfig import Constants
from ik5r.core.status import (BAD_ORIENTATION, INVALID, OUT_OF_LIMITS, SINGULAR_BASE, SINGULAR_ELBOW,
                              UNREACHABLE)

# --- orientation checks ---------------------------------------------------------------------------


def check_word(value, k: Constants):
    """The top bits of a unit word of format ``k`` (floor): the operand of an orientation check."""
    return value >> k.check_shift


def beyond(value, centre, k: Constants):
    """|value - centre| > the orientation tolerance (products of check words, Q(2 check_frac))."""
    return (value > centre + k.check_tol_c2) | (value < centre - k.check_tol_c2)


def frame_is_bad(n_u, o_u, a_u, k: Constants):
    """n, o, a (three words each, format ``k``) not a right-handed orthonormal frame within the
    orientation tolerance: |n.n - 1|, |o.o - 1|, |n.o| or a component of n x o - a above it."""
    n = [check_word(v, k) for v in n_u]
    o = [check_word(v, k) for v in o_u]
    a = [check_word(v, k) << k.check_frac for v in a_u]
    one = k.check_one_c2
    bad = beyond(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], one, k)
    bad |= beyond(o[0] * o[0] + o[1] * o[1] + o[2] * o[2], one, k)
    bad |= beyond(n[0] * o[0] + n[1] * o[1] + n[2] * o[2], 0, k)
    bad |= beyond(n[1] * o[2] - n[2] * o[1] - a[0], 0, k)
    bad |= beyond(n[2] * o[0] - n[0] * o[2] - a[1], 0, k)
    bad |= beyond(n[0] * o[1] - n[1] * o[0] - a[2], 0, k)
    return bad


def off_plane(ax, ay, c1_u, s1_u, ki: Constants):
    """The approach's component normal to the arm's plane, ay c1 - ax s1 (check words of the
    internal format), beyond the orientation tolerance."""
    normal = check_word(ay, ki) * check_word(c1_u, ki) - check_word(ax, ki) * check_word(s1_u, ki)
    return beyond(normal, 0, ki)


# --- the IK, stage by stage -------------------------------------------------------------------


def _magnitude(fx, value, k: Constants):
    """|value| of a word, from two clips (no negation of a word)."""
    return fx.clip(value, 0, k.word_max) - fx.clip(value, k.word_min, 0)


def _approach_weight(fx, px, py, ax, ay, guard: int, ki: Constants):
    """2 where the tool point lies within 2 input LSB of the approach's vertical plane (the
    mismatch the input rounding can make), else 0: then the approach may set the arm's plane.

    |u x v| / |v| is the point's distance from the approach's plane; |v| is bounded by
    L = |ax| + |ay| in [|v|, sqrt(2) |v|], so the test is |u x v| / one_u <= 2 2^guard L / one_u,
    both sides rounded to integers. Words: |px ay - py ax| < 2**(2 width - 1) (exact, then >> fu)."""
    nearest = ki.cfg.round_nearest
    cross = fx.dot_round(px, ay, -py, ax, ki.cfg.frac_unit, nearest, ki)
    span = _magnitude(fx, ax, ki) + _magnitude(fx, ay, ki)
    slack = fx.rshift_round(span, ki.cfg.frac_unit - guard - 1, nearest) - _magnitude(fx, cross, ki)
    return fx.clip(slack + slack + 2, 0, 2)


def _plane_direction(fx, px, py, ax, ay, guard: int, ki: Constants):
    """The horizontal direction of the arm's plane, (x, y) words (docs/algorithm.md, "Joint 1
    near the base axis"): the tool point's horizontal part u, plus the approach's v (sign turned
    to agree with u) where the point lies on the approach's plane to within the input rounding.
    Then each enters by its length in its own LSBs: near the axis the approach sets q1. Elsewhere
    (a pose whose approach is off the point's plane) u alone, as the word IK always did.

    Words: the sums may pass the word range only for points beyond any reach: clipped."""
    nearest = ki.cfg.round_nearest
    weight = _approach_weight(fx, px, py, ax, ay, guard, ki)
    # v or 0: v * weight / 2 (weight 0 or 2), exact, one product the tracer can lower.
    vx, vy = (fx.mul_round(v, weight, 1, nearest, ki) for v in (ax, ay))
    # The sign of u . v from v's check words (products below 2**55 in every format): wrong only
    # where u is too short (2 LSB) to tell the point's side of the axis.
    opposed = check_word(ax, ki) * px + check_word(ay, ki) * py < 0
    low, high = ki.word_min, ki.word_max
    x = fx.select(opposed, fx.clip(px - vx, low, high), fx.clip(px + vx, low, high))
    y = fx.select(opposed, fx.clip(py - vy, low, high), fx.clip(py + vy, low, high))
    return x, y


def _joint1(fx, fw, px, py, ax, ay, back, guard: int, ki: Constants):
    """q1 and the signed radius r: the arm's plane from the tool point and the approach together
    (:func:`_plane_direction`). Returns (q1_a, r_l, c1_u, s1_u, status)."""
    nearest = ki.cfg.round_nearest
    # px^2 + py^2 reaches 2**(2 width - 1) (px = py = word_min): the C sums it in 128 bits.
    rho_l, status = fx.saturate(fw.isqrt(fx.sum_of_squares(px, py, ki), 2 * ki.cfg.width, nearest), ki)
    # The direction is the zero vector only where the point is on the axis and the approach
    # vertical (then q1 is free).
    x, y = _plane_direction(fx, px, py, ax, ay, guard, ki)
    theta1_a, vertical = fw.atan2_angle(y, x, ki)
    status |= fx.flag(vertical, SINGULAR_BASE)
    q1_a = fx.select(back, fx.opposite(theta1_a, ki), theta1_a)
    r_l = fx.select(back, -rho_l, rho_l)
    c1_u, s1_u, sat = fw.cordic_rotate(ki.one_u, 0, q1_a, ki)
    return q1_a, r_l, c1_u, s1_u, status | sat


def _pitch(fx, fw, ax, ay, az, c1_u, s1_u, ki: Constants):
    """Tool pitch phi = q2 + q3 + q4 from the approach projected onto the arm's plane.

    Words: |c1|, |s1| <= one_u + a few LSB, (c1, s1) a unit vector: |ax c1 + ay s1| <= |(ax, ay)| *
    |(c1, s1)| <= 2**31.5 * 2**30 (+ tiny) < 2**61.6; + 2**29 rounding bias. Returns (phi_a, status).
    """
    nearest = ki.cfg.round_nearest
    a_radial_u, status = fx.saturate(fx.dot_round(ax, c1_u, ay, s1_u, ki.cfg.frac_unit, nearest, ki), ki)
    pitch_a, no_direction = fw.atan2_angle(a_radial_u, az, ki)
    status |= fx.flag(no_direction, INVALID)
    status |= fx.flag(off_plane(ax, ay, c1_u, s1_u, ki), BAD_ORIENTATION)
    return fx.opposite(pitch_a, ki), status


def _wrist(fx, fw, r_l, pz, phi_a, ki: Constants):
    """Wrist centre (joint 4 axis) in the arm's plane: subtract R(phi) (a4, d5).

    Words: differences of three words < 2**(width + 1). Returns (xw_l, yw_l, status)."""
    off_x_l, off_y_l, status = fw.cordic_rotate(ki.a4_l, ki.d5_l, phi_a, ki)
    xw_l, sat = fx.saturate(r_l - ki.a1_l - off_x_l, ki)
    status |= sat
    yw_l, sat = fx.saturate(ki.d1_l - pz - off_y_l, ki)
    return xw_l, yw_l, status | sat


def _elbow(fx, fw, xw_l, yw_l, complements: bool, ki: Constants):
    """Elbow: law of cosines, clipped to the reachable annulus; c3 = cos q3 by one constant
    multiply, or (``complements``: the config has internal guard bits) 1 -+ c3 by two. Returns
    (elbow_a >= 0, c3_u, s3_u, status).

    xw^2 + yw^2 reaches 2**(2 width - 1) (xw = yw = word_min): summed exactly as
    (xw^2 - links_sq) + yw^2 (the C subtracts first, in 128 bits; in int64 for the word formats
    xw^2 - links_sq is in (-2**56, 2**62], + yw^2 <= 2**62 stays < 2**63 - links_sq). Beyond the
    annulus by more than the reach tolerance: unreachable; within it: clipped only (a straight or
    folded elbow, flagged singular).
    """
    nearest = ki.cfg.round_nearest
    num_l2 = fx.exact_add(fx.exact_sub(fx.exact_mul(xw_l, xw_l, ki), fx.exact_const(ki.links_sq_l2, ki)),
                          fx.exact_mul(yw_l, yw_l, ki))
    reach = fx.exact_const(ki.reach_limit_l2, ki)
    out_of_reach = (fx.exact_less(reach, num_l2)
                    | fx.exact_less(num_l2, fx.exact_sub(fx.exact_const(0, ki), reach)))
    twice = fx.exact_const(ki.twice_a2a3_l2, ki)
    num_l2 = fx.exact_clip(num_l2, twice)
    if not complements:
        # |num_l2| <= twice_a2a3_l2: rshift by pre < 2**31 (ConstMul contract), product < 2**62.
        c3_u = fx.clip(fx.mul_const(num_l2, ki.c3_from_l2, nearest), -ki.one_u, ki.one_u)
        elbow_a, s3_u, _ = fw.cordic_acos(c3_u, ki)
    else:
        # 1 - c3 = (2 a2 a3 - num) / (2 a2 a3) and 1 + c3 = (2 a2 a3 + num) / (2 a2 a3) straight
        # from the law of cosines: near the straight (folded) elbow 1 - c3 (1 + c3) is small and
        # keeps its relative precision, which 1 - c3 formed from a rounded c3 would not.
        two_u = 2 * ki.one_u
        complement = ki.c3_complement_from_l2
        one_minus_c3_u = fx.minimum(two_u, fx.mul_const(fx.exact_sub(twice, num_l2), complement, nearest))
        one_plus_c3_u = fx.minimum(two_u, fx.mul_const(fx.exact_add(twice, num_l2), complement, nearest))
        c3_u = ki.one_u - one_minus_c3_u
        elbow_a, s3_u = fw.acos_of_complements(one_minus_c3_u, one_plus_c3_u, ki)
    status = fx.flag(out_of_reach, UNREACHABLE) | fx.flag(s3_u <= ki.singular_s3_u, SINGULAR_ELBOW)
    return elbow_a, c3_u, s3_u, status


def _shoulder(fx, fw, xw_l, yw_l, c3_u, s3_u, down, ki: Constants):
    """q2 = atan2(yw, xw) -+ atan2(a3 sin|q3|, a2 + a3 cos q3).

    Words: s3_u, |c3_u| <= one_u = 2**30 < 2**31 (a3_from_u.pre = 0): products < 2**61.3."""
    nearest = ki.cfg.round_nearest
    gamma_a = fw.atan2_angle(yw_l, xw_l, ki)[0]
    beta_a = fw.atan2_angle(fx.mul_const(s3_u, ki.a3_from_u, nearest),
                            ki.a2_l + fx.mul_const(c3_u, ki.a3_from_u, nearest), ki)[0]
    return fx.wrap_angle(fx.select(down, gamma_a + beta_a, gamma_a - beta_a), ki)


def _joint5(fx, fw, n_u, o_u, a_u, c1_u, s1_u, roll, k: Constants):
    """Tool roll from n and o (input words) where ``roll``. Returns (q5_a, status); where not roll
    q5_a is meaningless and status 0 (the caller takes its default).

    Words: as the pitch's a_radial, < 2**61.6. A batch computes every element (rows without n, o
    carry zeros) and masks the flags."""
    ki = k.internal
    guard = k.cfg.internal_guard_bits
    nearest = k.cfg.round_nearest
    fu = ki.cfg.frac_unit
    nx, ny = (v << guard for v in n_u[:2])
    ox, oy = (v << guard for v in o_u[:2])
    s5_u, sat_s = fx.saturate(fx.dot_round(nx, s1_u, -ny, c1_u, fu, nearest, ki), ki)
    c5_u, sat_c = fx.saturate(fx.dot_round(ox, s1_u, -oy, c1_u, fu, nearest, ki), ki)
    q5_a, no_roll = fw.atan2_angle(s5_u, c5_u, ki)
    status = sat_s | sat_c | fx.flag(no_roll, INVALID)
    status |= fx.flag(frame_is_bad(n_u, o_u, a_u, k), BAD_ORIENTATION)
    return q5_a, fx.select(roll, status, 0)


def solve(fx, fw, k: Constants, p_l, a_u, n_u, o_u, roll, back, down, q5_default_a):
    """The fixed-point IK for one branch: ((q1..q5) angle words, status bits).

    p_l, a_u, n_u, o_u: three input words each (position in the length format, approach, n, o in
    the unit format); roll: n and o are given (else q5 = q5_default_a); back: the tool point
    behind joint 1 (q1 + pi); down: q3 = -acos(c3) instead of +acos(c3).
    """
    ki = k.internal           # the format the IK runs on (k itself without internal guard bits)
    guard = k.cfg.internal_guard_bits
    # Input words to internal words: exact (guard more fraction bits, the same real range).
    px, py, pz = (v << guard for v in p_l)
    ax, ay, az = (v << guard for v in a_u)

    q1_a, r_l, c1_u, s1_u, status = _joint1(fx, fw, px, py, ax, ay, back, guard, ki)
    phi_a, sat = _pitch(fx, fw, ax, ay, az, c1_u, s1_u, ki)
    status |= sat
    xw_l, yw_l, sat = _wrist(fx, fw, r_l, pz, phi_a, ki)
    status |= sat
    elbow_a, c3_u, s3_u, sat = _elbow(fx, fw, xw_l, yw_l, guard > 0, ki)
    status |= sat
    q3_a = fx.select(down, -elbow_a, elbow_a)
    q2_a = _shoulder(fx, fw, xw_l, yw_l, c3_u, s3_u, down, ki)
    q4_a = fx.wrap_angle(fx.wrap_angle(phi_a - q2_a, ki) - q3_a, ki)
    q5_a = q5_default_a << guard
    if fx.any_of(roll):
        q5_roll_a, sat = _joint5(fx, fw, n_u, o_u, a_u, c1_u, s1_u, roll, k)
        q5_a = fx.select(roll, q5_roll_a, q5_a)
        status |= sat

    return _output(fx, (q1_a, q2_a, q3_a, q4_a, q5_a), status, k)


def _output(fx, angles, status, k: Constants):
    """Joint angles to the arm's readings as words: offset removed (and, for a joint whose sense
    is reversed, the difference taken the other way round: q = offset - theta), rounded and
    saturated (the last overflow check); then OUT_OF_LIMITS where a reading passes a limit. A
    side of a limit at +-pi or beyond is no check at all (``Constants.limit_lo_a`` holds
    word_min there), so an arm with no limits gets no compare in any layer."""
    ki, guard = k.internal, k.cfg.internal_guard_bits
    joints = []
    for j, (q, off) in enumerate(zip(angles, ki.offset_a)):
        turned = q - off if k.sense[j] > 0 else off - q
        joint_a, sat = fx.saturate(fx.rshift_round(fx.wrap_angle(turned, ki), guard, k.cfg.round_nearest), k)
        joints.append(joint_a)
        status |= sat
        if k.limit_lo_a[j] != k.word_min:
            status |= fx.flag(joint_a < k.limit_lo_a[j], OUT_OF_LIMITS)
        if k.limit_hi_a[j] != k.word_max:
            status |= fx.flag(joint_a > k.limit_hi_a[j], OUT_OF_LIMITS)
    return joints, status
