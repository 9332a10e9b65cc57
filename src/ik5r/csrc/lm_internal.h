/* Shared between lm_kernel.c (one row at a time) and lm_lanes.c (four rows in the lanes of a
 * vector): the scalar pieces the lanes fall back on for a lane off the common path, so that a row
 * gets the same bits whichever code solves it. Not part of the public interface (lm_kernel.h). */
#ifndef IK5R_LM_INTERNAL_H
#define IK5R_LM_INTERNAL_H

#include "lm_kernel.h"

double lm_atan2_upper(double y, double x);          /* atan2 for y >= 0 (others: libm) */
void lm_rotation_log(double Rerr[3][3], double out[3]); /* numeric.rotation_log of one matrix */
double lm_py_mod(double a, double b);               /* numpy's mod */

/* The lanes' kernel: rows r < count as lm_solve_rows, for pose mode with n <= 6 (the task
 * Jacobian's rows m = 6 >= n). The chain and params are checked by the caller. */
void lm_solve_lanes(const lm_chain *chain, const lm_params *params, size_t count, const long long *rows,
                    const double *target_p, const double *target_R, const double *q0, double *q, double *pos,
                    double *rot, long long *iters);

#endif
