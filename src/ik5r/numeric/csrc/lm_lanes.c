/* lm_kernel.c's iteration on four rows at once, one per lane of a GCC vector: the common case
 * (pose mode, six joints) of lm_solve_rows on an x86-64 CPU with AVX2 (four doubles per
 * instruction; on the baseline ISA the vectors split into SSE2 halves and run slower than a row at
 * a time, so lm_kernel.c keeps those). The scalar code is the specification: every lane does the
 * same IEEE operations in the same order (ISO C: no contraction into fused multiply-adds; AVX2
 * brings no FMA), so a row gets the same bits here as there; a lane off the common path (a huge
 * angle, a rotation error near pi, a joint wrapped from out of its turn) takes the scalar function
 * for that lane. The lanes run in lockstep, each on its own row; a lane whose row stops takes the
 * next row. */
#include "lm_internal.h"

#include <math.h>

#ifdef LM_HAVE_LANES

#define LANES 4
#define TASK 6
#define MAXJ 6 /* the lanes solve six-joint arms (others: lm_kernel.c, a row at a time) */
#define LM_PI 3.14159265358979323846
#define UNROLL _Pragma("GCC unroll 8")
#define HOT static inline __attribute__((always_inline, target("avx2"))) /* into lm_solve_lanes */

typedef double lv __attribute__((vector_size(LANES * sizeof(double))));
typedef long long li __attribute__((vector_size(LANES * sizeof(long long))));
typedef unsigned long long lu __attribute__((vector_size(LANES * sizeof(long long))));

typedef struct {
    lv R[3][3], p[3]; /* tool frame, R[row][col] */
    lv e[TASK], J[TASK][MAXJ], pos, rot, cost;
} lane_eval;

typedef struct {
    lv q[MAXJ], h[MAXJ], x[MAXJ], mu, nu, pred;
    lv tp[3], tR[9];         /* each lane's target */
    lane_eval cur, nxt;
    long long row[LANES];    /* row index r of each lane, -1 when idle */
    li fresh;                /* lane just loaded (or idle): its next evaluation is at its start */
    int it[LANES];
} lanes;

/* Helpers as macros (no vector passes by value: a 32-byte vector argument has no baseline ABI). */
#define splat(v) ((lv){(v), (v), (v), (v)})
#define splat_i(v) ((li){(v), (v), (v), (v)})
#define sel(mask, a, b) ((lv)(((lu)(mask) & (lu)(a)) | (~(lu)(mask) & (lu)(b))))
#define vabs(v) ((lv)((lu)(v) & (lu)splat_i(0x7fffffffffffffffLL)))
#define any(mask) (__builtin_ia32_movmskpd256((lv)(mask)) != 0) /* any lane set (sign bits) */
#define vfmax(x, y) sel(((x) > (y)) | ((y) != (y)), (x), (y)) /* C99 fmax for a non-NaN x, as maxsd */

HOT void vsqrt(lv *v) { *v = __builtin_ia32_sqrtpd256(*v); } /* IEEE: the scalar sqrt's bits */

/* lm_kernel.c's sin_cos_n, lane-wise; the quadrant's sign applied as a sign-bit flip (exactly the
 * scalar product by -1). */
HOT void sin_cos_lanes(int n, const lv *x, lv *s_out, lv *c_out) {
    static const double S1 = -1.66666666666666324348e-01, S2 = 8.33333333332248946124e-03,
                        S3 = -1.98412698298579493134e-04, S4 = 2.75573137070700676789e-06,
                        S5 = -2.50507602534068634195e-08, S6 = 1.58969099521155010221e-10;
    static const double C1 = 4.16666666666666019037e-02, C2 = -1.38888888888741095749e-03,
                        C3 = 2.48015872894767294178e-05, C4 = -2.75573143513906633035e-07,
                        C5 = 2.08757232129817482790e-09, C6 = -1.13596475577881948265e-11;
    static const double INV_PIO2 = 6.36619772367581382433e-01, PIO2_1 = 1.57079632673412561417e+00,
                        PIO2_2 = 6.07710050630396597660e-11, PIO2_3 = 2.02226624871116645580e-21;
    int i, l;
    UNROLL
    for (i = 0; i < n; i++) {
        li small = vabs(x[i]) < splat(1e5), odd;
        lv xi = sel(small, x[i], splat(0.0)), fn, r, z, hz, w, s, c;
        lu k; /* fn's two's complement low bits (fn + 1.5 * 2^52 is exact), for the quadrant */
        /* the scalar (long) cast: rounded toward zero (mode 3), in the vector unit (|fn| < 2^17) */
        fn = __builtin_ia32_roundpd256(xi * INV_PIO2 + sel(xi >= splat(0.0), splat(0.5), splat(-0.5)), 3);
        k = (lu)(fn + 0x1.8p52);
        r = ((xi - fn * PIO2_1) - fn * PIO2_2) - fn * PIO2_3;
        z = r * r;
        s = r + z * r * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))));
        hz = 0.5 * z;
        w = 1.0 - hz;
        c = w + (((1.0 - w) - hz) + z * z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6))))));
        odd = (k & 1) != (lu)splat_i(0);
        s_out[i] = (lv)((lu)sel(odd, c, s) ^ ((lu)((k >> 1) & 1) << 63));
        c_out[i] = (lv)((lu)sel(odd, s, c) ^ ((lu)(((k + 1) >> 1) & 1) << 63));
        if (!any(small == splat_i(0))) continue;
        for (l = 0; l < LANES; l++)
            if (!small[l]) {
                s_out[i][l] = sin(x[i][l]);
                c_out[i][l] = cos(x[i][l]);
            }
    }
}

/* lm_kernel.c's forward: tool R, p and the geometric Jacobian, the angular rows times w. */
HOT void forward_lanes(const lm_chain *c, int n, const lv *q, lane_eval *ev, double w) {
    lv col[3][3], org[MAXJ][3], ax[MAXJ][3], cosv[MAXJ], sinv[MAXJ], angle[MAXJ], *p = ev->p;
    int i, j, k;
    UNROLL
    for (i = 0; i < n; i++) angle[i] = c->offset[i] + c->scale[i] * q[i];
    sin_cos_lanes(n, angle, sinv, cosv);
    UNROLL
    for (j = 0; j < 3; j++) {
        UNROLL
        for (k = 0; k < 3; k++) col[j][k] = splat(c->consts[0][4 * k + j]);
        p[j] = splat(c->consts[0][4 * j + 3]);
    }
    UNROLL
    for (i = 0; i < n; i++) {
        const double *C = c->consts[i + 1];
        lv v = c->offset[i] + c->scale[i] * q[i], nc[3][3], np_[3];
        UNROLL
        for (k = 0; k < 3; k++) { ax[i][k] = col[2][k]; org[i][k] = p[k]; }
        if (c->kind[i] == LM_PRISMATIC) {
            UNROLL
            for (k = 0; k < 3; k++) p[k] += v * col[2][k];
        } else {
            lv cs = cosv[i], sn = sinv[i], x, y;
            UNROLL
            for (k = 0; k < 3; k++) {
                x = col[0][k]; y = col[1][k];
                col[0][k] = cs * x + sn * y;
                col[1][k] = cs * y - sn * x;
            }
        }
        UNROLL
        for (k = 0; k < 3; k++) {
            np_[k] = p[k] + col[0][k] * C[3] + col[1][k] * C[7] + col[2][k] * C[11];
            UNROLL
            for (j = 0; j < 3; j++) nc[j][k] = col[0][k] * C[j] + col[1][k] * C[4 + j] + col[2][k] * C[8 + j];
        }
        UNROLL
        for (k = 0; k < 3; k++) {
            p[k] = np_[k];
            UNROLL
            for (j = 0; j < 3; j++) col[j][k] = nc[j][k];
        }
    }
    UNROLL
    for (j = 0; j < 3; j++)
        UNROLL
        for (k = 0; k < 3; k++) ev->R[k][j] = col[j][k];
    UNROLL
    for (i = 0; i < n; i++) {
        const lv *z = ax[i];
        lv d[3];
        double s = c->scale[i];
        UNROLL
        for (k = 0; k < 3; k++) d[k] = p[k] - org[i][k];
        if (c->kind[i] == LM_PRISMATIC) {
            UNROLL
            for (k = 0; k < 3; k++) { ev->J[k][i] = s * z[k]; ev->J[3 + k][i] = splat(0.0); }
        } else {
            ev->J[0][i] = s * (z[1] * d[2] - z[2] * d[1]);
            ev->J[1][i] = s * (z[2] * d[0] - z[0] * d[2]);
            ev->J[2][i] = s * (z[0] * d[1] - z[1] * d[0]);
            UNROLL
            for (k = 0; k < 3; k++) ev->J[3 + k][i] = w * (s * z[k]);
        }
    }
}

/* lm_kernel.c's atan2_upper, lane-wise: each lane's reduction interval picked by selects, one
 * division for all; a lane with a special argument (zero, NaN, infinite, huge ratio) is redone by
 * the scalar function. */
HOT void atan2_lanes(const lv *yp, const lv *xp, lv *outp) {
    static const double T[11] = {3.33333333333329318027e-01, -1.99999999998764832476e-01,
                                 1.42857142725034663711e-01, -1.11111104054623557880e-01,
                                 9.09088713343650656196e-02, -7.69187620504482999495e-02,
                                 6.66107313738753120669e-02, -5.83357013379057348645e-02,
                                 4.97687799461593236017e-02, -3.65315727442169155270e-02,
                                 1.62858201153657823623e-02};
    static const double PI_HI = 3.1415926535897931160e+00, PI_LO = 1.2246467991473531772e-16;
    lv y = *yp, x = *xp, t = y / vabs(x), num, den, hi, lo, z, w, s1, s2, r, out;
    li a = t < splat(0.4375), b = t < splat(0.6875), c = t < splat(1.1875), d = t < splat(2.4375);
    li special = ~(y >= splat(0.0)) | ~(vabs(x) < splat(1e300)) | ~(y < splat(1e300)) | (y == splat(0.0))
                 | (x == splat(0.0)) | (t > splat(1e18));
    int l;
    num = sel(a, t, sel(b, 2.0 * t - 1.0, sel(c, t - 1.0, sel(d, t - 1.5, splat(-1.0)))));
    den = sel(a, splat(1.0), sel(b, 2.0 + t, sel(c, t + 1.0, sel(d, 1.0 + 1.5 * t, t))));
    hi = sel(b, splat(4.63647609000806093515e-01), sel(c, splat(7.85398163397448278999e-01),
             sel(d, splat(9.82793723247329054082e-01), splat(1.57079632679489655800e+00))));
    lo = sel(b, splat(2.26987774529616870924e-17), sel(c, splat(3.06161699786838301793e-17),
             sel(d, splat(1.39033110312309984516e-17), splat(6.12323399573676603587e-17))));
    t = num / den; /* exact for the first interval: t / 1 */
    z = t * t;
    w = z * z;
    s1 = z * (T[0] + w * (T[2] + w * (T[4] + w * (T[6] + w * (T[8] + w * T[10])))));
    s2 = w * (T[1] + w * (T[3] + w * (T[5] + w * (T[7] + w * T[9]))));
    r = sel(a, t - t * (s1 + s2), hi - ((t * (s1 + s2) - lo) - t));
    out = sel(x > splat(0.0), r, PI_HI - (r - PI_LO));
    if (any(special))
        for (l = 0; l < LANES; l++)
            if (special[l]) out[l] = lm_atan2_upper(y[l], x[l]);
    *outp = out;
}

/* lm_kernel.c's rotation_log, lane-wise; a lane near a half turn takes the scalar function. */
HOT void rotation_log_lanes(lv Rerr[3][3], lv out[3]) {
    lv v[3], s, c, f, angle;
    li near_pi;
    int j, k, l;
    v[0] = 0.5 * (Rerr[2][1] - Rerr[1][2]);
    v[1] = 0.5 * (Rerr[0][2] - Rerr[2][0]);
    v[2] = 0.5 * (Rerr[1][0] - Rerr[0][1]);
    s = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    vsqrt(&s);
    c = 0.5 * (Rerr[0][0] + Rerr[1][1] + Rerr[2][2] - 1.0);
    atan2_lanes(&s, &c, &angle);
    f = sel(s > splat(1e-300), angle / s, splat(1.0));
    for (k = 0; k < 3; k++) out[k] = v[k] * f;
    near_pi = (c < splat(0.0)) & (s < splat(1e-6));
    if (!any(near_pi)) return;
    for (l = 0; l < LANES; l++) {
        double M[3][3], o[3];
        if (!near_pi[l]) continue;
        for (j = 0; j < 3; j++)
            for (k = 0; k < 3; k++) M[j][k] = Rerr[j][k][l];
        lm_rotation_log(M, o);
        for (k = 0; k < 3; k++) out[k][l] = o[k];
    }
}

/* lm_kernel.c's evaluate in pose mode: FK, weighted task error and Jacobian, residuals, cost. */
HOT void evaluate_lanes(const lm_chain *c, int n, const lanes *st, const lv *q, lane_eval *ev) {
    lv d2 = splat(0.0), Rerr[3][3], er[3], f2 = splat(0.0), chord;
    int j, k, l;
    forward_lanes(c, n, q, ev, c->weight);
    UNROLL
    for (k = 0; k < 3; k++) {
        ev->e[k] = st->tp[k] - ev->p[k];
        d2 += ev->e[k] * ev->e[k];
    }
    vsqrt(&d2);
    ev->pos = d2;
    UNROLL
    for (j = 0; j < 3; j++)
        UNROLL
        for (k = 0; k < 3; k++) {
            const lv *tR = st->tR;
            Rerr[j][k] = tR[3 * j] * ev->R[k][0] + tR[3 * j + 1] * ev->R[k][1] + tR[3 * j + 2] * ev->R[k][2];
            f2 += (ev->R[j][k] - tR[3 * j + k]) * (ev->R[j][k] - tR[3 * j + k]);
        }
    rotation_log_lanes(Rerr, er);
    UNROLL
    for (k = 0; k < 3; k++) ev->e[3 + k] = c->weight * er[k];
    vsqrt(&f2);
    chord = f2 / sqrt(2.0);
    for (l = 0; l < LANES; l++) ev->rot[l] = 2.0 * asin(fmin(chord[l] / 2.0, 1.0));
    ev->cost = splat(0.0);
    UNROLL
    for (k = 0; k < TASK; k++) ev->cost += ev->e[k] * ev->e[k];
    ev->cost *= 0.5;
}

/* lm_kernel.c's ldl_solve, lane-wise; a lane with a non-positive pivot gets a zero step (its
 * pivot replaced by 1 so that the other lanes' arithmetic runs on). */
HOT void ldl_lanes(lv A[MAXJ][MAXJ], lv *b, int k) {
    lv inv[MAXJ], L[MAXJ][MAXJ], Ld[MAXJ][MAXJ];
    li bad = splat_i(0);
    int i, j, r;
    UNROLL
    for (j = 0; j < k; j++) {
        lv s = A[j][j];
        li ok;
        UNROLL
        for (r = 0; r < j; r++) s -= Ld[j][r] * L[j][r];
        ok = s > splat(0.0);
        bad |= ~ok;
        inv[j] = 1.0 / sel(ok, s, splat(1.0));
        UNROLL
        for (i = j + 1; i < k; i++) {
            lv t = A[i][j];
            UNROLL
            for (r = 0; r < j; r++) t -= L[i][r] * Ld[j][r];
            Ld[i][j] = t;
            L[i][j] = t * inv[j];
        }
    }
    UNROLL
    for (i = 0; i < k; i++)
        UNROLL
        for (r = 0; r < i; r++) b[i] -= L[i][r] * b[r];
    UNROLL
    for (i = 0; i < k; i++) b[i] *= inv[i];
    UNROLL
    for (i = k - 1; i >= 0; i--)
        UNROLL
        for (r = i + 1; r < k; r++) b[i] -= L[r][i] * b[r];
    UNROLL
    for (i = 0; i < k; i++) b[i] = sel(bad, splat(0.0), b[i]);
}

/* lm_kernel.c's damped_step for m = n = 6: h = (J^T J + mu I)^-1 J^T e; the predicted decrease. */
HOT void damped_lanes(const lane_eval *ev, int n, const lv *mup, lv *h, lv *predp) {
    lv A[MAXJ][MAXJ], g[MAXJ], pred = splat(0.0), mu = *mup;
    int i, j, r;
    UNROLL
    for (i = 0; i < n; i++) {
        g[i] = splat(0.0);
        UNROLL
        for (r = 0; r < TASK; r++) g[i] += ev->J[r][i] * ev->e[r];
    }
    UNROLL
    for (i = 0; i < n; i++) {
        h[i] = g[i];
        UNROLL
        for (j = 0; j <= i; j++) {
            lv s = splat(0.0);
            UNROLL
            for (r = 0; r < TASK; r++) s += ev->J[r][i] * ev->J[r][j];
            A[i][j] = s + (i == j ? mu : splat(0.0));
        }
    }
    ldl_lanes(A, h, n);
    UNROLL
    for (i = 0; i < n; i++) pred += h[i] * (mu * h[i] + g[i]);
    *predp = 0.5 * pred;
}

/* lm_kernel.c's clamp_joints, lane-wise (fmax and fmin as glibc's x86-64 maxsd / minsd); a wrapped
 * joint out of its turn is wrapped by the scalar mod. */
HOT void clamp_lanes(const lm_chain *c, int n, lv *q) {
    int i, l;
    UNROLL
    for (i = 0; i < n; i++) {
        lv lower = splat(c->lower[i]), upper = splat(c->upper[i]);
        if (c->kind[i] == LM_WRAPPED) {
            lv t = q[i] - lower;
            li inside = (t >= splat(0.0)) & (t < splat(2.0 * LM_PI));
            if (any(~inside))
                for (l = 0; l < LANES; l++)
                    if (!inside[l]) t[l] = lm_py_mod(t[l], 2.0 * LM_PI);
            q[i] = lower + t;
        } else {
            lv up = sel(q[i] > lower, q[i], lower);
            q[i] = sel(up < upper, up, upper);
        }
    }
}

static int below(double pos, double rot, double tol) { return pos <= tol && !(rot > tol); }

/* lm_kernel.c's stopping rules for a lane's row after `it` steps. */
static int lane_done(const lm_params *pr, double pos, double rot, double nu, int it) {
    int within = pos <= pr->tol_cm && !(rot > pr->tol_rad), close = below(pos, rot, pr->close);
    return below(pos, rot, pr->stop) || nu > 1e6 || (it >= pr->iterations && !close) || it == pr->extra * pr->iterations
           || (within && nu >= 16) || (it >= pr->give_up && !below(pos, rot, pr->hopeless));
}

typedef struct { /* the rows, as lm_solve_rows takes them */
    size_t count;
    const long long *rows;
    const double *target_p, *target_R, *q0;
    double *q, *pos, *rot;
    long long *iters;
} lane_io;

/* Lane l takes row r: its start and target; its next evaluation is at the start. */
static void load_lane(lanes *st, int n, int l, size_t r, const lane_io *io) {
    size_t t = (size_t)io->rows[r];
    int i, k;
    st->row[l] = (long long)r;
    st->it[l] = 0;
    st->fresh[l] = -1;
    for (i = 0; i < n; i++) st->q[i][l] = io->q0[(size_t)n * r + i];
    for (k = 0; k < 3; k++) st->tp[k][l] = io->target_p[3 * t + k];
    for (k = 0; k < 9; k++) st->tR[k][l] = io->target_R[9 * t + k];
}

/* After an evaluation: a fresh lane starts its row there (damping from the Jacobian's largest
 * column), the others accept or reject their step by the gain ratio (Nielsen), as solve_row. */
HOT void accept_lanes(lanes *st, int n, double damping) {
    lv dmax = splat(0.0), rho, t, grow;
    li acc, take;
    int i, r, l;
    if (any(st->fresh)) { /* the damping of a lane starting its row */
        UNROLL
        for (i = 0; i < n; i++) {
            lv s = splat(0.0);
            UNROLL
            for (r = 0; r < TASK; r++) s += st->nxt.J[r][i] * st->nxt.J[r][i];
            dmax = vfmax(dmax, s);
        }
    }
    rho = (st->cur.cost - st->nxt.cost) / vfmax(st->pred, splat(1e-300));
    acc = (rho > splat(0.0)) & ~st->fresh;
    take = acc | st->fresh;
    t = 2.0 * rho - 1.0;
    grow = st->mu * vfmax(splat(1.0 / 3.0), 1.0 - t * t * t);
    st->mu = sel(st->fresh, damping * dmax + 1e-300, sel(acc, grow, st->mu * st->nu));
    st->nu = sel(take, splat(2.0), st->nu * 2.0);
    UNROLL
    for (i = 0; i < n; i++) st->q[i] = sel(take, st->x[i], st->q[i]);
    UNROLL
    for (r = 0; r < TASK; r++) {
        st->cur.e[r] = sel(take, st->nxt.e[r], st->cur.e[r]);
        UNROLL
        for (i = 0; i < n; i++) st->cur.J[r][i] = sel(take, st->nxt.J[r][i], st->cur.J[r][i]);
    }
    st->cur.pos = sel(take, st->nxt.pos, st->cur.pos);
    st->cur.rot = sel(take, st->nxt.rot, st->cur.rot);
    st->cur.cost = sel(take, st->nxt.cost, st->cur.cost);
    for (l = 0; l < LANES; l++) {
        st->it[l] += !st->fresh[l];
        st->fresh[l] = st->row[l] < 0 ? -1 : 0; /* an idle lane re-evaluates its last start */
    }
}

/* Lanes whose row stopped: write it out and take the next row (or idle). Returns the lanes left busy. */
static int retire_lanes(lanes *st, int n, const lm_params *pr, size_t *next, const lane_io *io) {
    int l, i, busy = 0;
    for (l = 0; l < LANES; l++) {
        size_t r = (size_t)st->row[l];
        if (st->row[l] < 0) continue;
        if (lane_done(pr, st->cur.pos[l], st->cur.rot[l], st->nu[l], st->it[l])) {
            for (i = 0; i < n; i++) io->q[(size_t)n * r + i] = st->q[i][l];
            io->pos[r] = st->cur.pos[l];
            io->rot[r] = st->cur.rot[l];
            io->iters[r] = st->it[l];
            st->row[l] = -1;
            st->fresh[l] = -1;
            if (*next < io->count) load_lane(st, n, l, (*next)++, io);
        }
        busy += st->row[l] >= 0;
    }
    return busy;
}

/* Every row of io with n joints (a constant at the call below: the loops unroll fully). */
HOT void solve_lanes_n(const lm_chain *c, int n, const lm_params *pr, const lane_io *io) {
    lanes st = {0};
    size_t next = 0;
    int i, l, busy = 1;
    for (l = 0; l < LANES; l++) {
        st.row[l] = -1;
        st.fresh[l] = -1;
        st.tR[0][l] = st.tR[4][l] = st.tR[8][l] = 1.0; /* an idle lane's target: a valid rotation */
        if (next < io->count) load_lane(&st, n, l, next++, io);
    }
    while (io->count && busy) {
        UNROLL
        for (i = 0; i < n; i++) st.x[i] = st.q[i] + sel(st.fresh, splat(0.0), st.h[i]);
        clamp_lanes(c, n, st.x);
        UNROLL
        for (i = 0; i < n; i++) st.x[i] = sel(st.fresh, st.q[i], st.x[i]); /* a start is not clamped */
        evaluate_lanes(c, n, &st, st.x, &st.nxt);
        accept_lanes(&st, n, pr->damping);
        busy = retire_lanes(&st, n, pr, &next, io);
        damped_lanes(&st.cur, n, &st.mu, st.h, &st.pred);
    }
}

__attribute__((target("avx2"))) /* callers check the CPU */
void lm_solve_lanes(const lm_chain *chain, const lm_params *params, size_t count, const long long *rows,
                    const double *target_p, const double *target_R, const double *q0, double *q, double *pos,
                    double *rot, long long *iters) {
    lane_io io;
    io.count = count;
    io.rows = rows;
    io.target_p = target_p;
    io.target_R = target_R;
    io.q0 = q0;
    io.q = q;
    io.pos = pos;
    io.rot = rot;
    io.iters = iters;
    solve_lanes_n(chain, 6, params, &io); /* n = 6: checked by the caller */
}
#else
typedef int lm_lanes_absent; /* ISO C wants a declaration in every file */
#endif
