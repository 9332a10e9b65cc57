/* Shared between lm_kernel.c (one row at a time) and lm_lanes.c (four rows in the lanes of a
 * vector): the scalar pieces the lanes fall back on for a lane off the common path, so that a row
 * gets the same bits whichever code solves it. Not part of the public interface (lm_kernel.h). */
#ifndef IK5R_LM_INTERNAL_H
#define IK5R_LM_INTERNAL_H

#include "lm_kernel.h"

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__)) && !defined(LM_NO_LANES)
#define LM_HAVE_LANES 1 /* lm_lanes.c: GCC vectors, compiled for AVX2, used when the CPU has it */
#endif

extern int lm_use_lanes; /* 1 (default): use the lanes where they apply; 0: a row at a time (tests) */
int lm_lanes_available(void); /* 1 when this build and CPU have the lanes (x86 with AVX2) */

double lm_atan2_upper(double y, double x);          /* atan2 for y >= 0 (others: libm) */
void lm_rotation_log(double Rerr[3][3], double out[3]); /* numeric.rotation_log of one matrix */
double lm_py_mod(double a, double b);               /* numpy's mod */

#ifdef LM_HAVE_LANES
/* The lanes' kernel: rows r < count as lm_solve_rows, for pose mode and n = 6 (the common case;
 * one specialisation keeps the build short). The chain and params are checked by the caller. */
void lm_solve_lanes(const lm_chain *chain, const lm_params *params, size_t count, const long long *rows,
                    const double *target_p, const double *target_R, const double *q0, double *q, double *pos,
                    double *rot, long long *iters);
#endif

#endif
