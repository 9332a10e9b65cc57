/* See lm_kernel.h. Every step mirrors ik5r/numeric.py and ik5r/chain.py (names kept), so the two
 * agree to rounding; the numpy code is the reference and documents the method. */
#include "lm_kernel.h"

#include <math.h>

#define LM_MAX_TASK 6
#define LM_PI 3.14159265358979323846
#define LM_UNROLL _Pragma("GCC unroll 8")

typedef struct {
    double R[3][3]; /* tool rotation, R[row][col] */
    double p[3];
    double e[LM_MAX_TASK];
    double J[LM_MAX_TASK][LM_MAX_JOINTS]; /* task Jacobian */
    double pos, rot, cost;
} lm_eval;

static int task_rows(int mode) { return mode == LM_POSITION ? 3 : 6; }

/* sin and cos of the n joint angles x[i] at once, within an ulp or so: fdlibm's kernels on x
 * reduced by a three-part pi/2 (exact products for |k| < 2^20). libm's sin and cos cost a quarter
 * of the run time here; these loops inline, have no branch on the quadrant (a select, so no
 * mispredictions) and run the n polynomials side by side (independent chains overlap). Large |x|
 * (never a joint angle) goes to libm. */
static inline void sin_cos_n(int n, const double *x, double *s_out, double *c_out) {
    static const double S1 = -1.66666666666666324348e-01, S2 = 8.33333333332248946124e-03,
                        S3 = -1.98412698298579493134e-04, S4 = 2.75573137070700676789e-06,
                        S5 = -2.50507602534068634195e-08, S6 = 1.58969099521155010221e-10;
    static const double C1 = 4.16666666666666019037e-02, C2 = -1.38888888888741095749e-03,
                        C3 = 2.48015872894767294178e-05, C4 = -2.75573143513906633035e-07,
                        C5 = 2.08757232129817482790e-09, C6 = -1.13596475577881948265e-11;
    static const double INV_PIO2 = 6.36619772367581382433e-01, PIO2_1 = 1.57079632673412561417e+00,
                        PIO2_2 = 6.07710050630396597660e-11, PIO2_3 = 2.02226624871116645580e-21;
    static const double SIGN[2] = {1.0, -1.0};
    double sc[LM_MAX_JOINTS][2];
    long k[LM_MAX_JOINTS];
    int i;
    for (i = 0; i < n; i++) {
        double xi = fabs(x[i]) < 1e5 ? x[i] : 0.0, fn, r, z, hz, w;
        k[i] = (long)(xi * INV_PIO2 + (xi >= 0.0 ? 0.5 : -0.5));
        fn = (double)k[i];
        r = ((xi - fn * PIO2_1) - fn * PIO2_2) - fn * PIO2_3;
        z = r * r;
        sc[i][0] = r + z * r * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))));
        hz = 0.5 * z;
        w = 1.0 - hz;
        sc[i][1] = w + (((1.0 - w) - hz) + z * z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6))))));
    }
    for (i = 0; i < n; i++) { /* quadrant k: (sin, cos) = (s, c), (c, -s), (-s, -c), (-c, s) */
        int odd = (int)(k[i] & 1);
        s_out[i] = SIGN[(k[i] >> 1) & 1] * sc[i][odd];
        c_out[i] = SIGN[((k[i] + 1) >> 1) & 1] * sc[i][1 - odd];
        if (!(fabs(x[i]) < 1e5)) {
            s_out[i] = sin(x[i]);
            c_out[i] = cos(x[i]);
        }
    }
}

/* frames + jacobian of chain.py: tool R, p and the geometric Jacobian (6 x n). */
static void forward(const lm_chain *c, int n, const double *q, double R[3][3], double p[3],
                    double J[LM_MAX_TASK][LM_MAX_JOINTS], double w) {
    /* zeroed: GCC's unrolled loops otherwise see maybe-uninitialized entries beyond n */
    double col[3][3], org[LM_MAX_JOINTS][3] = {{0}}, ax[LM_MAX_JOINTS][3] = {{0}};
    double cosv[LM_MAX_JOINTS] = {0}, sinv[LM_MAX_JOINTS] = {0}, angle[LM_MAX_JOINTS] = {0};
    int i, j, k;
    LM_UNROLL
    for (i = 0; i < n; i++) angle[i] = c->offset[i] + c->scale[i] * q[i]; /* unused if prismatic */
    sin_cos_n(n, angle, sinv, cosv);
    LM_UNROLL
    for (j = 0; j < 3; j++) {
        LM_UNROLL
        for (k = 0; k < 3; k++) col[j][k] = c->consts[0][4 * k + j];
        p[j] = c->consts[0][4 * j + 3];
    }
    LM_UNROLL
    for (i = 0; i < n; i++) {
        const double *C = c->consts[i + 1];
        double v = c->offset[i] + c->scale[i] * q[i], nc[3][3], np_[3];
        LM_UNROLL
        for (k = 0; k < 3; k++) { ax[i][k] = col[2][k]; org[i][k] = p[k]; }
        if (c->kind[i] == LM_PRISMATIC) {
            LM_UNROLL
            for (k = 0; k < 3; k++) p[k] += v * col[2][k];
        } else {
            double cs = cosv[i], sn = sinv[i], x, y;
            LM_UNROLL
            for (k = 0; k < 3; k++) {
                x = col[0][k]; y = col[1][k];
                col[0][k] = cs * x + sn * y;
                col[1][k] = cs * y - sn * x;
            }
        }
        LM_UNROLL
        for (k = 0; k < 3; k++) {
            np_[k] = p[k] + col[0][k] * C[3] + col[1][k] * C[7] + col[2][k] * C[11];
            LM_UNROLL
            for (j = 0; j < 3; j++) nc[j][k] = col[0][k] * C[j] + col[1][k] * C[4 + j] + col[2][k] * C[8 + j];
        }
        LM_UNROLL
        for (k = 0; k < 3; k++) {
            p[k] = np_[k];
            LM_UNROLL
            for (j = 0; j < 3; j++) col[j][k] = nc[j][k];
        }
    }
    LM_UNROLL
    for (j = 0; j < 3; j++)
        LM_UNROLL
        for (k = 0; k < 3; k++) R[k][j] = col[j][k];
    LM_UNROLL
    for (i = 0; i < n; i++) {
        const double *z = ax[i];
        double d[3], s = c->scale[i];
        LM_UNROLL
        for (k = 0; k < 3; k++) d[k] = p[k] - org[i][k];
        if (c->kind[i] == LM_PRISMATIC) {
            LM_UNROLL
            for (k = 0; k < 3; k++) { J[k][i] = s * z[k]; J[3 + k][i] = 0.0; }
        } else {
            J[0][i] = s * (z[1] * d[2] - z[2] * d[1]);
            J[1][i] = s * (z[2] * d[0] - z[0] * d[2]);
            J[2][i] = s * (z[0] * d[1] - z[1] * d[0]);
            LM_UNROLL
            for (k = 0; k < 3; k++) J[3 + k][i] = w * (s * z[k]);
        }
    }
}

static double chord_angle(double chord) { return 2.0 * asin(fmin(chord / 2.0, 1.0)); }

/* atan2(y, x) for y >= 0, within an ulp: fdlibm's atan (four reduction intervals, an 11-term
 * polynomial), inlined: libm's atan2 was a tenth of the run time. */
static double atan2_upper(double y, double x) {
    static const double HI[4] = {4.63647609000806093515e-01, 7.85398163397448278999e-01,
                                 9.82793723247329054082e-01, 1.57079632679489655800e+00};
    static const double LO[4] = {2.26987774529616870924e-17, 3.06161699786838301793e-17,
                                 1.39033110312309984516e-17, 6.12323399573676603587e-17};
    static const double T[11] = {3.33333333333329318027e-01, -1.99999999998764832476e-01,
                                 1.42857142725034663711e-01, -1.11111104054623557880e-01,
                                 9.09088713343650656196e-02, -7.69187620504482999495e-02,
                                 6.66107313738753120669e-02, -5.83357013379057348645e-02,
                                 4.97687799461593236017e-02, -3.65315727442169155270e-02,
                                 1.62858201153657823623e-02};
    static const double PI_HI = 3.1415926535897931160e+00, PI_LO = 1.2246467991473531772e-16;
    double t, z, w, s1, s2, r;
    int id;
    if (!(y >= 0.0) || !(fabs(x) < 1e300) || !(y < 1e300)) return atan2(y, x); /* NaN, inf: libm */
    if (y == 0.0) return x < 0.0 || (x == 0.0 && signbit(x)) ? PI_HI : 0.0;
    if (x == 0.0) return 0.5 * PI_HI;
    t = y / fabs(x);
    if (t > 1e18) return 0.5 * PI_HI; /* as libm to rounding */
    if (t < 0.4375) {
        id = -1;
    } else if (t < 1.1875) {
        if (t < 0.6875) { id = 0; t = (2.0 * t - 1.0) / (2.0 + t); }
        else { id = 1; t = (t - 1.0) / (t + 1.0); }
    } else if (t < 2.4375) {
        id = 2; t = (t - 1.5) / (1.0 + 1.5 * t);
    } else {
        id = 3; t = -1.0 / t;
    }
    z = t * t;
    w = z * z;
    s1 = z * (T[0] + w * (T[2] + w * (T[4] + w * (T[6] + w * (T[8] + w * T[10])))));
    s2 = w * (T[1] + w * (T[3] + w * (T[5] + w * (T[7] + w * T[9]))));
    r = id < 0 ? t - t * (s1 + s2) : HI[id] - ((t * (s1 + s2) - LO[id]) - t);
    return x > 0.0 ? r : PI_HI - (r - PI_LO);
}

/* numeric.rotation_log: rotation vector of Rerr (axis times angle in [0, pi]). */
static void rotation_log(double Rerr[3][3], double out[3]) {
    double v[3], s, c, angle, f;
    int k;
    v[0] = 0.5 * (Rerr[2][1] - Rerr[1][2]);
    v[1] = 0.5 * (Rerr[0][2] - Rerr[2][0]);
    v[2] = 0.5 * (Rerr[1][0] - Rerr[0][1]);
    s = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    c = 0.5 * (Rerr[0][0] + Rerr[1][1] + Rerr[2][2] - 1.0);
    angle = atan2_upper(s, c);
    f = s > 1e-300 ? angle / s : 1.0;
    for (k = 0; k < 3; k++) out[k] = v[k] * f;
    if (c < 0 && s < 1e-6) { /* sin ~ 0: the axis is the largest column of (R + I), sign from v */
        double B[3][3], best = -1.0, axis[3], norm, dot;
        int j, pick = 0;
        for (j = 0; j < 3; j++)
            for (k = 0; k < 3; k++) B[j][k] = Rerr[j][k] + (j == k ? 1.0 : 0.0);
        for (k = 0; k < 3; k++) {
            norm = sqrt(B[0][k] * B[0][k] + B[1][k] * B[1][k] + B[2][k] * B[2][k]);
            if (norm > best) { best = norm; pick = k; }
        }
        for (j = 0; j < 3; j++) axis[j] = B[j][pick] / best;
        dot = axis[0] * v[0] + axis[1] * v[1] + axis[2] * v[2];
        for (k = 0; k < 3; k++) out[k] = axis[k] * ((dot < 0 ? -1.0 : 1.0) * angle);
    }
}

/* numeric._evaluate: FK, weighted task error and Jacobian, residuals, cost, for target i. */
static void evaluate(const lm_chain *c, int n, const double *tp, const double *tR, const double *ta,
                     const double *q, lm_eval *ev) {
    double d2 = 0.0;
    int i, j, k, m = task_rows(c->mode);
    forward(c, n, q, ev->R, ev->p, ev->J, c->mode == LM_POSE ? c->weight : 1.0); /* J: weighted in pose mode */
    LM_UNROLL
    for (k = 0; k < 3; k++) {
        ev->e[k] = tp[k] - ev->p[k];
        d2 += ev->e[k] * ev->e[k];
    }
    ev->pos = sqrt(d2);
    if (c->mode == LM_POSE) {
        double Rerr[3][3], er[3], f2 = 0.0;
        LM_UNROLL
        for (j = 0; j < 3; j++)
            LM_UNROLL
            for (k = 0; k < 3; k++) {
                Rerr[j][k] = tR[3 * j] * ev->R[k][0] + tR[3 * j + 1] * ev->R[k][1] + tR[3 * j + 2] * ev->R[k][2];
                f2 += (ev->R[j][k] - tR[3 * j + k]) * (ev->R[j][k] - tR[3 * j + k]);
            }
        rotation_log(Rerr, er);
        LM_UNROLL
        for (k = 0; k < 3; k++) ev->e[3 + k] = c->weight * er[k];
        ev->rot = chord_angle(sqrt(f2) / sqrt(2.0));
    } else if (c->mode == LM_DIRECTION) {
        double z[3] = {ev->R[0][2], ev->R[1][2], ev->R[2][2]}, f2 = 0.0;
        LM_UNROLL
        for (k = 0; k < 3; k++) {
            ev->e[3 + k] = c->weight * (ta[k] - z[k]);
            f2 += (z[k] - ta[k]) * (z[k] - ta[k]);
        }
        LM_UNROLL
        for (i = 0; i < n; i++) { /* Jw x z */
            double w0 = ev->J[3][i], w1 = ev->J[4][i], w2 = ev->J[5][i];
            ev->J[3][i] = c->weight * (w1 * z[2] - w2 * z[1]);
            ev->J[4][i] = c->weight * (w2 * z[0] - w0 * z[2]);
            ev->J[5][i] = c->weight * (w0 * z[1] - w1 * z[0]);
        }
        ev->rot = chord_angle(sqrt(f2));
    } else {
        ev->rot = NAN;
    }
    ev->cost = 0.0;
    LM_UNROLL
    for (k = 0; k < m; k++) ev->cost += ev->e[k] * ev->e[k];
    ev->cost *= 0.5;
}

/* Solve A x = b in place for symmetric positive definite A (k x k, lower triangle read) by
 * LDL^T; numpy's reference uses LU, equal to rounding. A non-positive pivot (damping lost to
 * rounding) gives a zero step, which the caller rejects like any step that does not descend. */
static void ldl_solve(double A[LM_MAX_JOINTS][LM_MAX_JOINTS], double *b, int k) {
    double inv[LM_MAX_JOINTS] = {0}, L[LM_MAX_JOINTS][LM_MAX_JOINTS] = {{0}}, Ld[LM_MAX_JOINTS][LM_MAX_JOINTS] = {{0}};
    int i, j, r;
    LM_UNROLL
    for (j = 0; j < k; j++) { /* L[i][j] = Ld[i][j] / d[j], Ld = L * d: no division in the sums */
        double s = A[j][j];
        LM_UNROLL
        for (r = 0; r < j; r++) s -= Ld[j][r] * L[j][r];
        if (!(s > 0.0)) {
            LM_UNROLL
            for (i = 0; i < k; i++) b[i] = 0.0;
            return;
        }
        inv[j] = 1.0 / s;
        LM_UNROLL
        for (i = j + 1; i < k; i++) {
            double t = A[i][j];
            LM_UNROLL
            for (r = 0; r < j; r++) t -= L[i][r] * Ld[j][r];
            Ld[i][j] = t;
            L[i][j] = t * inv[j];
        }
    }
    LM_UNROLL
    for (i = 0; i < k; i++)
        LM_UNROLL
        for (r = 0; r < i; r++) b[i] -= L[i][r] * b[r];
    LM_UNROLL
    for (i = 0; i < k; i++) b[i] *= inv[i];
    LM_UNROLL
    for (i = k - 1; i >= 0; i--)
        LM_UNROLL
        for (r = i + 1; r < k; r++) b[i] -= L[r][i] * b[r];
}

/* numeric._step: damped step h and g = J^T e; returns the predicted decrease. */
static double damped_step(const lm_eval *ev, int m, int n, double mu, double *h) {
    double A[LM_MAX_JOINTS][LM_MAX_JOINTS] = {{0}}, g[LM_MAX_JOINTS] = {0}, pred = 0.0; /* zeroed: as in forward */
    int i, j, r;
    LM_UNROLL
    for (i = 0; i < n; i++) {
        g[i] = 0.0;
        LM_UNROLL
        for (r = 0; r < m; r++) g[i] += ev->J[r][i] * ev->e[r];
    }
    if (m < n) {
        double y[LM_MAX_JOINTS];
        LM_UNROLL
        for (i = 0; i < m; i++) {
            y[i] = ev->e[i];
            LM_UNROLL
            for (j = 0; j <= i; j++) {
                double s = 0.0;
                LM_UNROLL
                for (r = 0; r < n; r++) s += ev->J[i][r] * ev->J[j][r];
                A[i][j] = s + (i == j ? mu : 0.0);
            }
        }
        ldl_solve(A, y, m);
        LM_UNROLL
        for (i = 0; i < n; i++) {
            h[i] = 0.0;
            LM_UNROLL
            for (r = 0; r < m; r++) h[i] += ev->J[r][i] * y[r];
        }
    } else {
        LM_UNROLL
        for (i = 0; i < n; i++) {
            h[i] = g[i];
            LM_UNROLL
            for (j = 0; j <= i; j++) {
                double s = 0.0;
                LM_UNROLL
                for (r = 0; r < m; r++) s += ev->J[r][i] * ev->J[r][j];
                A[i][j] = s + (i == j ? mu : 0.0);
            }
        }
        ldl_solve(A, h, n);
    }
    LM_UNROLL
    for (i = 0; i < n; i++) pred += h[i] * (mu * h[i] + g[i]);
    return 0.5 * pred;
}

/* numpy's mod (result has the divisor's sign). */
static double py_mod(double a, double b) {
    double r = fmod(a, b);
    if (r != 0.0 && ((r < 0.0) != (b < 0.0))) r += b;
    return r;
}

/* numeric.clamp: wrap full-turn joints into their limits, clip the others. */
static void clamp_joints(const lm_chain *c, int n, double *q) {
    int i;
    LM_UNROLL
    for (i = 0; i < n; i++) {
        if (c->kind[i] == LM_WRAPPED) { /* fmod only when out of the turn: fmod(t, b) = t in [0, b) */
            double t = q[i] - c->lower[i];
            q[i] = c->lower[i] + (t >= 0.0 && t < 2.0 * LM_PI ? t : py_mod(t, 2.0 * LM_PI));
        }
        else
            q[i] = fmin(fmax(q[i], c->lower[i]), c->upper[i]);
    }
}

static int below(double pos, double rot, double tol) { return pos <= tol && !(rot > tol); }

/* numeric.levenberg_marquardt for one row; returns the number of steps tried. */
static long long solve_row(const lm_chain *c, int n, const lm_params *pr, const double *tp, const double *tR,
                           const double *ta, const double *q0, double *q_out, double *pos, double *rot) {
    lm_eval buf[2], *cur = &buf[0], *nxt = &buf[1];
    double q[LM_MAX_JOINTS] = {0}, qn[LM_MAX_JOINTS], h[LM_MAX_JOINTS], mu, nu = 2.0, dmax = 0.0;
    int i, r, m = task_rows(c->mode), it, last = pr->extra * pr->iterations;
    LM_UNROLL
    for (i = 0; i < n; i++) q[i] = q0[i];
    evaluate(c, n, tp, tR, ta, q, cur);
    LM_UNROLL
    for (i = 0; i < n; i++) {
        double s = 0.0;
        LM_UNROLL
        for (r = 0; r < m; r++) s += cur->J[r][i] * cur->J[r][i];
        dmax = fmax(dmax, s);
    }
    mu = pr->damping * dmax + 1e-300;
    for (it = 0;; it++) {
        int within = cur->pos <= pr->tol_cm && !(cur->rot > pr->tol_rad);
        int close = below(cur->pos, cur->rot, pr->close);
        double predicted, rho;
        if (below(cur->pos, cur->rot, pr->stop) || nu > 1e6 || (it >= pr->iterations && !close) || it == last
            || (within && nu >= 16) || (it >= pr->give_up && !below(cur->pos, cur->rot, pr->hopeless)))
            break;
        predicted = damped_step(cur, m, n, mu, h);
        LM_UNROLL
        for (i = 0; i < n; i++) qn[i] = q[i] + h[i];
        clamp_joints(c, n, qn);
        evaluate(c, n, tp, tR, ta, qn, nxt);
        rho = (cur->cost - nxt->cost) / fmax(predicted, 1e-300);
        if (rho > 0) {
            double t = 2.0 * rho - 1.0;
            lm_eval *spent = cur;
            cur = nxt;
            nxt = spent;
            LM_UNROLL
            for (i = 0; i < n; i++) q[i] = qn[i];
            mu *= fmax(1.0 / 3.0, 1.0 - t * t * t);
            nu = 2.0;
        } else {
            mu *= nu;
            nu *= 2.0;
        }
    }
    LM_UNROLL
    for (i = 0; i < n; i++) q_out[i] = q[i];
    *pos = cur->pos;
    *rot = cur->rot;
    return it;
}

/* Rows of one chain, n a constant at each call below so that the compiler specialises the loops. */
static void solve_rows(const lm_chain *chain, int n, const lm_params *params, size_t count, const long long *rows,
                       const double *target_p, const double *target_R, const double *target_a,
                       const double *q0, double *q, double *pos, double *rot, long long *iters) {
    size_t r;
    for (r = 0; r < count; r++) {
        size_t i = (size_t)rows[r];
        iters[r] = solve_row(chain, n, params, target_p + 3 * i, target_R ? target_R + 9 * i : 0,
                             target_a ? target_a + 3 * i : 0, q0 + (size_t)n * r, q + (size_t)n * r,
                             pos + r, rot + r);
    }
}

int lm_solve_rows(const lm_chain *chain, const lm_params *params, size_t count, const long long *rows,
                  const double *target_p, const double *target_R, const double *target_a,
                  const double *q0, double *q, double *pos, double *rot, long long *iters) {
    int n = chain->n;
    if (n < 1 || n > LM_MAX_JOINTS || chain->mode < LM_POSE || chain->mode > LM_DIRECTION
        || (chain->mode == LM_POSE && !target_R) || (chain->mode == LM_DIRECTION && !target_a)
        || params->iterations < 0 || params->extra < 1)
        return -1;
    switch (n) {
    case 1: solve_rows(chain, 1, params, count, rows, target_p, target_R, target_a, q0, q, pos, rot, iters); break;
    case 2: solve_rows(chain, 2, params, count, rows, target_p, target_R, target_a, q0, q, pos, rot, iters); break;
    case 3: solve_rows(chain, 3, params, count, rows, target_p, target_R, target_a, q0, q, pos, rot, iters); break;
    case 4: solve_rows(chain, 4, params, count, rows, target_p, target_R, target_a, q0, q, pos, rot, iters); break;
    case 5: solve_rows(chain, 5, params, count, rows, target_p, target_R, target_a, q0, q, pos, rot, iters); break;
    case 6: solve_rows(chain, 6, params, count, rows, target_p, target_R, target_a, q0, q, pos, rot, iters); break;
    default: solve_rows(chain, 7, params, count, rows, target_p, target_R, target_a, q0, q, pos, rot, iters);
    }
    return 0;
}
