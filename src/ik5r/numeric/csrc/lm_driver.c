/* Test driver of lm_kernel.c for the sanitizer build: reads a chain, parameters and rows as text
 * on stdin (format written by ik5r.numeric.lmkernel.driver_input), solves the rows in one call, prints
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

typedef struct { /* the rows read, grown as they come */
    size_t count, cap;
    long long *rows;
    double *p, *R, *a, *q0;
} batch;

static int grow_to(void **block, size_t bytes) { /* realloc, the old block kept on failure */
    void *grown = realloc(*block, bytes);
    if (!grown) return 0;
    *block = grown;
    return 1;
}

static int grow(batch *b, int n) {
    size_t cap = b->cap ? 2 * b->cap : 64;
    void *rows = b->rows, *p = b->p, *R = b->R, *a = b->a, *q0 = b->q0;
    int ok = grow_to(&rows, cap * sizeof *b->rows) && grow_to(&p, cap * 3 * sizeof *b->p)
             && grow_to(&R, cap * 9 * sizeof *b->R) && grow_to(&a, cap * 3 * sizeof *b->a)
             && grow_to(&q0, cap * n * sizeof *b->q0);
    b->rows = rows;
    b->p = p;
    b->R = R;
    b->a = a;
    b->q0 = q0;
    if (ok) b->cap = cap;
    return ok;
}

static int read_rows(const lm_chain *c, batch *b) {
    double first;
    while (scanf("%lf", &first) == 1) {
        size_t r = b->count;
        if (r == b->cap && !grow(b, c->n)) return 0;
        b->rows[r] = (long long)r;
        b->p[3 * r] = first;
        if (!read_doubles(b->p + 3 * r + 1, 2) || (c->mode == LM_POSE && !read_doubles(b->R + 9 * r, 9))
            || (c->mode == LM_DIRECTION && !read_doubles(b->a + 3 * r, 3)) || !read_doubles(b->q0 + c->n * r, c->n))
            return 0;
        b->count++;
    }
    return 1;
}

/* All rows in one call, as the library gets them (so the lanes take rows in turn). */
static int solve_and_print(const lm_chain *c, const lm_params *pr, const batch *b) {
    size_t count = b->count, r;
    double *q, *pos, *rot;
    long long *iters;
    int i, ok;
    if (!count) return 1;
    q = malloc(count * c->n * sizeof *q);
    pos = malloc(count * sizeof *pos);
    rot = malloc(count * sizeof *rot);
    iters = malloc(count * sizeof *iters);
    ok = q && pos && rot && iters
         && lm_solve_rows(c, pr, count, b->rows, b->p, b->R, b->a, b->q0, q, pos, rot, iters) == 0;
    for (r = 0; ok && r < count; r++) {
        for (i = 0; i < c->n; i++) printf("%.17g ", q[c->n * r + i]);
        printf("%.17g %.17g %lld\n", pos[r], rot[r], iters[r]);
    }
    free(q);
    free(pos);
    free(rot);
    free(iters);
    return ok;
}

int main(void) {
    lm_chain c;
    lm_params pr;
    batch b = {0, 0, 0, 0, 0, 0, 0};
    int ok;
    if (!read_chain(&c, &pr)) return 2;
    ok = read_rows(&c, &b) && solve_and_print(&c, &pr, &b);
    free(b.rows);
    free(b.p);
    free(b.R);
    free(b.a);
    free(b.q0);
    return ok ? 0 : 2;
}
