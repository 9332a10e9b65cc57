/* ik5r.c -- integer-only inverse kinematics of the 5R arm (Nios-style C99).
 *
 * Every static function mirrors the function of the same name in firmware_model/model.py (the
 * specification) one to one and computes exactly what it computes, bit for bit, for the config
 * and arm of the generated "ik5r_config.h". C99, <stdint.h>/<stddef.h> only: no float, no libm,
 * no division, no malloc.
 *
 * Types: word values (inputs, saturated results, angles) are int32_t; every sum and product is
 * formed in int64_t (32x32->64 multiply: both operands are converted to int64_t first), as is the
 * CORDIC x/y/z state; the sum of squares px^2 + py^2 (up to 2^63) is uint64_t and
 * xw^2 + yw^2 - links_sq is summed in the model's order (xw^2 - links_sq) + yw^2 in int64_t.
 * Bounds (widest config, width 32, frac.unit 30, 4 guard bits): atan2 x/y state < 2^37,
 * magnitude product < 2^62.6, rotate state < 2^36, z < 2^39 (any config), mul_const products
 * checked by the generator (ik5r.firmware.codegen.check_bounds).
 *
 * Undefined behaviour avoided by construction:
 *  - no signed overflow: -x of a word is taken in int64_t; px^2 + py^2 in uint64_t;
 *  - no left shift of a negative value: value * 2^n is written as value * ((int64_t)1 << n),
 *    which is exact for every value here (bounds above) -- see rshift_round();
 *  - no shift by >= the width: every shift count is < 63 (table index < 40, shifts <= 62).
 * Implementation-defined behaviour relied on:
 *  - >> of a negative int32_t/int64_t is an arithmetic shift, i.e. floor(v / 2^n) like Python's
 *    >> (gcc, clang and Nios II gcc all do this): checked at compile time (IK5R_STATIC_ASSERT) and
 *    at start-up (ik5r_self_check);
 *  - conversions int64_t -> int32_t happen only in narrow(), for values proven to be words
 *    (trap in builds with -DIK5R_CHECK_BOUNDS, used by the sanitizer test).
 * See docs/algorithm.md, "C semantics relied on".
 */
#define IK5R_DEFINE_TABLES
#include "ik5r.h"

/* ---- compile-time checks ---------------------------------------------------------------- */

#define IK5R_STATIC_ASSERT(name, cond) typedef char ik5r_static_assert_##name[(cond) ? 1 : -1]

/* Arithmetic (flooring) right shift of negative values, in int and in int64_t. */
IK5R_STATIC_ASSERT(asr_int, (-5 >> 1) == -3 && (-1 >> 7) == -1);
IK5R_STATIC_ASSERT(asr_int64, ((int64_t)-5 >> 1) == -3 && (INT64_C(-1) >> 62) == -1
                   && ((-(INT64_C(1) << 40) - 1) >> 40) == -2);
/* The config fits the int32_t words and int64_t datapath this file is written for. */
IK5R_STATIC_ASSERT(width, IK5R_WIDTH >= 8 && IK5R_WIDTH <= 32);
IK5R_STATIC_ASSERT(iterations, IK5R_ITERATIONS == IK5R_ATAN_TABLE_LEN && IK5R_ITERATIONS <= 40);
IK5R_STATIC_ASSERT(guard, IK5R_GUARD_BITS >= 0 && IK5R_GUARD_BITS <= 8 && IK5R_ANGLE_GUARD_BITS >= 0
                   && IK5R_ANGLE_GUARD_BITS <= 8 && IK5R_INV_GAIN_FRAC > IK5R_GUARD_BITS);
IK5R_STATIC_ASSERT(unit, 2 * IK5R_FRAC_UNIT + 2 <= 64 && IK5R_ONE_U <= IK5R_WORD_MAX);
IK5R_STATIC_ASSERT(word, IK5R_WORD_MAX == (INT64_C(1) << (IK5R_WIDTH - 1)) - 1
                   && IK5R_WORD_MIN == -IK5R_WORD_MAX - 1);
IK5R_STATIC_ASSERT(offsets, IK5R_OFFSET_A_LEN == 5);

typedef struct {
    int pre;      /* right shift of the operand (rounded) */
    int64_t mant; /* signed mantissa, |mant| < 2^IK5R_CONST_MANT_BITS */
    int post;     /* right shift of the product (rounded) */
} const_mul_t;

static const const_mul_t c3_from_l2 = {IK5R_C3_FROM_L2_PRE, IK5R_C3_FROM_L2_MANT, IK5R_C3_FROM_L2_POST};
static const const_mul_t a3_from_u = {IK5R_A3_FROM_U_PRE, IK5R_A3_FROM_U_MANT, IK5R_A3_FROM_U_POST};

/* ---- helpers ------------------------------------------------------------------------------ */

/* An int64_t known to be a word, as an int32_t (the only narrowing conversion of the file). */
static int32_t narrow(int64_t value)
{
#ifdef IK5R_CHECK_BOUNDS
    if (value < INT32_MIN || value > INT32_MAX)
        __builtin_trap();
#endif
    return (int32_t)value;
}

/* 2^shift as int64_t, 0 <= shift <= 62. */
static int64_t pow2(int shift)
{
    return (int64_t)1 << shift;
}

/* ---- model.py, one function each ---------------------------------------------------------- */

/* value * 2^-shift, rounded half up (nearest) or floored (truncate). shift <= 0 is a left shift,
 * written as a multiplication (a left shift of a negative value is undefined in C99). */
static int64_t rshift_round(int64_t value, int shift, int nearest)
{
    if (shift <= 0)
        return value * pow2(-shift);
    if (nearest)
        value += pow2(shift - 1);
    return value >> shift; /* arithmetic shift: floor */
}

/* Clip to the word range; ORs IK5R_STATUS_SATURATED into *status when clipped. */
static int32_t saturate(int64_t value, uint32_t *status)
{
    if (value > IK5R_WORD_MAX) {
        *status |= IK5R_STATUS_SATURATED;
        return narrow(IK5R_WORD_MAX);
    }
    if (value < IK5R_WORD_MIN) {
        *status |= IK5R_STATUS_SATURATED;
        return narrow(IK5R_WORD_MIN);
    }
    return narrow(value);
}

/* value * c for a constant multiplier m (pre-shift, 31-bit mantissa, post-shift). */
static int64_t mul_const(int64_t value, const const_mul_t *m, int nearest)
{
    return rshift_round(rshift_round(value, m->pre, nearest) * m->mant, m->post, nearest);
}

/* Bring an angle within one turn of zero back to [-pi, pi] (one correction). */
static int64_t wrap_angle(int64_t angle_a)
{
    if (angle_a > IK5R_PI_A)
        return angle_a - 2 * IK5R_PI_A;
    if (angle_a < -IK5R_PI_A)
        return angle_a + 2 * IK5R_PI_A;
    return angle_a;
}

/* The angle of the opposite vector: atan2(-y, -x) from atan2(y, x), with no negation of a word. */
static int64_t opposite(int64_t angle_a)
{
    return angle_a > 0 ? angle_a - IK5R_PI_A : angle_a + IK5R_PI_A;
}

/* Bit length of an unsigned value (0 for 0). */
static int bit_length(uint64_t v)
{
    int n = 0;
    if (v >> 32) { v >>= 32; n += 32; }
    if (v >> 16) { v >>= 16; n += 16; }
    if (v >> 8) { v >>= 8; n += 8; }
    if (v >> 4) { v >>= 4; n += 4; }
    if (v >> 2) { v >>= 2; n += 2; }
    if (v >> 1) { v >>= 1; n += 1; }
    return n + (int)v;
}

/* Bit length of x | ones'-complement-abs(y), x >= 0: what the HDL's priority encoder sees.
 * ones'-complement-abs(y) = ~y = -(y + 1) for y < 0 (no overflow: y + 1 <= 0). */
static int bit_length_ones_abs(int64_t x, int64_t y)
{
    uint64_t ones_abs_y = (uint64_t)(y < 0 ? -(y + 1) : y);
    return bit_length((uint64_t)x | ones_abs_y);
}

/* Full-circle atan2 of two words by CORDIC vectoring: *angle_a, *magnitude (inputs' format,
 * saturated); returns 1 (zero) when x == y == 0, with angle and magnitude 0. */
static int cordic_atan2(int32_t y, int32_t x, int32_t *angle_a, int32_t *magnitude)
{
    int64_t xs, ys, z, xn;
    uint32_t unused = 0;
    int norm, i;

    if (x == 0 && y == 0) {
        *angle_a = 0;
        *magnitude = 0;
        return 1;
    }
    /* Coarse rotation by -+90 degrees into the right half-plane (widens by one bit: int64). */
    if (x < 0) {
        if (y >= 0) {
            xs = y;
            ys = -(int64_t)x;
            z = IK5R_HALF_PI_Z;
        } else {
            xs = -(int64_t)y;
            ys = x;
            z = -IK5R_HALF_PI_Z;
        }
    } else {
        xs = x;
        ys = y;
        z = 0;
    }
    /* Normalise: largest component's top bit to bit width-2 (block floating point). */
    norm = IK5R_WIDTH - 1 - bit_length_ones_abs(xs, ys);
    if (norm < 0)
        norm = 0;
    xs *= pow2(norm + IK5R_GUARD_BITS); /* xs << (norm + guard), ys may be negative */
    ys *= pow2(norm + IK5R_GUARD_BITS);
    for (i = 0; i < IK5R_ITERATIONS; i++) {
        if (ys >= 0) {
            xn = xs + (ys >> i);
            ys = ys - (xs >> i);
            z += ik5r_atan_table[i];
        } else {
            xn = xs - (ys >> i);
            ys = ys + (xs >> i);
            z -= ik5r_atan_table[i];
        }
        xs = xn;
    }
    *angle_a = narrow(rshift_round(z, IK5R_ANGLE_GUARD_BITS, IK5R_ROUND_NEAREST));
    /* Magnitude: drop the guard bits, undo the gain K, then undo the normalisation. */
    *magnitude = saturate(rshift_round((xs >> IK5R_GUARD_BITS) * IK5R_INV_GAIN,
                                       IK5R_INV_GAIN_FRAC + norm, IK5R_ROUND_NEAREST),
                          &unused);
    return 0;
}

/* Rotate the vector (x, y) of words by angle_a (|angle_a| <= pi + a few LSB). The CORDIC gain is
 * compensated on the input. Writes (x', y'); returns IK5R_STATUS_SATURATED or 0. */
static uint32_t cordic_rotate(int32_t x, int32_t y, int32_t angle_a, int32_t *x_out, int32_t *y_out)
{
    int64_t xv = x, yv = y, t, xs, ys, xn;
    int64_t z = (int64_t)angle_a * pow2(IK5R_ANGLE_GUARD_BITS); /* angle_a << angle_guard */
    uint32_t sat = 0;
    int i;

    if (z > IK5R_HALF_PI_Z) {
        t = xv;
        xv = -yv;
        yv = t;
        z -= IK5R_HALF_PI_Z;
    } else if (z < -IK5R_HALF_PI_Z) {
        t = xv;
        xv = yv;
        yv = -t;
        z += IK5R_HALF_PI_Z;
    }
    xs = rshift_round(xv * IK5R_INV_GAIN, IK5R_INV_GAIN_FRAC - IK5R_GUARD_BITS, IK5R_ROUND_NEAREST);
    ys = rshift_round(yv * IK5R_INV_GAIN, IK5R_INV_GAIN_FRAC - IK5R_GUARD_BITS, IK5R_ROUND_NEAREST);
    for (i = 0; i < IK5R_ITERATIONS; i++) {
        if (z >= 0) {
            xn = xs - (ys >> i);
            ys = ys + (xs >> i);
            z -= ik5r_atan_table[i];
        } else {
            xn = xs + (ys >> i);
            ys = ys - (xs >> i);
            z += ik5r_atan_table[i];
        }
        xs = xn;
    }
    *x_out = saturate(rshift_round(xs, IK5R_GUARD_BITS, IK5R_ROUND_NEAREST), &sat);
    *y_out = saturate(rshift_round(ys, IK5R_GUARD_BITS, IK5R_ROUND_NEAREST), &sat);
    return sat;
}

/* Square root of an unsigned integer below 2^bits by digit recurrence (bits even, <= 64).
 * root < 2^32 + 1 and rem <= 2 root, so rem << 2 < 2^35: no wrap-around. */
static uint64_t isqrt(uint64_t radicand, int bits, int nearest)
{
    uint64_t root = 0, rem = 0, trial;
    int i;

    for (i = (bits >> 1) - 1; i >= 0; i--) { /* bits >> 1 == bits // 2 for bits >= 0 */
        rem = (rem << 2) | ((radicand >> (2 * i)) & 3u);
        trial = (root << 2) | 1u;
        root <<= 1;
        if (rem >= trial) {
            rem -= trial;
            root |= 1u;
        }
    }
    if (nearest && rem > root)
        root += 1;
    return root;
}

/* Square root of a non-negative word with frac fraction bits, same format. The radicand
 * x << frac is formed in uint64_t: for x >= 0 it is exact; a negative x becomes its two's
 * complement modulo 2^64, of which isqrt reads only the low bits -- the model's result too. */
static int64_t sqrt_word(int32_t x, int frac)
{
    int bits = IK5R_WIDTH + frac + ((IK5R_WIDTH + frac) & 1);
    uint64_t radicand = (uint64_t)(int64_t)x << frac;
    return (int64_t)isqrt(radicand, bits, IK5R_ROUND_NEAREST);
}

/* acos of a unit-format word as atan2(sqrt((1 - x)(1 + x)), x). Input outside [-1, 1] is
 * clipped and flagged. Writes angle_a and sine_u = sin(angle) >= 0; returns the flags. */
static uint32_t cordic_acos(int32_t x_u, int32_t *angle_a, int32_t *sine_u)
{
    int64_t x = x_u;
    uint32_t flags = 0;
    int64_t product_u2;
    int32_t unused;

    if (x > IK5R_ONE_U) {
        x = IK5R_ONE_U;
        flags = IK5R_STATUS_SATURATED;
    } else if (x < -IK5R_ONE_U) {
        x = -IK5R_ONE_U;
        flags = IK5R_STATUS_SATURATED;
    }
    /* (1 - x)(1 + x) is in [0, 1] with 2*frac_unit fraction bits: below 2^(2*frac_unit + 1). */
    product_u2 = (IK5R_ONE_U - x) * (IK5R_ONE_U + x);
    *sine_u = narrow((int64_t)isqrt((uint64_t)product_u2, 2 * IK5R_FRAC_UNIT + 2, IK5R_ROUND_NEAREST));
    (void)cordic_atan2(*sine_u, narrow(x), angle_a, &unused);
    return flags;
}

/* The fixed-point IK of one pose for one branch: q_a[5] and the status bits. n_u, o_u NULL:
 * q5 = q5_default_a (the model's Pose with n = o = None). */
static uint32_t ik_solve(const int32_t p_l[3], const int32_t a_u[3], const int32_t *n_u,
                         const int32_t *o_u, int shoulder_back, int elbow_down,
                         int32_t q5_default_a, int32_t q_a[5])
{
    const int nearest = IK5R_ROUND_NEAREST;
    uint32_t status = 0;
    const int64_t px = p_l[0], py = p_l[1], pz = p_l[2];
    const int64_t ax = a_u[0], ay = a_u[1], az = a_u[2];
    int32_t rho_l, theta1_a, q1_a, c1_u, s1_u, a_radial_u, pitch_a, phi_a, off_x_l, off_y_l;
    int32_t xw_l, yw_l, c3_u, elbow_a, s3_u, gamma_a, beta_a, q5_a, unused;
    int64_t r_l, num_l2, q2_a, q3_a, q4_a;
    uint64_t rho_sq_l2;
    int64_t joints[5];
    int i;

    /* Joint 1: the arm's plane contains the tool point, or the approach if the point is on
     * the axis. px^2 + py^2 <= 2^63: uint64_t. */
    rho_sq_l2 = (uint64_t)(px * px) + (uint64_t)(py * py);
    rho_l = saturate((int64_t)isqrt(rho_sq_l2, 64, nearest), &status);
    if (rho_l != 0) {
        (void)cordic_atan2(narrow(py), narrow(px), &theta1_a, &unused);
    } else if (cordic_atan2(narrow(ay), narrow(ax), &theta1_a, &unused)) {
        status |= IK5R_STATUS_SINGULAR_BASE; /* vertical approach on the axis: q1 free */
    }
    if (shoulder_back) {
        q1_a = narrow(opposite(theta1_a));
        r_l = -(int64_t)rho_l;
    } else {
        q1_a = theta1_a;
        r_l = rho_l;
    }
    status |= cordic_rotate(narrow(IK5R_ONE_U), 0, q1_a, &c1_u, &s1_u);

    /* Tool pitch phi = q2 + q3 + q4 from the approach projected onto the arm's plane. */
    a_radial_u = saturate(rshift_round(ax * c1_u + ay * s1_u, IK5R_FRAC_UNIT, nearest), &status);
    if (cordic_atan2(a_radial_u, narrow(az), &pitch_a, &unused))
        status |= IK5R_STATUS_INVALID;
    phi_a = narrow(opposite(pitch_a));

    /* Wrist centre (joint 4 axis) in the arm's plane: subtract R(phi) (a4, d5). */
    status |= cordic_rotate(narrow(IK5R_A4_L), narrow(IK5R_D5_L), phi_a, &off_x_l, &off_y_l);
    xw_l = saturate(r_l - IK5R_A1_L - off_x_l, &status);
    yw_l = saturate(IK5R_D1_L - pz - off_y_l, &status);

    /* Elbow: law of cosines, clipped to the reachable annulus. xw^2 + yw^2 reaches 2^63
     * (xw = yw = word_min), one past int64_t: subtract first, as the model does. xw^2 - links
     * is in [-links_sq_l2, 2^62], so num_l2 <= 2^63 - links_sq_l2 fits int64_t
     * (1 <= links_sq_l2 < 2^63 is checked by the generator). */
    num_l2 = ((int64_t)xw_l * xw_l - IK5R_LINKS_SQ_L2) + (int64_t)yw_l * yw_l;
    if (num_l2 > IK5R_TWICE_A2A3_L2) {
        num_l2 = IK5R_TWICE_A2A3_L2;
        status |= IK5R_STATUS_UNREACHABLE;
    } else if (num_l2 < -IK5R_TWICE_A2A3_L2) {
        num_l2 = -IK5R_TWICE_A2A3_L2;
        status |= IK5R_STATUS_UNREACHABLE;
    }
    {
        int64_t c3 = mul_const(num_l2, &c3_from_l2, nearest);
        c3_u = narrow(c3 > IK5R_ONE_U ? IK5R_ONE_U : c3 < -IK5R_ONE_U ? -IK5R_ONE_U : c3);
    }
    (void)cordic_acos(c3_u, &elbow_a, &s3_u);
    if (s3_u <= IK5R_SINGULAR_S3_U)
        status |= IK5R_STATUS_SINGULAR_ELBOW;
    q3_a = elbow_down ? -(int64_t)elbow_a : (int64_t)elbow_a;

    /* Shoulder: q2 = atan2(yw, xw) -+ atan2(a3 sin|q3|, a2 + a3 cos q3). */
    (void)cordic_atan2(yw_l, xw_l, &gamma_a, &unused);
    (void)cordic_atan2(narrow(mul_const(s3_u, &a3_from_u, nearest)),
                       narrow(IK5R_A2_L + mul_const(c3_u, &a3_from_u, nearest)), &beta_a, &unused);
    q2_a = wrap_angle(elbow_down ? (int64_t)gamma_a + beta_a : (int64_t)gamma_a - beta_a);
    q4_a = wrap_angle(wrap_angle(phi_a - q2_a) - q3_a);

    /* Joint 5: tool roll from n and o, else the caller's value. */
    if (n_u != NULL && o_u != NULL) {
        const int64_t nx = n_u[0], ny = n_u[1], ox = o_u[0], oy = o_u[1];
        int32_t s5_u = saturate(rshift_round(nx * s1_u - ny * c1_u, IK5R_FRAC_UNIT, nearest), &status);
        int32_t c5_u = saturate(rshift_round(ox * s1_u - oy * c1_u, IK5R_FRAC_UNIT, nearest), &status);
        if (cordic_atan2(s5_u, c5_u, &q5_a, &unused))
            status |= IK5R_STATUS_INVALID;
    } else {
        q5_a = q5_default_a;
    }

    joints[0] = q1_a;
    joints[1] = q2_a;
    joints[2] = q3_a;
    joints[3] = q4_a;
    joints[4] = q5_a;
    for (i = 0; i < 5; i++)
        q_a[i] = narrow(wrap_angle(joints[i] - ik5r_offset_a[i]));
    return status;
}

/* ---- public API --------------------------------------------------------------------------- */

int ik5r_self_check(void)
{
    volatile int64_t m5 = -5;
    volatile int32_t m7 = -7;
    volatile int32_t most_negative = INT32_MIN;
    volatile int64_t big_negative = -(INT64_C(1) << 40) - 1;

    if ((m5 >> 1) != -3)
        return 1; /* int64_t >> is not arithmetic */
    if ((m7 >> 2) != -2)
        return 2; /* int32_t >> is not arithmetic */
    if ((big_negative >> 40) != -2)
        return 3;
    if ((int64_t)most_negative * most_negative != INT64_C(1) << 62)
        return 4; /* 32x32->64 multiply */
    if (isqrt(UINT64_C(1) << 62, 64, 0) != UINT64_C(1) << 31)
        return 5;
    return 0;
}

const char *ik5r_config_name(void)
{
    return IK5R_CONFIG_NAME;
}

uint32_t ik5r_solve(const int32_t p_l[3], const int32_t a_u[3], const int32_t n_u[3],
                    const int32_t o_u[3], int has_roll, int shoulder_back, int elbow_down,
                    int32_t q5_default_a, int32_t q_a[5])
{
    return ik_solve(p_l, a_u, has_roll ? n_u : NULL, has_roll ? o_u : NULL, shoulder_back,
                    elbow_down, q5_default_a, q_a);
}

void ik5r_solve_batch(size_t count, const int32_t *p_l, const int32_t *a_u, const int32_t *n_u,
                      const int32_t *o_u, const uint8_t *has_roll, const uint8_t *shoulder_back,
                      const uint8_t *elbow_down, const int32_t *q5_default_a, int32_t *q_a,
                      uint32_t *status)
{
    size_t i;
    for (i = 0; i < count; i++)
        status[i] = ik5r_solve(p_l + 3 * i, a_u + 3 * i, n_u != NULL ? n_u + 3 * i : NULL,
                               o_u != NULL ? o_u + 3 * i : NULL, has_roll[i], shoulder_back[i],
                               elbow_down[i], q5_default_a[i], q_a + 5 * i);
}

int ik5r_atan2(int32_t y, int32_t x, int32_t *angle_a, int32_t *magnitude)
{
    return cordic_atan2(y, x, angle_a, magnitude);
}

uint32_t ik5r_rotate(int32_t x, int32_t y, int32_t angle_a, int32_t *x_out, int32_t *y_out)
{
    return cordic_rotate(x, y, angle_a, x_out, y_out);
}

uint32_t ik5r_acos(int32_t x_u, int32_t *angle_a, int32_t *sine_u)
{
    return cordic_acos(x_u, angle_a, sine_u);
}

int64_t ik5r_sqrt_word(int32_t x, int frac)
{
    if (frac < 0 || frac > 64 - IK5R_WIDTH - 1)
        return -1;
    return sqrt_word(x, frac);
}

uint64_t ik5r_isqrt64(uint64_t radicand, int bits, int nearest)
{
    if (bits < 0 || bits > 64)
        return UINT64_MAX;
    return isqrt(radicand, bits, nearest);
}

#ifndef IK5R_NO_BATCH_API
void ik5r_atan2_batch(size_t count, const int32_t *y, const int32_t *x, int32_t *angle_a,
                      int32_t *magnitude, uint8_t *zero)
{
    size_t i;
    for (i = 0; i < count; i++)
        zero[i] = (uint8_t)cordic_atan2(y[i], x[i], angle_a + i, magnitude + i);
}

void ik5r_rotate_batch(size_t count, const int32_t *x, const int32_t *y, const int32_t *angle_a,
                       int32_t *x_out, int32_t *y_out, uint32_t *flags)
{
    size_t i;
    for (i = 0; i < count; i++)
        flags[i] = cordic_rotate(x[i], y[i], angle_a[i], x_out + i, y_out + i);
}

void ik5r_acos_batch(size_t count, const int32_t *x_u, int32_t *angle_a, int32_t *sine_u,
                     uint32_t *flags)
{
    size_t i;
    for (i = 0; i < count; i++)
        flags[i] = cordic_acos(x_u[i], angle_a + i, sine_u + i);
}

void ik5r_sqrt_word_batch(size_t count, const int32_t *x, const int32_t *frac, int64_t *root)
{
    size_t i;
    for (i = 0; i < count; i++)
        root[i] = ik5r_sqrt_word(x[i], frac[i]);
}

void ik5r_isqrt64_batch(size_t count, const uint64_t *radicand, const int32_t *bits,
                        const uint8_t *nearest, uint64_t *root)
{
    size_t i;
    for (i = 0; i < count; i++)
        root[i] = ik5r_isqrt64(radicand[i], bits[i], nearest[i]);
}
#endif
