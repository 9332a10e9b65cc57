/* ik5r.h -- public API of the integer-only inverse kinematics of the 5R arm (Nios-style C99).
 *
 * Bit for bit the computation of firmware/model.py (the specification), for the
 * fixed-point config and arm baked into the generated "ik5r_config.h"
 * (python -m ik5r.firmware.codegen --config q32 -o ik5r_config.h).
 *
 * Formats (suffix of every name): _l length Q(IK5R_FRAC_LENGTH) cm, _u unit-vector component
 * Q(IK5R_FRAC_UNIT), _a angle Q(IK5R_FRAC_ANGLE) radians. Every input is a word: a signed
 * IK5R_WIDTH-bit integer carried in an int32_t (the solver does not check the range of its
 * inputs; values outside [IK5R_WORD_MIN, IK5R_WORD_MAX] are outside the contract, although
 * still free of undefined behaviour). Status values are OR-ed IK5R_STATUS_* bits.
 *
 * Implementation-defined behaviour relied on: >> of a negative signed integer is an arithmetic
 * (flooring) shift -- checked at compile time and by ik5r_self_check(). See docs/algorithm.md,
 * "C semantics relied on".
 */
#ifndef IK5R_H
#define IK5R_H

#include <stddef.h>
#include <stdint.h>

#include "ik5r_config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* 0 when the C semantics the solver relies on hold on this target (call once at start-up);
 * otherwise a non-zero code naming the first failed check. */
int ik5r_self_check(void);

/* The config name baked in (IK5R_CONFIG_NAME). */
const char *ik5r_config_name(void);

/* IK of one pose for one branch.
 * p_l[3]: tool point; a_u[3]: approach; n_u[3], o_u[3]: normal and orientation, used for the tool
 * roll q5 when has_roll != 0 and both are non-NULL; otherwise q5 = q5_default_a.
 * shoulder_back: tool point behind joint 1 (q1 + pi); elbow_down: q3 = -acos(c3).
 * Writes the five joint angles q_a[5] (words) and returns the status bits. */
uint32_t ik5r_solve(const int32_t p_l[3], const int32_t a_u[3], const int32_t n_u[3],
                    const int32_t o_u[3], int has_roll, int shoulder_back, int elbow_down,
                    int32_t q5_default_a, int32_t q_a[5]);

/* ik5r_solve over count poses (row-major arrays, e.g. from numpy via ctypes):
 * p_l, a_u, n_u, o_u: count x 3; has_roll, shoulder_back, elbow_down: count bytes (0/1);
 * q5_default_a: count; outputs q_a: count x 5, status: count. n_u and o_u may be NULL (no roll). */
void ik5r_solve_batch(size_t count, const int32_t *p_l, const int32_t *a_u, const int32_t *n_u,
                      const int32_t *o_u, const uint8_t *has_roll, const uint8_t *shoulder_back,
                      const uint8_t *elbow_down, const int32_t *q5_default_a, int32_t *q_a,
                      uint32_t *status);

/* Building blocks, exported for testing (model.py functions of the same name). */

/* cordic_atan2: *angle_a = atan2(y, x), *magnitude = |(x, y)| in the inputs' format (saturated);
 * returns 1 when x == y == 0 (angle and magnitude 0), else 0. */
int ik5r_atan2(int32_t y, int32_t x, int32_t *angle_a, int32_t *magnitude);

/* cordic_rotate: (x, y) rotated by angle_a (|angle_a| <= pi + a few LSB for an accurate result);
 * returns IK5R_STATUS_SATURATED when an output was clipped to the word range, else 0. */
uint32_t ik5r_rotate(int32_t x, int32_t y, int32_t angle_a, int32_t *x_out, int32_t *y_out);

/* cordic_acos: *angle_a = acos(x_u), *sine_u = sin(acos(x_u)) >= 0; input outside [-1, 1] is
 * clipped and IK5R_STATUS_SATURATED returned, else 0. */
uint32_t ik5r_acos(int32_t x_u, int32_t *angle_a, int32_t *sine_u);

/* sqrt_word: square root of the word x (x >= 0 by contract) with frac fraction bits, same
 * format. A negative x is taken modulo 2^bits like the model (bits = width + frac rounded up to
 * even), which is why the result is int64_t. Returns -1 when frac is outside
 * [0, 64 - IK5R_WIDTH - 1] (the radicand would not fit 64 bits). */
int64_t ik5r_sqrt_word(int32_t x, int frac);

/* isqrt: floor (nearest == 0) or rounded (nearest != 0) square root of radicand < 2^bits by
 * digit recurrence, bits even. Returns UINT64_MAX when bits is outside [0, 64]. */
uint64_t ik5r_isqrt64(uint64_t radicand, int bits, int nearest);

#ifndef IK5R_NO_BATCH_API
/* Element-wise batches of the building blocks (for ctypes/numpy tests). */
void ik5r_atan2_batch(size_t count, const int32_t *y, const int32_t *x, int32_t *angle_a,
                      int32_t *magnitude, uint8_t *zero);
void ik5r_rotate_batch(size_t count, const int32_t *x, const int32_t *y, const int32_t *angle_a,
                       int32_t *x_out, int32_t *y_out, uint32_t *flags);
void ik5r_acos_batch(size_t count, const int32_t *x_u, int32_t *angle_a, int32_t *sine_u,
                     uint32_t *flags);
void ik5r_sqrt_word_batch(size_t count, const int32_t *x, const int32_t *frac, int64_t *root);
void ik5r_isqrt64_batch(size_t count, const uint64_t *radicand, const int32_t *bits,
                        const uint8_t *nearest, uint64_t *root);
#endif

#ifdef __cplusplus
}
#endif

#endif /* IK5R_H */
