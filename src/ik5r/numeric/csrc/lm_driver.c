/* Test driver of lm_kernel.c for the sanitizer build: reads a chain, parameters and rows as text
 * on stdin (format written by ik5r.numeric.lmkernel.driver_input), solves each row, prints
 * "q... pos rot iters" per row with 17 significant digits. Exit 2 on malformed input. */
#include <stdio.h>
#include <stdlib.h>

#include "lm_kernel.h"

static int read_doubles(double *out, int count) {
    int i;
    for (i = 0; i < count; i++)
        if (scanf("%lf", &out[i]) != 1) return 0;
    return 1;
}

static int read_chain(lm_chain *c, lm_params *pr) {
    int i;
    if (scanf("%d %d %lf", &c->n, &c->mode, &c->weight) != 3 || c->n < 1 || c->n > LM_MAX_JOINTS) return 0;
    for (i = 0; i <= c->n; i++)
        if (!read_doubles(c->consts[i], 12)) return 0;
    for (i = 0; i < c->n; i++)
        if (scanf("%lf %lf %lf %lf %d", &c->offset[i], &c->scale[i], &c->lower[i], &c->upper[i], &c->kind[i]) != 5)
            return 0;
    return scanf("%d %d %lf %lf %lf %lf %lf %lf %d", &pr->iterations, &pr->extra, &pr->tol_cm, &pr->tol_rad,
                 &pr->stop, &pr->close, &pr->damping, &pr->hopeless, &pr->give_up) == 9;
}

int main(void) {
    lm_chain c;
    lm_params pr;
    double p[3], R[9], a[3], q0[LM_MAX_JOINTS], q[LM_MAX_JOINTS], pos, rot;
    long long row = 0, iters;
    int i;
    if (!read_chain(&c, &pr)) return 2;
    while (scanf("%lf", &p[0]) == 1) {
        if (!read_doubles(p + 1, 2) || (c.mode == LM_POSE && !read_doubles(R, 9))
            || (c.mode == LM_DIRECTION && !read_doubles(a, 3)) || !read_doubles(q0, c.n))
            return 2;
        if (lm_solve_rows(&c, &pr, 1, &row, p, R, a, q0, q, &pos, &rot, &iters) != 0) return 2;
        for (i = 0; i < c.n; i++) printf("%.17g ", q[i]);
        printf("%.17g %.17g %lld\n", pos, rot, iters);
    }
    return 0;
}
