/* ik5r.c -- integer-only inverse kinematics of the 5R arm (Nios-style C99).
 *
 * Every static function mirrors the function of the same name in firmware/model.py (the
 * specification) one to one and computes exactly what it computes, bit for bit, for the config
 * and arm of the generated "ik5r_config.h". C99, <stdint.h>/<stddef.h> only: no float, no libm,
 * no division, no malloc, no 128-bit compiler types (Nios II is a 32-bit target).
 *
 * Two formats (format_t): the config's words (IK5R_*, at most 32 bits), on which the exported
 * building blocks work, and the internal format the IK runs on (IK5R_IK_*: IK5R_INTERNAL_GUARD_BITS
 * more fraction bits in every quantity, at most 40-bit words; the word format itself when that is
 * 0). Types: words of either format and the CORDIC x/y/z state are int64_t (state < 2^50); every
 * product of two values is formed exactly in 128 bits (wide_t, two uint64_t halves of a two's
 * complement value, built from 32x32->64 limb products), as are sums of such products; squares
 * of lengths (Q(2 frac.length)) are wide_t. The public API takes and returns int32_t words.
 * Bounds are checked per config by the generator (ik5r.firmware.codegen.check_bounds).
 *
 * Undefined behaviour avoided by construction:
 *  - no signed overflow: int64_t values stay below 2^50 except products, which are wide_t; the
 *    128-bit arithmetic is done on unsigned halves (modular, well defined);
 *  - no left shift of a negative value: value * 2^n is written as value * ((int64_t)1 << n),
 *    which is exact for every value here -- see rshift_round();
 *  - no shift by >= the width: every shift count of a 64-bit value is in [0, 63].
 * Implementation-defined behaviour relied on:
 *  - >> of a negative int32_t/int64_t is an arithmetic shift, i.e. floor(v / 2^n) like Python's
 *    >> (gcc, clang and Nios II gcc all do this): checked at compile time (IK5R_STATIC_ASSERT) and
 *    at start-up (ik5r_self_check);
 *  - conversions int64_t -> int32_t happen only in narrow(), for values proven to be words
 *    (trap in builds with -DIK5R_CHECK_BOUNDS, used by the sanitizer test). uint64_t -> int64_t
 *    happens only in to_int64(), which never converts a value above INT64_MAX.
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
/* The config fits the int32_t words, int64_t state and 128-bit products this file is written for. */
IK5R_STATIC_ASSERT(width, IK5R_WIDTH >= 8 && IK5R_WIDTH <= 32);
IK5R_STATIC_ASSERT(ik_width, IK5R_IK_WIDTH == IK5R_WIDTH + IK5R_INTERNAL_GUARD_BITS && IK5R_IK_WIDTH <= 40);
IK5R_STATIC_ASSERT(iterations, IK5R_ITERATIONS == IK5R_ATAN_TABLE_LEN && IK5R_ITERATIONS <= 40
                   && IK5R_IK_ITERATIONS == IK5R_IK_ATAN_TABLE_LEN && IK5R_IK_ITERATIONS <= 48);
IK5R_STATIC_ASSERT(guard, IK5R_GUARD_BITS >= 0 && IK5R_GUARD_BITS <= 8 && IK5R_ANGLE_GUARD_BITS >= 0
                   && IK5R_ANGLE_GUARD_BITS <= 8 && IK5R_INV_GAIN_FRAC > IK5R_GUARD_BITS
                   && IK5R_IK_GUARD_BITS == IK5R_GUARD_BITS
                   && IK5R_IK_ANGLE_GUARD_BITS == IK5R_ANGLE_GUARD_BITS);
IK5R_STATIC_ASSERT(unit, 2 * IK5R_FRAC_UNIT + 4 <= 64 && IK5R_ONE_U <= IK5R_WORD_MAX
                   && IK5R_IK_ONE_U <= IK5R_IK_WORD_MAX);
IK5R_STATIC_ASSERT(word, IK5R_WORD_MAX == (INT64_C(1) << (IK5R_WIDTH - 1)) - 1
                   && IK5R_WORD_MIN == -IK5R_WORD_MAX - 1
                   && IK5R_IK_WORD_MAX == (INT64_C(1) << (IK5R_IK_WIDTH - 1)) - 1
                   && IK5R_IK_WORD_MIN == -IK5R_IK_WORD_MAX - 1);
IK5R_STATIC_ASSERT(offsets, IK5R_IK_OFFSET_A_LEN == 5 && IK5R_IK_SENSE_LEN == 5 && IK5R_LIMIT_LO_A_LEN == 5
                   && IK5R_LIMIT_HI_A_LEN == 5);

/* ---- 128-bit integers --------------------------------------------------------------------- */

/* The two's complement 128-bit integer hi * 2^64 + lo (hi read as signed): products of two
 * values of up to 64 bits and their sums. All arithmetic on the halves is unsigned (modular). */
typedef struct {
    uint64_t hi;
    uint64_t lo;
} wide_t;

/* The int64_t whose two's complement is u (C99 leaves (int64_t)u implementation-defined for
 * u > INT64_MAX; here ~u <= INT64_MAX and -(~u) - 1 is the value). */
static int64_t to_int64(uint64_t u)
{
    return u <= (uint64_t)INT64_MAX ? (int64_t)u : -(int64_t)~u - 1;
}

static wide_t wide_from(int64_t value)
{
    wide_t w;
    w.hi = value < 0 ? UINT64_MAX : 0u;
    w.lo = (uint64_t)value; /* modular: the low half of the two's complement */
    return w;
}

/* 2^n, 0 <= n <= 126. */
static wide_t wide_pow2(int n)
{
    wide_t w;
    w.hi = n >= 64 ? UINT64_C(1) << (n - 64) : 0u;
    w.lo = n < 64 ? UINT64_C(1) << n : 0u;
    return w;
}

static wide_t wide_add(wide_t a, wide_t b)
{
    wide_t sum;
    sum.lo = a.lo + b.lo;
    sum.hi = a.hi + b.hi + (sum.lo < a.lo ? 1u : 0u); /* carry out of the low half */
    return sum;
}

static wide_t wide_neg(wide_t a)
{
    wide_t neg;
    neg.lo = 0u - a.lo;
    neg.hi = ~a.hi + (a.lo == 0 ? 1u : 0u);
    return neg;
}

static wide_t wide_sub(wide_t a, wide_t b)
{
    return wide_add(a, wide_neg(b));
}

/* a < b, signed. */
static int wide_less(wide_t a, wide_t b)
{
    const uint64_t sign = UINT64_C(1) << 63;
    if (a.hi != b.hi)
        return (a.hi ^ sign) < (b.hi ^ sign);
    return a.lo < b.lo;
}

/* The exact product a * b: magnitudes multiplied in 32-bit limbs (four 32x32->64 products,
 * mul + mulxuu on Nios II), then the sign. Two int32_t-range operands (every product of the
 * word configs) take one 32x32->64 multiply instead. */
static wide_t wide_mul(int64_t a, int64_t b)
{
    const uint64_t mask = UINT64_C(0xffffffff);
    if (a >= INT32_MIN && a <= INT32_MAX && b >= INT32_MIN && b <= INT32_MAX)
        return wide_from((int64_t)(int32_t)a * (int32_t)b);
    const uint64_t ua = a < 0 ? 0u - (uint64_t)a : (uint64_t)a;
    const uint64_t ub = b < 0 ? 0u - (uint64_t)b : (uint64_t)b;
    const uint64_t a0 = ua & mask, a1 = ua >> 32, b0 = ub & mask, b1 = ub >> 32;
    const uint64_t p00 = a0 * b0, p01 = a0 * b1, p10 = a1 * b0, p11 = a1 * b1;
    const uint64_t mid = (p00 >> 32) + (p01 & mask) + (p10 & mask); /* < 3 * 2^32 */
    wide_t product;
    product.lo = (mid << 32) | (p00 & mask);
    product.hi = p11 + (p01 >> 32) + (p10 >> 32) + (mid >> 32);
    return (a < 0) != (b < 0) ? wide_neg(product) : product;
}

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

/* One format of words: the config's (word_format) or the IK's internal one (ik_format). */
typedef struct {
    int width, frac_unit, iterations, guard_bits, angle_guard_bits, inv_gain_frac;
    int64_t word_min, word_max, one_u, pi_a, half_pi_z, inv_gain;
    const int64_t *atan_table;
} format_t;

static const format_t word_format = {
    IK5R_WIDTH, IK5R_FRAC_UNIT, IK5R_ITERATIONS, IK5R_GUARD_BITS, IK5R_ANGLE_GUARD_BITS,
    IK5R_INV_GAIN_FRAC, IK5R_WORD_MIN, IK5R_WORD_MAX, IK5R_ONE_U, IK5R_PI_A, IK5R_HALF_PI_Z,
    IK5R_INV_GAIN, ik5r_atan_table};

static const format_t ik_format = {
    IK5R_IK_WIDTH, IK5R_IK_FRAC_UNIT, IK5R_IK_ITERATIONS, IK5R_IK_GUARD_BITS,
    IK5R_IK_ANGLE_GUARD_BITS, IK5R_IK_INV_GAIN_FRAC, IK5R_IK_WORD_MIN, IK5R_IK_WORD_MAX,
    IK5R_IK_ONE_U, IK5R_IK_PI_A, IK5R_IK_HALF_PI_Z, IK5R_IK_INV_GAIN, ik5r_ik_atan_table};

typedef struct {
    int pre;      /* right shift of the operand (rounded) */
    int64_t mant; /* signed mantissa, |mant| < 2^IK5R_IK_CONST_MANT_BITS */
    int post;     /* right shift of the product (rounded) */
} const_mul_t;

/* The IK's constants in the internal format (Q(2 frac.length) squares as wide_t). */
static const const_mul_t c3_from_l2 = {IK5R_IK_C3_FROM_L2_PRE, IK5R_IK_C3_FROM_L2_MANT,
                                       IK5R_IK_C3_FROM_L2_POST};
static const const_mul_t c3_complement_from_l2 = {IK5R_IK_C3_COMPLEMENT_FROM_L2_PRE,
                                                  IK5R_IK_C3_COMPLEMENT_FROM_L2_MANT,
                                                  IK5R_IK_C3_COMPLEMENT_FROM_L2_POST};
static const const_mul_t a3_from_u = {IK5R_IK_A3_FROM_U_PRE, IK5R_IK_A3_FROM_U_MANT,
                                      IK5R_IK_A3_FROM_U_POST};
static const wide_t links_sq_l2 = {IK5R_IK_LINKS_SQ_L2_HI, IK5R_IK_LINKS_SQ_L2_LO};
static const wide_t twice_a2a3_l2 = {IK5R_IK_TWICE_A2A3_L2_HI, IK5R_IK_TWICE_A2A3_L2_LO};
static const wide_t reach_limit_l2 = {IK5R_IK_REACH_LIMIT_L2_HI, IK5R_IK_REACH_LIMIT_L2_LO};

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

/* rshift_round of a 128-bit value, 0 <= shift <= 126, whose result is known to fit int64_t. */
static int64_t wide_rshift_round(wide_t value, int shift, int nearest)
{
    if (shift == 0)
        return to_int64(value.lo);
    if (nearest)
        value = wide_add(value, wide_pow2(shift - 1));
    if (shift < 64) /* the 64 bits from bit `shift` up: the result's two's complement */
        return to_int64((value.lo >> shift) | (value.hi << (64 - shift)));
    return to_int64(value.hi) >> (shift - 64); /* arithmetic shift: floor */
}

/* Clip to the word range of format f; ORs IK5R_STATUS_SATURATED into *status when clipped. */
static int64_t saturate(int64_t value, const format_t *f, uint32_t *status)
{
    if (value > f->word_max) {
        *status |= IK5R_STATUS_SATURATED;
        return f->word_max;
    }
    if (value < f->word_min) {
        *status |= IK5R_STATUS_SATURATED;
        return f->word_min;
    }
    return value;
}

/* value * c for a constant multiplier m (pre-shift, mantissa, post-shift; bounds per config in
 * codegen.check_bounds: the pre-shifted operand fits int64_t, the result too). */
static int64_t mul_const(wide_t value, const const_mul_t *m, int nearest)
{
    return wide_rshift_round(wide_mul(wide_rshift_round(value, m->pre, nearest), m->mant), m->post,
                             nearest);
}

/* Bring an angle within one turn of zero back to [-pi, pi] (one correction). */
static int64_t wrap_angle(int64_t angle_a, const format_t *f)
{
    if (angle_a > f->pi_a)
        return angle_a - 2 * f->pi_a;
    if (angle_a < -f->pi_a)
        return angle_a + 2 * f->pi_a;
    return angle_a;
}

/* The angle of the opposite vector: atan2(-y, -x) from atan2(y, x), with no negation of a word. */
static int64_t opposite(int64_t angle_a, const format_t *f)
{
    return angle_a > 0 ? angle_a - f->pi_a : angle_a + f->pi_a;
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

/* Full-circle atan2 of two words of format f by CORDIC vectoring: *angle_a, *magnitude (inputs'
 * format, saturated); returns 1 (zero) when x == y == 0, with angle and magnitude 0.
 * State: |xs|, |ys| < 2^(width + guard + 1), |z| < 2^(frac.angle + angle guard + 2). */
static int cordic_atan2(int64_t y, int64_t x, const format_t *f, int64_t *angle_a, int64_t *magnitude)
{
    int64_t xs, ys, z, xn;
    uint32_t unused = 0;
    int norm, i;

    if (x == 0 && y == 0) {
        *angle_a = 0;
        *magnitude = 0;
        return 1;
    }
    /* Coarse rotation by -+90 degrees into the right half-plane (widens by one bit). */
    if (x < 0) {
        if (y >= 0) {
            xs = y;
            ys = -x;
            z = f->half_pi_z;
        } else {
            xs = -y;
            ys = x;
            z = -f->half_pi_z;
        }
    } else {
        xs = x;
        ys = y;
        z = 0;
    }
    /* Normalise: largest component's top bit to bit width-2 (block floating point). */
    norm = f->width - 1 - bit_length_ones_abs(xs, ys);
    if (norm < 0)
        norm = 0;
    xs *= pow2(norm + f->guard_bits); /* xs << (norm + guard), ys may be negative */
    ys *= pow2(norm + f->guard_bits);
    for (i = 0; i < f->iterations; i++) {
        if (ys >= 0) {
            xn = xs + (ys >> i);
            ys = ys - (xs >> i);
            z += f->atan_table[i];
        } else {
            xn = xs - (ys >> i);
            ys = ys + (xs >> i);
            z -= f->atan_table[i];
        }
        xs = xn;
    }
    *angle_a = rshift_round(z, f->angle_guard_bits, IK5R_ROUND_NEAREST);
    /* Magnitude: drop the guard bits, undo the gain K, then undo the normalisation. */
    *magnitude = saturate(wide_rshift_round(wide_mul(xs >> f->guard_bits, f->inv_gain),
                                            f->inv_gain_frac + norm, IK5R_ROUND_NEAREST),
                          f, &unused);
    return 0;
}

/* Rotate the vector (x, y) of words of format f by angle_a (|angle_a| <= pi + a few LSB). The
 * CORDIC gain is compensated on the input. Writes (x', y'); returns IK5R_STATUS_SATURATED or 0. */
static uint32_t cordic_rotate(int64_t x, int64_t y, int64_t angle_a, const format_t *f,
                              int64_t *x_out, int64_t *y_out)
{
    int64_t xv = x, yv = y, t, xs, ys, xn;
    int64_t z = angle_a * pow2(f->angle_guard_bits); /* angle_a << angle_guard */
    uint32_t sat = 0;
    int i;

    if (z > f->half_pi_z) {
        t = xv;
        xv = -yv;
        yv = t;
        z -= f->half_pi_z;
    } else if (z < -f->half_pi_z) {
        t = xv;
        xv = yv;
        yv = -t;
        z += f->half_pi_z;
    }
    xs = wide_rshift_round(wide_mul(xv, f->inv_gain), f->inv_gain_frac - f->guard_bits, IK5R_ROUND_NEAREST);
    ys = wide_rshift_round(wide_mul(yv, f->inv_gain), f->inv_gain_frac - f->guard_bits, IK5R_ROUND_NEAREST);
    for (i = 0; i < f->iterations; i++) {
        if (z >= 0) {
            xn = xs - (ys >> i);
            ys = ys + (xs >> i);
            z -= f->atan_table[i];
        } else {
            xn = xs + (ys >> i);
            ys = ys - (xs >> i);
            z += f->atan_table[i];
        }
        xs = xn;
    }
    *x_out = saturate(rshift_round(xs, f->guard_bits, IK5R_ROUND_NEAREST), f, &sat);
    *y_out = saturate(rshift_round(ys, f->guard_bits, IK5R_ROUND_NEAREST), f, &sat);
    return sat;
}

/* Square root of an unsigned integer below 2^bits by digit recurrence (bits even, <= 126), reading
 * the low `bits` bits of the radicand. root < 2^63 and rem <= 2 root; for bits <= 84 (every caller)
 * root < 2^42, so rem << 2 < 2^45: no wrap-around. */
static uint64_t isqrt(wide_t radicand, int bits, int nearest)
{
    uint64_t root = 0, rem = 0, trial, digit;
    int i;

    for (i = (bits >> 1) - 1; i >= 0; i--) { /* bits >> 1 == bits // 2 for bits >= 0 */
        digit = 2 * i < 64 ? radicand.lo >> (2 * i) : radicand.hi >> (2 * i - 64);
        rem = (rem << 2) | (digit & 3u);
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
 * complement modulo 2^64, of which isqrt reads only the low bits (<= 64) -- the model's result too. */
static int64_t sqrt_word(int32_t x, int frac)
{
    int bits = IK5R_WIDTH + frac + ((IK5R_WIDTH + frac) & 1);
    wide_t radicand;
    radicand.hi = 0u;
    radicand.lo = (uint64_t)(int64_t)x << frac;
    return (int64_t)isqrt(radicand, bits, IK5R_ROUND_NEAREST);
}

/* acos(x) as atan2(sqrt((1 - x)(1 + x)), x), given 1 - x and 1 + x (unit format of f, each in
 * [0, 2]): writes angle_a and sine_u = sin(angle) >= 0. */
static void acos_of_complements(int64_t one_minus_u, int64_t one_plus_u, const format_t *f,
                                int64_t *angle_a, int64_t *sine_u)
{
    int64_t unused;
    /* The product of two numbers in [0, 2] with 2*frac_unit fraction bits: at most 2^(2*frac_unit + 2). */
    *sine_u = (int64_t)isqrt(wide_mul(one_minus_u, one_plus_u), 2 * f->frac_unit + 4, IK5R_ROUND_NEAREST);
    (void)cordic_atan2(*sine_u, f->one_u - one_minus_u, f, angle_a, &unused);
}

/* acos of a unit-format word of f as atan2(sqrt((1 - x)(1 + x)), x). Input outside [-1, 1] is
 * clipped and flagged. Writes angle_a and sine_u = sin(angle) >= 0; returns the flags. */
static uint32_t cordic_acos(int64_t x_u, const format_t *f, int64_t *angle_a, int64_t *sine_u)
{
    uint32_t flags = 0;

    if (x_u > f->one_u) {
        x_u = f->one_u;
        flags = IK5R_STATUS_SATURATED;
    } else if (x_u < -f->one_u) {
        x_u = -f->one_u;
        flags = IK5R_STATUS_SATURATED;
    }
    acos_of_complements(f->one_u - x_u, f->one_u + x_u, f, angle_a, sine_u);
    return flags;
}

/* An input word as a word of the internal format: exact (the guard bits more fraction bits). */
static int64_t to_internal(int32_t word)
{
    return (int64_t)word * pow2(IK5R_INTERNAL_GUARD_BITS); /* word << guard, word may be negative */
}

/* ---- orientation checks (model.check_word, beyond, frame_is_bad, off_plane): products of
 * check words (the top 17 bits of a unit word, floored) in int64_t, below 2^34. ---- */

static int beyond(int64_t value, int64_t centre, int64_t tolerance)
{
    return value > centre + tolerance || value < centre - tolerance;
}

/* n, o, a (words) not a right-handed orthonormal frame within the orientation tolerance. */
static int frame_is_bad(const int32_t n_u[3], const int32_t o_u[3], const int32_t a_u[3])
{
    const int64_t tol = IK5R_CHECK_TOL_C2, one = IK5R_CHECK_ONE_C2;
    const int64_t scale = (int64_t)1 << IK5R_CHECK_FRAC;
    int64_t n[3], o[3], a[3];
    int i;

    for (i = 0; i < 3; i++) {
        n[i] = (int64_t)n_u[i] >> IK5R_CHECK_SHIFT;
        o[i] = (int64_t)o_u[i] >> IK5R_CHECK_SHIFT;
        a[i] = ((int64_t)a_u[i] >> IK5R_CHECK_SHIFT) * scale;
    }
    return beyond(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], one, tol)
        || beyond(o[0] * o[0] + o[1] * o[1] + o[2] * o[2], one, tol)
        || beyond(n[0] * o[0] + n[1] * o[1] + n[2] * o[2], 0, tol)
        || beyond(n[1] * o[2] - n[2] * o[1] - a[0], 0, tol)
        || beyond(n[2] * o[0] - n[0] * o[2] - a[1], 0, tol)
        || beyond(n[0] * o[1] - n[1] * o[0] - a[2], 0, tol);
}

/* The approach's component normal to the arm's plane, ay c1 - ax s1 (internal words), beyond
 * the orientation tolerance. */
static int off_plane(int64_t ax, int64_t ay, int64_t c1_u, int64_t s1_u)
{
    const int shift = IK5R_IK_CHECK_SHIFT;
    return beyond((ay >> shift) * (c1_u >> shift) - (ax >> shift) * (s1_u >> shift), 0,
                  IK5R_IK_CHECK_TOL_C2);
}

static int64_t clip_word(int64_t value, const format_t *f)
{
    return value > f->word_max ? f->word_max : value < f->word_min ? f->word_min : value;
}

/* |value| of a word (model.ik._magnitude: two clips, no negation of a word). */
static int64_t magnitude(int64_t value, const format_t *f)
{
    return (value > 0 ? (value < f->word_max ? value : f->word_max) : 0)
         - (value < 0 ? (value > f->word_min ? value : f->word_min) : 0);
}

/* 1 where the tool point lies within 2 input LSB of the approach's vertical plane, else 0
 * (model.ik._approach_weight): |px ay - py ax| >> fu (128 bits, rounded) against
 * (|ax| + |ay|) >> (fu - guard - 1). */
static int64_t approach_weight(int64_t px, int64_t py, int64_t ax, int64_t ay, const format_t *f)
{
    const int nearest = IK5R_ROUND_NEAREST;
    const int64_t cross = wide_rshift_round(wide_sub(wide_mul(px, ay), wide_mul(py, ax)),
                                            IK5R_IK_FRAC_UNIT, nearest);
    const int64_t span = magnitude(ax, f) + magnitude(ay, f);
    const int64_t slack = rshift_round(span, IK5R_IK_FRAC_UNIT - IK5R_INTERNAL_GUARD_BITS - 1, nearest)
                        - magnitude(cross, f);
    return slack + 1 < 0 ? 0 : slack + 1 > 1 ? 1 : slack + 1;
}

/* The horizontal direction of the arm's plane (model.ik._plane_direction): the tool point's
 * horizontal part, plus the approach's (sign turned to agree with it, from the approach's check
 * words) where approach_weight is 1; sums clipped to the word range. */
static void plane_direction(int64_t px, int64_t py, int64_t ax, int64_t ay, const format_t *f,
                            int64_t *x, int64_t *y)
{
    const int shift = IK5R_IK_CHECK_SHIFT;
    const int64_t weight = approach_weight(px, py, ax, ay, f);
    const int64_t vx = ax * weight, vy = ay * weight;
    const int opposed = (ax >> shift) * px + (ay >> shift) * py < 0;

    *x = clip_word(opposed ? px - vx : px + vx, f);
    *y = clip_word(opposed ? py - vy : py + vy, f);
}

/* The fixed-point IK of one pose for one branch: q_a[5] and the status bits. n_u, o_u NULL:
 * q5 = q5_default_a (the model's Pose with n = o = None). Every quantity is in the internal
 * format (ik_format, IK5R_IK_* constants) until the joints are rounded back to words. */
static uint32_t ik_solve(const int32_t p_l[3], const int32_t a_u[3], const int32_t *n_u,
                         const int32_t *o_u, int shoulder_back, int elbow_down,
                         int32_t q5_default_a, int32_t q_a[5])
{
    /* Without internal guard bits the two formats are equal: take the word format's object, so
     * that the compiler sees one constant format throughout (and folds it). */
    const format_t *ik = IK5R_INTERNAL_GUARD_BITS > 0 ? &ik_format : &word_format;
    const int nearest = IK5R_ROUND_NEAREST;
    uint32_t status = 0;
    const int64_t px = to_internal(p_l[0]), py = to_internal(p_l[1]), pz = to_internal(p_l[2]);
    const int64_t ax = to_internal(a_u[0]), ay = to_internal(a_u[1]), az = to_internal(a_u[2]);
    int64_t plane_x, plane_y, rho_l, theta1_a, q1_a, r_l, c1_u, s1_u, a_radial_u, pitch_a, phi_a, off_x_l, off_y_l;
    int64_t xw_l, yw_l, c3_u, elbow_a, s3_u, q3_a, gamma_a, beta_a, q2_a, q4_a, q5_a, unused;
    wide_t num_l2;
    int64_t joints[5];
    int i;

    /* Joint 1: the arm's plane from the tool point and the approach together (plane_direction).
     * px^2 + py^2 < 2^(2 width): 128 bits. */
    rho_l = saturate((int64_t)isqrt(wide_add(wide_mul(px, px), wide_mul(py, py)), 2 * IK5R_IK_WIDTH,
                                    nearest),
                     ik, &status);
    plane_direction(px, py, ax, ay, ik, &plane_x, &plane_y);
    if (cordic_atan2(plane_y, plane_x, ik, &theta1_a, &unused))
        status |= IK5R_STATUS_SINGULAR_BASE; /* vertical approach on the axis: q1 free */
    if (shoulder_back) {
        q1_a = opposite(theta1_a, ik);
        r_l = -rho_l;
    } else {
        q1_a = theta1_a;
        r_l = rho_l;
    }
    status |= cordic_rotate(IK5R_IK_ONE_U, 0, q1_a, ik, &c1_u, &s1_u);

    /* Tool pitch phi = q2 + q3 + q4 from the approach projected onto the arm's plane. */
    a_radial_u = saturate(wide_rshift_round(wide_add(wide_mul(ax, c1_u), wide_mul(ay, s1_u)),
                                            IK5R_IK_FRAC_UNIT, nearest),
                          ik, &status);
    if (cordic_atan2(a_radial_u, az, ik, &pitch_a, &unused))
        status |= IK5R_STATUS_INVALID;
    if (off_plane(ax, ay, c1_u, s1_u))
        status |= IK5R_STATUS_BAD_ORIENTATION;
    phi_a = opposite(pitch_a, ik);

    /* Wrist centre (joint 4 axis) in the arm's plane: subtract R(phi) (a4, d5). */
    status |= cordic_rotate(IK5R_IK_A4_L, IK5R_IK_D5_L, phi_a, ik, &off_x_l, &off_y_l);
    xw_l = saturate(r_l - IK5R_IK_A1_L - off_x_l, ik, &status);
    yw_l = saturate(IK5R_IK_D1_L - pz - off_y_l, ik, &status);

    /* Elbow: law of cosines in 128 bits, clipped to the reachable annulus; unreachable only
     * beyond it by more than the reach tolerance (else a straight or folded elbow). */
    num_l2 = wide_add(wide_sub(wide_mul(xw_l, xw_l), links_sq_l2), wide_mul(yw_l, yw_l));
    if (wide_less(reach_limit_l2, num_l2) || wide_less(num_l2, wide_neg(reach_limit_l2)))
        status |= IK5R_STATUS_UNREACHABLE;
    if (wide_less(twice_a2a3_l2, num_l2))
        num_l2 = twice_a2a3_l2;
    else if (wide_less(num_l2, wide_neg(twice_a2a3_l2)))
        num_l2 = wide_neg(twice_a2a3_l2);
    if (IK5R_INTERNAL_GUARD_BITS == 0) {
        int64_t c3 = mul_const(num_l2, &c3_from_l2, nearest);
        c3_u = c3 > IK5R_IK_ONE_U ? IK5R_IK_ONE_U : c3 < -IK5R_IK_ONE_U ? -IK5R_IK_ONE_U : c3;
        (void)cordic_acos(c3_u, ik, &elbow_a, &s3_u);
    } else {
        /* 1 - c3 = (2 a2 a3 - num) / (2 a2 a3) and 1 + c3 = (2 a2 a3 + num) / (2 a2 a3) straight
         * from the law of cosines: near the straight (folded) elbow the small complement keeps its
         * relative precision, which 1 - c3 formed from a rounded c3 would not. */
        const int64_t two_u = 2 * IK5R_IK_ONE_U;
        int64_t one_minus_c3_u = mul_const(wide_sub(twice_a2a3_l2, num_l2), &c3_complement_from_l2, nearest);
        int64_t one_plus_c3_u = mul_const(wide_add(twice_a2a3_l2, num_l2), &c3_complement_from_l2, nearest);
        if (one_minus_c3_u > two_u)
            one_minus_c3_u = two_u;
        if (one_plus_c3_u > two_u)
            one_plus_c3_u = two_u;
        c3_u = IK5R_IK_ONE_U - one_minus_c3_u;
        acos_of_complements(one_minus_c3_u, one_plus_c3_u, ik, &elbow_a, &s3_u);
    }
    if (s3_u <= IK5R_IK_SINGULAR_S3_U)
        status |= IK5R_STATUS_SINGULAR_ELBOW;
    q3_a = elbow_down ? -elbow_a : elbow_a;

    /* Shoulder: q2 = atan2(yw, xw) -+ atan2(a3 sin|q3|, a2 + a3 cos q3). */
    (void)cordic_atan2(yw_l, xw_l, ik, &gamma_a, &unused);
    (void)cordic_atan2(mul_const(wide_from(s3_u), &a3_from_u, nearest),
                       IK5R_IK_A2_L + mul_const(wide_from(c3_u), &a3_from_u, nearest), ik, &beta_a,
                       &unused);
    q2_a = wrap_angle(elbow_down ? gamma_a + beta_a : gamma_a - beta_a, ik);
    q4_a = wrap_angle(wrap_angle(phi_a - q2_a, ik) - q3_a, ik);

    /* Joint 5: tool roll from n and o, else the caller's value. */
    if (n_u != NULL && o_u != NULL) {
        const int64_t nx = to_internal(n_u[0]), ny = to_internal(n_u[1]);
        const int64_t ox = to_internal(o_u[0]), oy = to_internal(o_u[1]);
        int64_t s5_u = saturate(wide_rshift_round(wide_sub(wide_mul(nx, s1_u), wide_mul(ny, c1_u)),
                                                  IK5R_IK_FRAC_UNIT, nearest),
                                ik, &status);
        int64_t c5_u = saturate(wide_rshift_round(wide_sub(wide_mul(ox, s1_u), wide_mul(oy, c1_u)),
                                                  IK5R_IK_FRAC_UNIT, nearest),
                                ik, &status);
        if (cordic_atan2(s5_u, c5_u, ik, &q5_a, &unused))
            status |= IK5R_STATUS_INVALID;
        if (frame_is_bad(n_u, o_u, a_u))
            status |= IK5R_STATUS_BAD_ORIENTATION;
    } else {
        q5_a = to_internal(q5_default_a);
    }

    /* Joint angles back to words (rounded, saturated: the last overflow check). */
    joints[0] = q1_a;
    joints[1] = q2_a;
    joints[2] = q3_a;
    joints[3] = q4_a;
    joints[4] = q5_a;
    for (i = 0; i < 5; i++) {
        /* A reversed joint (sense -1) reads offset - theta. */
        const int64_t turned = (!IK5R_HAS_REVERSED || ik5r_ik_sense[i] > 0)
                                   ? joints[i] - ik5r_ik_offset_a[i]
                                   : ik5r_ik_offset_a[i] - joints[i];
        q_a[i] = narrow(saturate(rshift_round(wrap_angle(turned, ik), IK5R_INTERNAL_GUARD_BITS, nearest),
                                 &word_format, &status));
        /* Limits in output words; a side at +-pi or beyond holds the word's extreme: never true. */
        if (IK5R_HAS_LIMITS && (q_a[i] < ik5r_limit_lo_a[i] || q_a[i] > ik5r_limit_hi_a[i]))
            status |= IK5R_STATUS_OUT_OF_LIMITS;
    }
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
    if (isqrt(wide_pow2(62), 64, 0) != UINT64_C(1) << 31)
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
    int64_t angle, mag;
    int zero = cordic_atan2(y, x, &word_format, &angle, &mag);
    *angle_a = narrow(angle);
    *magnitude = narrow(mag);
    return zero;
}

uint32_t ik5r_rotate(int32_t x, int32_t y, int32_t angle_a, int32_t *x_out, int32_t *y_out)
{
    int64_t xo, yo;
    uint32_t flags = cordic_rotate(x, y, angle_a, &word_format, &xo, &yo);
    *x_out = narrow(xo);
    *y_out = narrow(yo);
    return flags;
}

uint32_t ik5r_acos(int32_t x_u, int32_t *angle_a, int32_t *sine_u)
{
    int64_t angle, sine;
    uint32_t flags = cordic_acos(x_u, &word_format, &angle, &sine);
    *angle_a = narrow(angle);
    *sine_u = narrow(sine);
    return flags;
}

int64_t ik5r_sqrt_word(int32_t x, int frac)
{
    if (frac < 0 || frac > 64 - IK5R_WIDTH - 1)
        return -1;
    return sqrt_word(x, frac);
}

uint64_t ik5r_isqrt64(uint64_t radicand, int bits, int nearest)
{
    wide_t wide_radicand;
    if (bits < 0 || bits > 64)
        return UINT64_MAX;
    wide_radicand.hi = 0u;
    wide_radicand.lo = radicand;
    return isqrt(wide_radicand, bits, nearest);
}

#ifndef IK5R_NO_BATCH_API
void ik5r_atan2_batch(size_t count, const int32_t *y, const int32_t *x, int32_t *angle_a,
                      int32_t *magnitude, uint8_t *zero)
{
    size_t i;
    for (i = 0; i < count; i++)
        zero[i] = (uint8_t)ik5r_atan2(y[i], x[i], angle_a + i, magnitude + i);
}

void ik5r_rotate_batch(size_t count, const int32_t *x, const int32_t *y, const int32_t *angle_a,
                       int32_t *x_out, int32_t *y_out, uint32_t *flags)
{
    size_t i;
    for (i = 0; i < count; i++)
        flags[i] = ik5r_rotate(x[i], y[i], angle_a[i], x_out + i, y_out + i);
}

void ik5r_acos_batch(size_t count, const int32_t *x_u, int32_t *angle_a, int32_t *sine_u,
                     uint32_t *flags)
{
    size_t i;
    for (i = 0; i < count; i++)
        flags[i] = ik5r_acos(x_u[i], angle_a + i, sine_u + i);
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
