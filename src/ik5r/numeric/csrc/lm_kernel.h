/* Damped least squares (Levenberg-Marquardt) inverse kinematics of a general serial arm, float64.
 * The C twin of ik5r.numeric.solver.levenberg_marquardt (the numpy reference): same iteration, same
 * stopping rules, one (pose, start) row at a time so that every row stops as soon as it is done. */
#ifndef IK5R_LM_KERNEL_H
#define IK5R_LM_KERNEL_H

#include <stddef.h>

#define LM_MAX_JOINTS 7

enum lm_mode { LM_POSE = 0, LM_POSITION = 1, LM_DIRECTION = 2 };
enum lm_joint_kind { LM_REVOLUTE = 0, LM_PRISMATIC = 1, LM_WRAPPED = 2 }; /* wrapped: full-turn revolute */

typedef struct {
    int n;                               /* joints, 1..LM_MAX_JOINTS */
    int mode;                            /* enum lm_mode */
    double consts[LM_MAX_JOINTS + 1][12]; /* row-major 3x4 [R | t] before joint i; [n] = tool */
    double offset[LM_MAX_JOINTS], scale[LM_MAX_JOINTS];
    double lower[LM_MAX_JOINTS], upper[LM_MAX_JOINTS];
    int kind[LM_MAX_JOINTS];             /* enum lm_joint_kind */
    double weight;                       /* orientation rows are scaled by this (cm per rad) */
} lm_chain;

typedef struct {
    int iterations, extra;               /* budget; rows within `close` get extra * iterations */
    double tol_cm, tol_rad, stop, close, damping;
    double hopeless;                     /* rows farther than this after give_up steps stop */
    int give_up;
} lm_params;

/* Rows r < count: solve pose rows[r] (target_p[3*i], target_R[9*i] row-major or target_a[3*i])
 * from q0[n*r]. Outputs q[n*r], pos[r] (cm), rot[r] (rad; NaN in position mode), iters[r] (number
 * of LM steps tried). Returns 0, or -1 on an invalid chain or params (nothing written). */
int lm_solve_rows(const lm_chain *chain, const lm_params *params, size_t count, const long long *rows,
                  const double *target_p, const double *target_R, const double *target_a,
                  const double *q0, double *q, double *pos, double *rot, long long *iters);

#endif
