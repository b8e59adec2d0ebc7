/*
 * The B-spline kind (issue 21) against an independent long-double
 * reference: the not-a-knot interpolant defined by its equations (one
 * interpolation row per data point, the fourth difference of the uniform
 * B-spline coefficients zero at knots 1 and N-1; for 2 and 3 points the
 * line and the parabola through them, as SciPy's CubicSpline and MATLAB's
 * spline), solved by dense Gaussian elimination with partial pivoting per
 * line length and evaluated with the textbook uniform cubic B-spline basis.
 * Data are exact 6-decimal numbers: the reference sees the decimals, the
 * core their rounding (Q24 coordinates, Q30 memberships), so an error
 * below includes input rounding.
 *
 * Goals (issue 21): memberships within 2e-7, coordinates within
 * 1e-6 max|coordinate| + 1e-7, for grids 2x2 .. 9x9 (every size pair), 64x64
 * and 256x256, smooth, rough and extreme (+-IT2N_COORD_LIMIT) data; update
 * bit-identical to a full solve; sampling bit-identical to eval; every
 * rejected input changes nothing.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "it2n.h"
#include "it2n_internal.h"
#include "tc_util.h"

__extension__ typedef __int128 tb_i128;
__extension__ typedef unsigned __int128 tb_u128;

#define NFP IT2N_FP_COUNT
#define NCH IT2N_CH_COUNT
#define TOL_MEMB 2e-7L
#define TOL_COORD_REL 1e-6L
#define TOL_COORD_ABS 1e-7L

/* ---- reference: one line length ----------------------------------------- */

typedef struct bref_lu {
    unsigned dim;       /* N + 3 unknowns c_{-1}..c_{N+1} */
    long double *a;     /* LU, unit lower triangle below the diagonal */
    unsigned *piv;      /* row swapped in at step k */
    unsigned *lo, *hi;  /* nonzero extent of L and U per row */
} bref_lu;

static bref_lu *lu_cache[256];

/* The defining equations of the interpolant for N intervals. */
static void bref_system(unsigned N, long double *A)
{
    unsigned d = N + 3u, i, k;
    memset(A, 0, sizeof(*A) * d * d);
    for (i = 0; i <= N; i++) { /* S(u_i) = (c_{i-1} + 4 c_i + c_{i+1}) / 6 */
        A[i * d + i] = 1.0L / 6.0L;
        A[i * d + i + 1] = 4.0L / 6.0L;
        A[i * d + i + 2] = 1.0L / 6.0L;
    }
    if (N >= 3u) { /* no jump of S''' at knots 1 and N-1 */
        static const long double d4[5] = {1, -4, 6, -4, 1};
        for (k = 0; k < 5; k++) {
            A[(N + 1u) * d + k] = d4[k];
            A[(N + 2u) * d + (N - 2u) + k] = d4[k];
        }
    } else if (N == 2u) { /* S''' = 0 on both spans: a parabola */
        static const long double d3[4] = {-1, 3, -3, 1};
        for (k = 0; k < 4; k++) {
            A[3u * d + k] = d3[k];
            A[4u * d + 1u + k] = d3[k];
        }
    } else { /* S'' = 0 at both ends: a line */
        static const long double d2[3] = {1, -2, 1};
        for (k = 0; k < 3; k++) {
            A[2u * d + k] = d2[k];
            A[3u * d + 1u + k] = d2[k];
        }
    }
}

static const bref_lu *bref_lu_get(unsigned N)
{
    bref_lu *f;
    unsigned d = N + 3u, i, j, k;
    if (lu_cache[N] != NULL) {
        return lu_cache[N];
    }
    f = calloc(1, sizeof(*f));
    assert_non_null(f);
    f->dim = d;
    f->a = malloc(sizeof(long double) * d * d);
    f->piv = malloc(sizeof(unsigned) * d);
    f->lo = malloc(sizeof(unsigned) * d);
    f->hi = malloc(sizeof(unsigned) * d);
    assert_true(f->a && f->piv && f->lo && f->hi);
    bref_system(N, f->a);
    for (k = 0; k < d; k++) {
        unsigned p = k;
        long double *A = f->a;
        for (i = k + 1; i < d; i++) {
            if (fabsl(A[i * d + k]) > fabsl(A[p * d + k])) {
                p = i;
            }
        }
        assert_true(A[p * d + k] != 0.0L);
        f->piv[k] = p;
        if (p != k) {
            for (j = 0; j < d; j++) {
                long double t = A[k * d + j];
                A[k * d + j] = A[p * d + j];
                A[p * d + j] = t;
            }
        }
        for (i = k + 1; i < d; i++) {
            long double l = A[i * d + k] / A[k * d + k];
            if (l == 0.0L) {
                continue;
            }
            A[i * d + k] = l;
            for (j = k + 1; j < d; j++) {
                A[i * d + j] -= l * A[k * d + j];
            }
        }
    }
    for (i = 0; i < d; i++) {
        f->lo[i] = i;
        for (j = 0; j < i; j++) {
            if (f->a[i * d + j] != 0.0L) {
                f->lo[i] = j;
                break;
            }
        }
        f->hi[i] = i;
        for (j = d; j-- > i + 1;) {
            if (f->a[i * d + j] != 0.0L) {
                f->hi[i] = j;
                break;
            }
        }
    }
    lu_cache[N] = f;
    return f;
}

/* c[0..N+2] = coefficients of the interpolant of y[0..N]. */
static void bref_line(unsigned N, const long double *y, long double *c)
{
    const bref_lu *f = bref_lu_get(N);
    unsigned d = f->dim, i, j;
    for (i = 0; i < d; i++) {
        c[i] = i <= N ? y[i] : 0.0L;
    }
    for (i = 0; i < d; i++) {
        long double t = c[i];
        c[i] = c[f->piv[i]];
        c[f->piv[i]] = t;
        for (j = f->lo[i]; j < i; j++) {
            c[i] -= f->a[i * d + j] * c[j];
        }
    }
    for (i = d; i-- > 0;) {
        for (j = i + 1; j <= f->hi[i]; j++) {
            c[i] -= f->a[i * d + j] * c[j];
        }
        c[i] /= f->a[i * d + i];
    }
}

/* ---- reference: one surface ------------------------------------------- */

typedef struct bref_net {
    unsigned n, m;
    long double *c; /* (n+3) x (m+3) */
} bref_net;

/* Solve the net of data f[i (m+1) + j]. */
static void bref_net_solve(bref_net *r, unsigned n, unsigned m,
                           const long double *f)
{
    unsigned i, j, w = m + 3u;
    long double *g = malloc(sizeof(long double) * (n + 1u) * w);
    long double col[259], out[259];
    assert_non_null(g);
    r->n = n;
    r->m = m;
    r->c = malloc(sizeof(long double) * (n + 3u) * w);
    assert_non_null(r->c);
    for (i = 0; i <= n; i++) {
        bref_line(m, f + i * (m + 1u), g + i * w);
    }
    for (j = 0; j < w; j++) {
        for (i = 0; i <= n; i++) {
            col[i] = g[i * w + j];
        }
        bref_line(n, col, out);
        for (i = 0; i < n + 3u; i++) {
            r->c[i * w + j] = out[i];
        }
    }
    free(g);
}

static void bref_basis(unsigned N, long double u, unsigned *k, long double b[4],
                       long double db[4])
{
    long double x = u * N, t;
    unsigned s = (unsigned)floorl(x);
    if (s >= N) {
        s = N - 1u;
    }
    t = x - s;
    *k = s;
    b[0] = (1 - t) * (1 - t) * (1 - t) / 6;
    b[1] = (3 * t * t * t - 6 * t * t + 4) / 6;
    b[2] = (-3 * t * t * t + 3 * t * t + 3 * t + 1) / 6;
    b[3] = t * t * t / 6;
    db[0] = -(1 - t) * (1 - t) / 2 * N;
    db[1] = (3 * t * t / 2 - 2 * t) * N;
    db[2] = (-3 * t * t / 2 + t + 0.5L) * N;
    db[3] = t * t / 2 * N;
}

/* Value (which 0), d/du (1) or d/dw (2) at (u, w). */
static long double bref_eval(const bref_net *r, long double u, long double w,
                             int which)
{
    long double bu[4], bw[4], dbu[4], dbw[4], s = 0;
    unsigned k, l, a, b;
    bref_basis(r->n, u, &k, bu, dbu);
    bref_basis(r->m, w, &l, bw, dbw);
    for (a = 0; a < 4; a++) {
        for (b = 0; b < 4; b++) {
            long double cu = which == 1 ? dbu[a] : bu[a];
            long double cw = which == 2 ? dbw[b] : bw[b];
            s += cu * cw * r->c[(k + a) * (r->m + 3u) + l + b];
        }
    }
    return s;
}

/* ---- test data --------------------------------------------------------- */

typedef struct bcase {
    unsigned n, m, flags;
    long double *v;        /* exact decimals [(i (m+1) + j) NFP + fp] NCH + ch */
    it2n_val *q;           /* their rounding, fine layout (Q30 T, I, F) */
    it2n_bspline_rec *rec;
    int32_t *coef;
    it2n_bspline_data ds;
    it2n_bspline_model mdl;
    bref_net ref[NFP][NCH];
    long double maxabs;    /* largest |coordinate| */
} bcase;

static size_t vidx(const bcase *c, unsigned i, unsigned j, unsigned fp,
                   unsigned ch)
{
    return (((size_t)i * (c->m + 1u) + j) * NFP + fp) * NCH + ch;
}

/* x rounded to 6 decimals: exact value into *exact, channel ch's format in
 * the fine layout (Q24 coordinates, Q30 memberships; ties away). */
static it2n_val dec6(unsigned ch, long double x, long double *exact)
{
    long long k = llroundl(x * 1e6L);
    tb_i128 num = (tb_i128)k * (ch >= IT2N_CH_T ? 1073741824 : 16777216), q;
    *exact = (long double)k / 1e6L;
    q = (num + (num >= 0 ? 500000 : -500000)) / 1000000;
    return (it2n_val)q;
}

static bool has_fp(unsigned flags, unsigned fp)
{
    return !(flags & IT2N_F_TYPE1) || fp == IT2N_FP_D;
}

static bool has_ch(unsigned flags, unsigned ch)
{
    return ch != IT2N_CH_Z || (flags & IT2N_F_Z);
}

enum { GEN_SMOOTH, GEN_ROUGH, GEN_EXTREME };

/* Fill a case: smooth (a wavy sheet of extent scale), rough (independent
 * random values) or extreme (alternating +-COORD_LIMIT, memberships 0/1). */
static void bcase_gen(bcase *c, unsigned n, unsigned m, unsigned flags,
                      int kind, long double scale, uint64_t seed)
{
    size_t cnt = (size_t)(n + 1u) * (m + 1u) * NFP * NCH;
    const long double lim = IT2N_COORD_LIMIT - 1;
    uint64_t s = seed;
    unsigned i, j, fp, ch;
    memset(c, 0, sizeof(*c));
    c->n = n;
    c->m = m;
    c->flags = flags;
    c->v = calloc(cnt, sizeof(long double));
    c->q = calloc(cnt, sizeof(it2n_val));
    assert_true(c->v && c->q);
    for (i = 0; i <= n; i++) {
        for (j = 0; j <= m; j++) {
            long double u = (long double)i / n, w = (long double)j / m;
            long double base[NCH], spread = 0;
            for (ch = 0; ch < NCH; ch++) {
                long double r = (long double)(tc_rand(&s) >> 11) / 9007199254740992.0L;
                switch (kind) {
                case GEN_SMOOTH:
                    base[ch] = ch == 0 ? scale * (u + 0.05L * sinl(3 * w + ch))
                             : ch == 1 ? scale * (w + 0.05L * cosl(2 * u))
                             : ch == 2 ? scale * 0.3L * sinl(2.5L * u + 1.5L * w)
                             : 0.5L + 0.35L * sinl(2.1L * u + 1.3L * w + ch);
                    spread = scale / 40;
                    break;
                case GEN_ROUGH:
                    base[ch] = ch <= 2 ? scale * (2 * r - 1) * 0.9L : 0.06L + 0.88L * r;
                    spread = scale / 40;
                    break;
                default:
                    base[ch] = ch <= 2 ? (((i + j + ch) & 1u) ? lim : -lim)
                             : (long double)((i + 2 * j + ch) & 1u);
                    spread = 0;
                    break;
                }
            }
            for (fp = 0; fp < NFP; fp++) {
                if (!has_fp(flags, fp)) {
                    continue;
                }
                for (ch = 0; ch < NCH; ch++) {
                    long double x = base[ch], e;
                    size_t k = vidx(c, i, j, fp, ch);
                    if (!has_ch(flags, ch)) {
                        continue;
                    }
                    if (ch <= 2) { /* nested: LL <= LR <= ... <= RR */
                        x += spread * ((long double)fp - 3);
                    } else if (kind != GEN_EXTREME) {
                        x += 0.02L * ((long double)fp - 3);
                    }
                    c->q[k] = dec6(ch, x, &e);
                    c->v[k] = e;
                    if (ch <= 2 && fabsl(e) > c->maxabs) {
                        c->maxabs = fabsl(e);
                    }
                }
            }
        }
    }
}

static void bcase_vals(const bcase *c, unsigned i, unsigned j, unsigned fp,
                       it2n_val vals[NCH])
{
    unsigned ch;
    for (ch = 0; ch < NCH; ch++) {
        vals[ch] = c->q[vidx(c, i, j, fp, ch)];
    }
}

/* Core data set and model of the case (asserts success). */
static void bcase_core(bcase *c)
{
    size_t recs = IT2N_BSPLINE_DATA_RECS(c->n, c->m, c->flags);
    size_t words = IT2N_BSPLINE_MODEL_WORDS(c->n, c->m, c->flags);
    it2n_errinfo err;
    unsigned i, j, fp;
    c->rec = malloc(recs * sizeof(*c->rec));
    c->coef = malloc(words * sizeof(*c->coef));
    assert_true(c->rec && c->coef);
    assert_int_equal(it2n_bspline_data_init(&c->ds, c->rec, recs, c->n, c->m,
                                            c->flags, &err), IT2N_OK);
    for (i = 0; i <= c->n; i++) {
        for (j = 0; j <= c->m; j++) {
            for (fp = 0; fp < NFP; fp++) {
                it2n_val vals[NCH];
                if (!has_fp(c->flags, fp)) {
                    continue;
                }
                bcase_vals(c, i, j, fp, vals);
                assert_int_equal(it2n_bspline_data_put_fine(&c->ds, i, j, fp, vals,
                                                            false, &err), IT2N_OK);
            }
        }
    }
    it2n_bspline_model_init(&c->mdl, c->coef, words);
    if (it2n_bspline_solve(&c->mdl, &c->ds, &err) != IT2N_OK) {
        fail_msg("solve %ux%u: %d at (%d,%d) fp %d ch %d", c->n, c->m, err.code,
                 err.i, err.j, err.fp, err.ch);
    }
}

static void bcase_ref(bcase *c)
{
    long double *f = malloc(sizeof(long double) * (c->n + 1u) * (c->m + 1u));
    unsigned i, j, fp, ch;
    assert_non_null(f);
    for (fp = 0; fp < NFP; fp++) {
        for (ch = 0; ch < NCH; ch++) {
            if (!has_fp(c->flags, fp) || !has_ch(c->flags, ch)) {
                continue;
            }
            for (i = 0; i <= c->n; i++) {
                for (j = 0; j <= c->m; j++) {
                    f[i * (c->m + 1u) + j] = c->v[vidx(c, i, j, fp, ch)];
                }
            }
            bref_net_solve(&c->ref[fp][ch], c->n, c->m, f);
        }
    }
    free(f);
}

static void bcase_free(bcase *c)
{
    unsigned fp, ch;
    for (fp = 0; fp < NFP; fp++) {
        for (ch = 0; ch < NCH; ch++) {
            free(c->ref[fp][ch].c);
        }
    }
    free(c->v);
    free(c->q);
    free(c->rec);
    free(c->coef);
}

typedef struct worst {
    long double memb, coord_rel; /* worst error, worst error / tolerance */
    long double coord;
    unsigned long checks;
} worst;

/* Compare core and reference at (u, w) for every net. */
static void check_point(const bcase *c, it2n_par uq, it2n_par wq, worst *wo)
{
    it2n_point pt;
    long double u = tc_ldp(uq), w = tc_ldp(wq);
    unsigned fp, ch;
    int rc = it2n_bspline_eval(&c->mdl, uq, wq, &pt, NULL);
    if (rc != IT2N_OK) {
        fail_msg("eval %ux%u at (%.9Lf, %.9Lf) -> %d", c->n, c->m, u, w, rc);
    }
    for (fp = 0; fp < NFP; fp++) {
        for (ch = 0; ch < NCH; ch++) {
            long double e, tol;
            if (!has_fp(c->flags, fp) || !has_ch(c->flags, ch)) {
                continue;
            }
            e = fabsl(tc_ld(pt.v[fp][ch]) - bref_eval(&c->ref[fp][ch], u, w, 0));
            tol = ch >= IT2N_CH_T ? TOL_MEMB
                                  : TOL_COORD_REL * c->maxabs + TOL_COORD_ABS;
            if (ch >= IT2N_CH_T) {
                wo->memb = e > wo->memb ? e : wo->memb;
            } else {
                wo->coord = e > wo->coord ? e : wo->coord;
            }
            wo->coord_rel = e / tol > wo->coord_rel ? e / tol : wo->coord_rel;
            wo->checks++;
            if (e > tol) {
                fail_msg("%ux%u %s.%s at (%.9Lf, %.9Lf): core %.12Lf ref %.12Lf "
                         "err %.3Le > tol %.3Le", c->n, c->m, it2n_fp_name(fp),
                         it2n_ch_name(ch), u, w, tc_ld(pt.v[fp][ch]),
                         bref_eval(&c->ref[fp][ch], u, w, 0), e, tol);
            }
        }
    }
}

/* Grid nodes (every data point), random points, the corners. */
static void check_case(const bcase *c, unsigned randoms, bool nodes,
                       uint64_t seed, worst *wo)
{
    uint64_t s = seed;
    unsigned i, j, k;
    if (nodes) {
        for (i = 0; i <= c->n; i++) {
            for (j = 0; j <= c->m; j++) {
                /* i/n in Q32 as it2n_parse_par would round it */
                it2n_par uq = (it2n_par)(((uint64_t)i << 32) + c->n / 2u) / c->n;
                it2n_par wq = (it2n_par)(((uint64_t)j << 32) + c->m / 2u) / c->m;
                check_point(c, uq, wq, wo);
            }
        }
    }
    for (k = 0; k < randoms; k++) {
        it2n_par uq = (it2n_par)(tc_rand(&s) % (IT2N_PAR_ONE + 1));
        it2n_par wq = (it2n_par)(tc_rand(&s) % (IT2N_PAR_ONE + 1));
        if (k < 4) {
            uq = (k & 1u) ? IT2N_PAR_ONE : 0;
            wq = (k & 2u) ? IT2N_PAR_ONE : 0;
        }
        check_point(c, uq, wq, wo);
    }
}

/* Every coefficient against the exact solution of the data the core was
 * given (Q24 coordinates, Q30 memberships): the solve's own error, relative to the net's largest
 * coefficient (plus the Q24 read-out's rounding). Returns the worst. */
static long double check_coefs(const bcase *c)
{
    long double *f = malloc(sizeof(long double) * (c->n + 1u) * (c->m + 1u));
    long double cworst = 0;
    unsigned i, j, fp, ch;
    assert_non_null(f);
    for (fp = 0; fp < NFP; fp++) {
        for (ch = 0; ch < NCH; ch++) {
            bref_net r;
            long double big = 0;
            if (!has_fp(c->flags, fp) || !has_ch(c->flags, ch)) {
                continue;
            }
            for (i = 0; i <= c->n; i++) {
                for (j = 0; j <= c->m; j++) {
                    f[i * (c->m + 1u) + j] = tc_ldq(ch, c->q[vidx(c, i, j, fp, ch)]);
                }
            }
            bref_net_solve(&r, c->n, c->m, f);
            for (i = 0; i < (c->n + 3u) * (c->m + 3u); i++) {
                big = fmaxl(big, fabsl(r.c[i]));
            }
            for (i = 0; i < c->n + 3u; i++) {
                for (j = 0; j < c->m + 3u; j++) {
                    long double e = fabsl(tc_ld(it2n_bspline_coef(&c->mdl, i, j, fp, ch)) -
                                          r.c[i * (c->m + 3u) + j]);
                    long double rel = (e - 0.5L / TC_Q24) / big;
                    cworst = fmaxl(cworst, rel);
                    /* the intermediate rows' 2^-31 rounding, amplified up
                     * to 15.6 times by the column solve (end coefficients):
                     * about 2^-27; bound 2^-24 */
                    if (rel > 5.96e-8L) {
                        fail_msg("coef %ux%u %s.%s [%u][%u]: err %.3Le of max %.3Le",
                                 c->n, c->m, it2n_fp_name(fp), it2n_ch_name(ch), i,
                                 j, e, big);
                    }
                }
            }
            free(r.c);
        }
    }
    free(f);
    return cworst;
}

static void report(const char *what, const worst *wo)
{
    printf("[bspline] %-30s worst |err| memb %.3Le coord %.3Le (%.3Lf of tol); %lu checks\n",
           what, wo->memb, wo->coord, wo->coord_rel, wo->checks);
}

/* ---- tests ---------------------------------------------------------------- */

/* The pivot table is round(2^32 a_{k-1} / a_k), a_k = 4 a_{k-1} - a_{k-2}. */
static void test_pivot_table(void **state)
{
    tb_u128 a_prev = 1, a = 4;
    unsigned k;
    (void)state;
    for (k = 0; k < 30; k++) {
        tb_u128 num = a_prev << 32;
        uint32_t want = (uint32_t)((2 * num + a) / (2 * a));
        assert_int_equal(it2n__bspline_pivot_inv(k), want);
        tb_u128 next = 4 * a - a_prev;
        a_prev = a;
        a = next;
    }
}

/* The reference is the not-a-knot interpolant: it interpolates, S''' has no
 * jump at knots 1 and N-1, and it reproduces cubics (lines and parabolas
 * for N = 1, 2). */
static void test_reference_self(void **state)
{
    unsigned N;
    (void)state;
    for (N = 1; N <= 40; N++) {
        long double y[64], c[64], p[64];
        unsigned i;
        uint64_t s = N;
        for (i = 0; i <= N; i++) {
            y[i] = (long double)(tc_rand(&s) % 2001) / 1000.0L - 1.0L;
        }
        bref_line(N, y, c);
        for (i = 0; i <= N; i++) {
            long double v = (c[i] + 4 * c[i + 1] + c[i + 2]) / 6;
            assert_true(fabsl(v - y[i]) < 1e-15L);
        }
        if (N >= 3) {
            long double j1 = c[0] - 4 * c[1] + 6 * c[2] - 4 * c[3] + c[4];
            long double j2 = c[N - 2] - 4 * c[N - 1] + 6 * c[N] - 4 * c[N + 1] + c[N + 2];
            assert_true(fabsl(j1) < 1e-14L && fabsl(j2) < 1e-14L);
        }
        /* a polynomial of the largest degree the end conditions allow */
        for (i = 0; i <= N; i++) {
            long double t = (long double)i / N;
            p[i] = N >= 3 ? 1 - 2 * t + 3 * t * t - 5 * t * t * t
                 : N == 2 ? 1 - 2 * t + 3 * t * t : 1 - 2 * t;
        }
        bref_line(N, p, c);
        {
            bref_net r = {N, 1, NULL};
            long double cc[64 * 4];
            unsigned k;
            /* constant in w: c2[r][s] = c[r] */
            for (k = 0; k < N + 3; k++) {
                cc[k * 4 + 0] = cc[k * 4 + 1] = cc[k * 4 + 2] = cc[k * 4 + 3] = c[k];
            }
            r.c = cc;
            for (k = 0; k <= 50; k++) {
                long double t = k / 50.0L;
                long double want = N >= 3 ? 1 - 2 * t + 3 * t * t - 5 * t * t * t
                                 : N == 2 ? 1 - 2 * t + 3 * t * t : 1 - 2 * t;
                assert_true(fabsl(bref_eval(&r, t, 0.5L, 0) - want) < 1e-14L);
            }
        }
    }
}

/* Every size pair 1..8 x 1..8 intervals, type-1 and type-2, with and
 * without z, smooth and rough. */
static void test_small_grids(void **state)
{
    worst all = {0, 0, 0, 0}, rough = {0, 0, 0, 0};
    long double coef_worst = 0;
    unsigned n, m;
    (void)state;
    for (n = 1; n <= 8; n++) {
        for (m = 1; m <= 8; m++) {
            static const unsigned fl[4] = {0, IT2N_F_Z, IT2N_F_TYPE1,
                                           IT2N_F_TYPE1 | IT2N_F_Z};
            bcase c;
            bcase_gen(&c, n, m, fl[(n + m) & 3u], GEN_SMOOTH, 10, n * 16 + m);
            bcase_core(&c);
            bcase_ref(&c);
            check_case(&c, 60, true, n * 31 + m, &all);
            coef_worst = fmaxl(coef_worst, check_coefs(&c));
            bcase_free(&c);
            bcase_gen(&c, n, m, fl[(n + 2 * m) & 3u], GEN_ROUGH, 1000, n * 7 + m);
            bcase_core(&c);
            bcase_ref(&c);
            check_case(&c, 60, true, n * 37 + m, &rough);
            coef_worst = fmaxl(coef_worst, check_coefs(&c));
            bcase_free(&c);
        }
    }
    report("1..8 x 1..8 smooth scale 10", &all);
    report("1..8 x 1..8 rough scale 1000", &rough);
    printf("[bspline] coefficients 1..8 x 1..8: worst err %.3Le of the net's max|c| "
           "(vs the exact solution of the data given)\n", coef_worst);
}

/* Data points are interpolated and the polynomial cases match exactly
 * what SciPy's CubicSpline gives for 2 and 3 points: a line, a parabola. */
static void test_small_n_polynomials(void **state)
{
    unsigned N;
    (void)state;
    for (N = 1; N <= 3; N++) {
        static it2n_bspline_rec rec[IT2N_BSPLINE_DATA_RECS(3, 1, IT2N_F_TYPE1)];
        static int32_t coef[IT2N_BSPLINE_MODEL_WORDS(3, 1, IT2N_F_TYPE1)];
        it2n_bspline_data ds;
        it2n_bspline_model mdl;
        unsigned i, j, k;
        assert_int_equal(it2n_bspline_data_init(&ds, rec, sizeof(rec) / sizeof(rec[0]),
                                                N, 1, IT2N_F_TYPE1, NULL), IT2N_OK);
        for (i = 0; i <= N; i++) {
            for (j = 0; j <= 1; j++) {
                long double t = (long double)i / N;
                /* x = polynomial of degree N in u; T = 0.25 + 0.5 t^N/.. */
                long double x = N == 1 ? 3 - 2 * t : N == 2 ? 1 + 4 * t - 6 * t * t
                              : 1 + t - 4 * t * t + 2 * t * t * t;
                it2n_val vals[NCH] = {0};
                vals[0] = (it2n_val)llroundl(x * 16777216.0L);
                vals[1] = (it2n_val)j << 24;
                vals[3] = vals[4] = vals[5] = IT2N_VAL_ONE / 4;
                assert_int_equal(it2n_bspline_data_put(&ds, i, j, IT2N_FP_D, vals,
                                                       false, NULL), IT2N_OK);
            }
        }
        it2n_bspline_model_init(&mdl, coef, sizeof(coef) / sizeof(coef[0]));
        assert_int_equal(it2n_bspline_solve(&mdl, &ds, NULL), IT2N_OK);
        for (k = 0; k <= 64; k++) {
            it2n_point pt;
            long double t = k / 64.0L;
            long double x = N == 1 ? 3 - 2 * t : N == 2 ? 1 + 4 * t - 6 * t * t
                          : 1 + t - 4 * t * t + 2 * t * t * t;
            assert_int_equal(it2n_bspline_eval(&mdl, (it2n_par)(k * (IT2N_PAR_ONE / 64)),
                                               IT2N_PAR_ONE / 2, &pt, NULL), IT2N_OK);
            assert_true(fabsl(tc_ld(pt.v[IT2N_FP_D][0]) - x) < 1e-7L);
            assert_true(fabsl(tc_ld(pt.v[IT2N_FP_D][1]) - 0.5L) < 1e-7L);
            /* constant data stay exactly constant */
            assert_int_equal(pt.v[IT2N_FP_D][IT2N_CH_T], IT2N_VAL_ONE / 4);
        }
    }
}

/* 64 x 64 type-2 with z (42 nets): smooth at scale 1000, rough. */
static void test_64x64(void **state)
{
    worst a = {0, 0, 0, 0}, b = {0, 0, 0, 0};
    bcase c;
    (void)state;
    bcase_gen(&c, 64, 64, IT2N_F_Z, GEN_SMOOTH, 1000, 64);
    bcase_core(&c);
    bcase_ref(&c);
    check_case(&c, 400, true, 640, &a);
    bcase_free(&c);
    report("64x64 type-2 x,y,z smooth 1000", &a);
    bcase_gen(&c, 64, 64, 0, GEN_ROUGH, 5000, 65);
    bcase_core(&c);
    bcase_ref(&c);
    check_case(&c, 400, true, 650, &b);
    printf("[bspline] coefficients 64x64 rough: worst err %.3Le of the net's max|c|\n",
           check_coefs(&c));
    bcase_free(&c);
    report("64x64 type-2 x,y rough 5000", &b);
}

/* The largest grid: 256 x 256 points, type-1 with z, smooth and rough
 * near the coordinate limit. */
static void test_256x256(void **state)
{
    worst a = {0, 0, 0, 0}, b = {0, 0, 0, 0};
    bcase c;
    (void)state;
    bcase_gen(&c, 255, 255, IT2N_F_TYPE1 | IT2N_F_Z, GEN_SMOOTH, 4e6L, 256);
    bcase_core(&c);
    bcase_ref(&c);
    check_case(&c, 2000, true, 2560, &a);
    bcase_free(&c);
    report("255x255 type-1 x,y,z smooth 4e6", &a);
    bcase_gen(&c, 255, 200, IT2N_F_TYPE1, GEN_ROUGH, 8e6L, 257);
    bcase_core(&c);
    bcase_ref(&c);
    check_case(&c, 2000, false, 2570, &b);
    bcase_free(&c);
    report("255x200 type-1 x,y rough 8e6", &b);
}

/* Alternating +-COORD_LIMIT and 0/1: coefficients reach ~240 times the
 * data (the not-a-knot end coefficients) and still fit; accuracy holds. */
static void test_extreme(void **state)
{
    worst a = {0, 0, 0, 0};
    unsigned sizes[][2] = {{3, 3}, {4, 7}, {9, 9}, {16, 5}, {33, 33}};
    unsigned k;
    (void)state;
    for (k = 0; k < sizeof(sizes) / sizeof(sizes[0]); k++) {
        bcase c;
        bcase_gen(&c, sizes[k][0], sizes[k][1], k & 1u ? IT2N_F_Z : 0,
                  GEN_EXTREME, 0, 99 + k);
        bcase_core(&c);
        bcase_ref(&c);
        check_case(&c, 200, true, 990 + k, &a);
        bcase_free(&c);
    }
    report("alternating +-limit, 0/1", &a);
}

/* Derivatives against the reference's analytic derivatives. */
static void test_derivatives(void **state)
{
    static const unsigned sizes[][2] = {{1, 2}, {3, 3}, {7, 5}, {40, 40}};
    long double worst_m = 0, worst_c = 0;
    unsigned k;
    (void)state;
    for (k = 0; k < 4; k++) {
        bcase c;
        uint64_t s = 5 + k;
        unsigned q, fp, ch;
        bcase_gen(&c, sizes[k][0], sizes[k][1], IT2N_F_Z, GEN_SMOOTH, 100, 50 + k);
        bcase_core(&c);
        bcase_ref(&c);
        for (q = 0; q < 100; q++) {
            it2n_point du, dw;
            it2n_par uq = (it2n_par)(tc_rand(&s) % (IT2N_PAR_ONE + 1));
            it2n_par wq = (it2n_par)(tc_rand(&s) % (IT2N_PAR_ONE + 1));
            assert_int_equal(it2n_bspline_deriv(&c.mdl, uq, wq, &du, &dw, NULL), IT2N_OK);
            for (fp = 0; fp < NFP; fp++) {
                for (ch = 0; ch < NCH; ch++) {
                    long double tol, e1, e2;
                    unsigned big = c.n > c.m ? c.n : c.m;
                    if (!has_ch(c.flags, ch)) {
                        continue;
                    }
                    /* one knot span is 1/N: errors scale with N */
                    tol = 4 * big * (ch >= IT2N_CH_T ? TOL_MEMB
                                     : TOL_COORD_REL * c.maxabs + TOL_COORD_ABS);
                    e1 = fabsl(tc_ld(du.v[fp][ch]) -
                               bref_eval(&c.ref[fp][ch], tc_ldp(uq), tc_ldp(wq), 1));
                    e2 = fabsl(tc_ld(dw.v[fp][ch]) -
                               bref_eval(&c.ref[fp][ch], tc_ldp(uq), tc_ldp(wq), 2));
                    if (e1 > tol || e2 > tol) {
                        fail_msg("deriv %ux%u %s.%s: err %.3Le %.3Le tol %.3Le", c.n,
                                 c.m, it2n_fp_name(fp), it2n_ch_name(ch), e1, e2, tol);
                    }
                    if (ch >= IT2N_CH_T) {
                        worst_m = fmaxl(worst_m, fmaxl(e1, e2) / tol);
                    } else {
                        worst_c = fmaxl(worst_c, fmaxl(e1, e2) / tol);
                    }
                }
            }
        }
        bcase_free(&c);
    }
    printf("[bspline] derivatives: worst %.3Lf (memberships), %.3Lf (coordinates) of tolerance\n",
           worst_m, worst_c);
}

/* Updates are bit-identical to a full solve of the changed data set. */
static void test_update_vs_solve(void **state)
{
    bcase c;
    uint64_t s = 77;
    size_t words;
    int32_t *fresh;
    unsigned k;
    (void)state;
    bcase_gen(&c, 20, 13, IT2N_F_Z, GEN_SMOOTH, 50, 21);
    bcase_core(&c);
    words = IT2N_BSPLINE_MODEL_WORDS(c.n, c.m, c.flags);
    fresh = malloc(words * sizeof(*fresh));
    assert_non_null(fresh);
    for (k = 0; k < 40; k++) {
        unsigned i = (unsigned)(tc_rand(&s) % (c.n + 1u));
        unsigned j = (unsigned)(tc_rand(&s) % (c.m + 1u));
        unsigned fp = (unsigned)(tc_rand(&s) % NFP), ch;
        it2n_val vals[NCH], lo[NCH], hi[NCH];
        it2n_bspline_model m2;
        uint32_t gen = c.mdl.generation;
        /* odd steps through the _fine entry points (Q30 memberships) */
        bool fine = (k & 1u) != 0u;
        void (*get)(const it2n_bspline_data *, unsigned, unsigned, unsigned,
                    it2n_val *) = fine ? it2n_bspline_data_get_fine
                                       : it2n_bspline_data_get;
        get(&c.ds, i, j, fp, vals);
        if (fp > 0) get(&c.ds, i, j, fp - 1, lo);
        if (fp + 1 < NFP) get(&c.ds, i, j, fp + 1, hi);
        for (ch = 0; ch < NCH; ch++) {
            if (!has_ch(c.flags, ch)) {
                continue;
            }
            if (ch >= IT2N_CH_T) {
                it2n_val one = fine ? IT2N_MEMB_ONE : IT2N_VAL_ONE;
                vals[ch] = (it2n_val)(tc_rand(&s) % (uint64_t)(one + 1));
            } else {
                /* anywhere between the neighbouring footprints */
                it2n_val a = fp > 0 ? lo[ch] : vals[ch] - (IT2N_VAL_ONE << 3);
                it2n_val b = fp + 1 < NFP ? hi[ch] : vals[ch] + (IT2N_VAL_ONE << 3);
                vals[ch] = a + (it2n_val)(tc_rand(&s) % (uint64_t)(b - a + 1));
            }
        }
        assert_int_equal((fine ? it2n_bspline_update_fine : it2n_bspline_update)(
                             &c.mdl, &c.ds, i, j, fp, vals, NULL),
                         IT2N_OK);
        assert_true(c.mdl.generation != gen);
        it2n_bspline_model_init(&m2, fresh, words);
        assert_int_equal(it2n_bspline_solve(&m2, &c.ds, NULL), IT2N_OK);
        assert_memory_equal(fresh, c.coef, words * sizeof(*fresh));
        assert_memory_equal(m2.frac, c.mdl.frac, sizeof(m2.frac));
    }
    printf("[bspline] 40 chained updates 20x13 vs full solve: bit-identical\n");
    free(fresh);
    bcase_free(&c);
}

/* Same values, summary and flags (struct padding aside). */
static void point_equal(const it2n_point *a, const it2n_point *b)
{
    assert_memory_equal(a->v, b->v, sizeof(a->v));
    assert_memory_equal(&a->sum, &b->sum, sizeof(a->sum));
    assert_int_equal(a->out_of_range, b->out_of_range);
}

static int sample_cb(void *ctx, unsigned r, unsigned col, it2n_par u,
                     it2n_par w, const it2n_point *pt)
{
    const it2n_bspline_model *mdl = ctx;
    it2n_point e;
    (void)col;
    assert_int_equal(it2n_bspline_eval(mdl, u, w, &e, NULL), IT2N_OK);
    point_equal(&e, pt);
    return r == 6 && col == 3 ? 42 : 0;
}

static void test_sample(void **state)
{
    bcase c;
    (void)state;
    bcase_gen(&c, 9, 4, 0, GEN_SMOOTH, 3, 9);
    bcase_core(&c);
    assert_int_equal(it2n_bspline_sample(&c.mdl, 5, 7, sample_cb, &c.mdl, NULL), IT2N_OK);
    assert_int_equal(it2n_bspline_sample(&c.mdl, 9, 5, sample_cb, &c.mdl, NULL), 42);
    assert_int_equal(it2n_bspline_sample(&c.mdl, 1, 5, sample_cb, &c.mdl, NULL),
                     IT2N_ERR_RANGE);
    bcase_free(&c);
}

/* Every rejected input changes nothing and says why. */
static void test_validation(void **state)
{
    static it2n_bspline_rec rec[IT2N_BSPLINE_DATA_RECS(3, 3, 0)];
    static int32_t coef[IT2N_BSPLINE_MODEL_WORDS(3, 3, 0)];
    it2n_bspline_data ds, before;
    it2n_bspline_model mdl, mbefore;
    it2n_errinfo err;
    it2n_val vals[NCH] = {0, 0, 0, IT2N_VAL_ONE / 2, 0, 0};
    it2n_point pt;
    unsigned i, j, fp;
    (void)state;
    memset(&ds, 0x5A, sizeof(ds));
    before = ds;
    assert_int_equal(it2n_bspline_data_init(&ds, rec, 1000, 0, 3, 0, &err), IT2N_ERR_INVAL);
    assert_int_equal(it2n_bspline_data_init(&ds, rec, 1000, 3, 256, 0, &err), IT2N_ERR_INVAL);
    assert_int_equal(err.hi, IT2N_BSPLINE_MAX_N);
    assert_int_equal(it2n_bspline_data_init(&ds, rec, 1000, 3, 3, IT2N_F_CHORD, &err),
                     IT2N_ERR_INVAL);
    assert_int_equal(it2n_bspline_data_init(&ds, rec, 10, 3, 3, 0, &err), IT2N_ERR_RANGE);
    assert_int_equal(err.lo, 16 * 7);
    assert_memory_equal(&ds, &before, sizeof(ds));
    assert_int_equal(it2n_bspline_data_init(&ds, rec, sizeof(rec) / sizeof(rec[0]), 3, 3,
                                            0, &err), IT2N_OK);
    assert_int_equal(it2n_bspline_data_missing(&ds), 16 * 7);
    assert_int_equal(it2n_bspline_data_check(&ds, &err), IT2N_ERR_MISSING);
    assert_int_equal(it2n_bspline_data_put(&ds, 4, 0, 0, vals, false, &err), IT2N_ERR_INVAL);
    assert_int_equal(it2n_bspline_data_put(&ds, 0, 0, 7, vals, false, &err), IT2N_ERR_INVAL);
    vals[IT2N_CH_T] = IT2N_VAL_ONE + 1;
    assert_int_equal(it2n_bspline_data_put(&ds, 0, 0, 0, vals, false, &err), IT2N_ERR_RANGE);
    assert_int_equal(err.ch, IT2N_CH_T);
    vals[IT2N_CH_T] = IT2N_VAL_ONE / 2;
    vals[0] = ((it2n_val)IT2N_COORD_LIMIT + 1) << 24;
    assert_int_equal(it2n_bspline_data_put(&ds, 0, 0, 0, vals, false, &err), IT2N_ERR_RANGE);
    assert_int_equal(it2n_bspline_data_missing(&ds), 16 * 7);
    for (i = 0; i <= 3; i++) {
        for (j = 0; j <= 3; j++) {
            for (fp = 0; fp < NFP; fp++) {
                vals[0] = (it2n_val)(i * 10 + fp) << 24;
                vals[1] = (it2n_val)(j * 10 + fp) << 24;
                assert_int_equal(it2n_bspline_data_put(&ds, i, j, fp, vals, false, &err),
                                 IT2N_OK);
            }
        }
    }
    assert_int_equal(it2n_bspline_data_put(&ds, 1, 1, 2, vals, false, &err),
                     IT2N_ERR_DUPLICATE);
    /* a small model buffer: refused, model unchanged */
    it2n_bspline_model_init(&mdl, coef, 10);
    mbefore = mdl;
    assert_int_equal(it2n_bspline_solve(&mdl, &ds, &err), IT2N_ERR_RANGE);
    assert_int_equal(err.lo, (it2n_val)IT2N_BSPLINE_MODEL_WORDS(3, 3, 0));
    assert_memory_equal(&mdl, &mbefore, sizeof(mdl));
    assert_int_equal(it2n_bspline_eval(&mdl, 0, 0, &pt, &err), IT2N_ERR_STATE);
    /* nesting broken by hand: solve refuses */
    before = ds;
    {
        it2n_bspline_rec save = rec[5 * 7 + 3];
        rec[5 * 7 + 3].lo[0] += 100u << 24; /* D above R at (1, 1) on x */
        it2n_bspline_model_init(&mdl, coef, sizeof(coef) / sizeof(coef[0]));
        assert_int_equal(it2n_bspline_solve(&mdl, &ds, &err), IT2N_ERR_ORDER);
        assert_int_equal(err.i, 1);
        assert_int_equal(err.j, 1);
        assert_int_equal(err.fp, 4);
        assert_int_equal(mdl.solved, 0);
        rec[5 * 7 + 3] = save;
    }
    assert_int_equal(it2n_bspline_solve(&mdl, &ds, &err), IT2N_OK);
    /* an update breaking nesting or out of range: nothing changes */
    {
        static it2n_bspline_rec rsave[sizeof(rec) / sizeof(rec[0])];
        static int32_t csave[sizeof(coef) / sizeof(coef[0])];
        it2n_bspline_model msave = mdl;
        memcpy(rsave, rec, sizeof(rec));
        memcpy(csave, coef, sizeof(coef));
        it2n_bspline_data_get(&ds, 2, 2, 3, vals);
        vals[1] += (it2n_val)50 << 24;
        assert_int_equal(it2n_bspline_update(&mdl, &ds, 2, 2, 3, vals, &err), IT2N_ERR_ORDER);
        assert_int_equal(err.fp, 4);
        vals[1] -= (it2n_val)50 << 24;
        vals[IT2N_CH_F] = -1;
        assert_int_equal(it2n_bspline_update(&mdl, &ds, 2, 2, 3, vals, &err), IT2N_ERR_RANGE);
        assert_int_equal(it2n_bspline_update(&mdl, &ds, 2, 4, 3, vals, &err), IT2N_ERR_INVAL);
        assert_memory_equal(rsave, rec, sizeof(rec));
        assert_memory_equal(csave, coef, sizeof(coef));
        assert_memory_equal(&msave, &mdl, sizeof(mdl));
    }
    /* parameters outside [0, 1] */
    assert_int_equal(it2n_bspline_eval(&mdl, -1, 0, &pt, &err), IT2N_ERR_RANGE);
    assert_int_equal(err.ch, 0);
    assert_int_equal(it2n_bspline_eval(&mdl, 0, IT2N_PAR_ONE + 1, &pt, &err), IT2N_ERR_RANGE);
    assert_int_equal(err.ch, 1);
    assert_int_equal(it2n_bspline_coef(&mdl, 6, 0, 0, 0), 0);
    assert_true(it2n_bspline_coef(&mdl, 5, 5, 6, 1) != 0);
}

/* The cost of a query does not depend on the grid: it reads 4 x 4
 * coefficients. Checked structurally: poisoning every coefficient outside
 * the query's window leaves the result bit-identical. */
static void test_local_support(void **state)
{
    bcase c;
    uint64_t s = 3;
    unsigned q;
    size_t words;
    int32_t *save;
    (void)state;
    bcase_gen(&c, 30, 30, IT2N_F_TYPE1, GEN_SMOOTH, 10, 30);
    bcase_core(&c);
    words = IT2N_BSPLINE_MODEL_WORDS(30, 30, IT2N_F_TYPE1);
    save = malloc(words * sizeof(*save));
    assert_non_null(save);
    memcpy(save, c.coef, words * sizeof(*save));
    for (q = 0; q < 50; q++) {
        it2n_par uq = (it2n_par)(tc_rand(&s) % (IT2N_PAR_ONE + 1));
        it2n_par wq = (it2n_par)(tc_rand(&s) % (IT2N_PAR_ONE + 1));
        unsigned k = (unsigned)((uq * 30) >> 32), l = (unsigned)((wq * 30) >> 32);
        it2n_point a, b;
        size_t x;
        k = k > 29 ? 29 : k;
        l = l > 29 ? 29 : l;
        assert_int_equal(it2n_bspline_eval(&c.mdl, uq, wq, &a, NULL), IT2N_OK);
        for (x = 0; x < words; x++) {
            size_t r = (x % (33u * 33u)) / 33u, col = x % 33u;
            if (r < k || r > k + 3 || col < l || col > l + 3) {
                c.coef[x] = (int32_t)0x7FFFFFFF;
            }
        }
        assert_int_equal(it2n_bspline_eval(&c.mdl, uq, wq, &b, NULL), IT2N_OK);
        point_equal(&a, &b);
        memcpy(c.coef, save, words * sizeof(*save));
    }
    free(save);
    bcase_free(&c);
}

/* Random shapes and magnitudes: sizes 1..40 each way, every flag set,
 * data from single LSBs to +-IT2N_COORD_LIMIT, zero rows and zero nets,
 * constants, spikes. Every model solves (the sanitizer build traps on the
 * exponent assertion), matches the reference, and an update matches a
 * full solve. */
static void test_random_shapes(void **state)
{
    static const unsigned fl[4] = {0, IT2N_F_Z, IT2N_F_TYPE1, IT2N_F_TYPE1 | IT2N_F_Z};
    uint64_t s = 4242;
    worst wo = {0, 0, 0, 0};
    unsigned t;
    (void)state;
    for (t = 0; t < 60; t++) {
        unsigned n = 1u + (unsigned)(tc_rand(&s) % 40u);
        unsigned m = 1u + (unsigned)(tc_rand(&s) % 40u);
        unsigned flags = fl[tc_rand(&s) % 4u], kind = (unsigned)(tc_rand(&s) % 6u);
        unsigned i, j, fp, ch;
        bcase c;
        bcase_gen(&c, n, m, flags, GEN_SMOOTH, 1, t);
        /* overwrite with the shape under test: the same for every
         * footprint, so they nest */
        for (i = 0; i <= n; i++) {
            for (j = 0; j <= m; j++) {
                for (ch = 0; ch < NCH; ch++) {
                    long double x, e;
                    it2n_val q;
                    uint64_t r = tc_rand(&s);
                    long double lim = ch < 3 ? IT2N_COORD_LIMIT - 1 : 1;
                    switch (kind) {
                    case 0: /* single LSBs (Q24 1e-6 steps) */
                        x = (long double)(r % 3u) * 1e-6L;
                        break;
                    case 1: /* +-limit at random */
                        x = ch < 3 ? ((r & 1u) ? lim : -lim) : (long double)(r & 1u);
                        break;
                    case 2: /* zero except a spike */
                        x = (i == n / 2u && j == m / 3u) ? lim : 0;
                        break;
                    case 3: /* constants (and all-zero nets for z, F) */
                        x = ch == 2 || ch == 5 ? 0 : lim / 3;
                        break;
                    case 4: /* zero rows */
                        x = (i & 1u) ? 0 : (long double)(r % 1000u) / 1000.0L * lim;
                        break;
                    default: /* random in range */
                        x = ch < 3 ? ((long double)(r % 2000001u) / 1e6L - 1) * lim
                                   : (long double)(r % 1000001u) / 1e6L;
                        break;
                    }
                    if (ch >= 3 && x < 0) {
                        x = -x;
                    }
                    q = dec6(ch, x, &e);
                    for (fp = 0; fp < NFP; fp++) {
                        if (has_fp(flags, fp) && has_ch(flags, ch)) {
                            c.q[vidx(&c, i, j, fp, ch)] = q;
                            c.v[vidx(&c, i, j, fp, ch)] = e;
                        }
                    }
                }
            }
        }
        c.maxabs = 0;
        for (i = 0; i <= n; i++)
            for (j = 0; j <= m; j++)
                for (ch = 0; ch < 3; ch++)
                    c.maxabs = fmaxl(c.maxabs, fabsl(c.v[vidx(&c, i, j, IT2N_FP_D, ch)]));
        bcase_core(&c);
        bcase_ref(&c);
        check_case(&c, 30, n * m < 200, t, &wo);
        (void)check_coefs(&c);
        {
            it2n_val vals[NCH];
            size_t words = IT2N_BSPLINE_MODEL_WORDS(n, m, flags);
            int32_t *fresh = malloc(words * sizeof(*fresh));
            it2n_bspline_model m2;
            assert_non_null(fresh);
            it2n_bspline_data_get(&c.ds, n, 0, IT2N_FP_D, vals);
            vals[IT2N_CH_T] = IT2N_VAL_ONE - vals[IT2N_CH_T];
            assert_int_equal(it2n_bspline_update(&c.mdl, &c.ds, n, 0, IT2N_FP_D, vals, NULL),
                             IT2N_OK);
            it2n_bspline_model_init(&m2, fresh, words);
            assert_int_equal(it2n_bspline_solve(&m2, &c.ds, NULL), IT2N_OK);
            assert_memory_equal(fresh, c.coef, words * sizeof(*fresh));
            free(fresh);
        }
        bcase_free(&c);
    }
    report("random shapes and magnitudes", &wo);
}

/* Locate: the (u, w) of a point of footprint D is found again, with the
 * surface values there; far-off locations are outside; errors. */
static void locate_case(unsigned pts, unsigned flags, long double scale,
                        unsigned queries, long double *worst_uw)
{
    bcase c;
    uint64_t s = pts;
    unsigned q, fp;
    bcase_gen(&c, pts - 1u, pts - 1u, flags, GEN_SMOOTH, scale, 300 + pts);
    bcase_core(&c);
    for (q = 0; q < queries; q++) {
        it2n_point pt;
        it2n_locate_result res;
        it2n_par uq = (it2n_par)(tc_rand(&s) % (IT2N_PAR_ONE + 1));
        it2n_par wq = (it2n_par)(tc_rand(&s) % (IT2N_PAR_ONE + 1));
        assert_int_equal(it2n_bspline_eval(&c.mdl, uq, wq, &pt, NULL), IT2N_OK);
        assert_int_equal(it2n_bspline_locate(&c.mdl, pt.v[IT2N_FP_D][IT2N_CH_X],
                                             pt.v[IT2N_FP_D][IT2N_CH_Y], &res, NULL),
                         IT2N_OK);
        for (fp = 0; fp < NFP; fp++) {
            const it2n_locate_fp *r = &res.fp[fp];
            if (!has_fp(flags, fp)) {
                assert_int_equal(r->status, IT2N_LOC_NOCONV);
                continue;
            }
            if (fp == IT2N_FP_D) {
                long double du = fabsl(tc_ldp(r->u) - tc_ldp(uq));
                long double dw = fabsl(tc_ldp(r->w) - tc_ldp(wq));
                if (r->status != IT2N_LOC_INSIDE || du > 1e-6L || dw > 1e-6L ||
                    llabs((long long)(r->v[IT2N_CH_T] - pt.v[IT2N_FP_D][IT2N_CH_T])) > 32) {
                    fail_msg("locate %ux%u: status %d (u,w) (%.9Lf,%.9Lf) want (%.9Lf,%.9Lf)",
                             pts, pts, r->status, tc_ldp(r->u), tc_ldp(r->w),
                             tc_ldp(uq), tc_ldp(wq));
                }
                *worst_uw = fmaxl(*worst_uw, fmaxl(du, dw));
            }
        }
    }
    {
        it2n_locate_result res;
        it2n_errinfo err;
        it2n_val far = (it2n_val)IT2N_COORD_LIMIT << 24;
        assert_int_equal(it2n_bspline_locate(&c.mdl, far, far, &res, NULL), IT2N_OK);
        assert_int_equal(res.fp[IT2N_FP_D].status, IT2N_LOC_OUTSIDE);
        assert_int_equal(it2n_bspline_locate(&c.mdl, far + 1, 0, &res, &err),
                         IT2N_ERR_RANGE);
        assert_int_equal(err.ch, IT2N_CH_X);
        c.mdl.solved = 0;
        assert_int_equal(it2n_bspline_locate(&c.mdl, 0, 0, &res, &err), IT2N_ERR_STATE);
    }
    bcase_free(&c);
}

static void test_locate(void **state)
{
    long double wuw = 0;
    (void)state;
    locate_case(31, IT2N_F_Z, 100, 40, &wuw);
    locate_case(4, 0, 10, 40, &wuw);
    locate_case(256, IT2N_F_TYPE1, 2500, 20, &wuw);
    printf("[bspline] locate 31x31, 4x4 and 256x256: 100 points found again, worst |du|,|dw| %.3Le\n",
           wuw);
}

/* Memory of data set + model (the caller's storage) per grid, and the
 * largest square grid a RAM budget holds (printed for docs/numerics.md). */
static size_t bs_bytes(unsigned n, unsigned flags)
{
    return IT2N_BSPLINE_DATA_RECS(n, n, flags) * sizeof(it2n_bspline_rec) +
           IT2N_BSPLINE_MODEL_WORDS(n, n, flags) * sizeof(int32_t);
}

static void test_memory(void **state)
{
    static const struct { unsigned flags; const char *name; } kinds[] = {
        {IT2N_F_TYPE1, "type-1 x,y"}, {IT2N_F_TYPE1 | IT2N_F_Z, "type-1 x,y,z"},
        {0, "type-2 x,y"}, {IT2N_F_Z, "type-2 x,y,z"}};
    unsigned k;
    (void)state;
    assert_int_equal(sizeof(it2n_bspline_rec), 32);
    for (k = 0; k < 4; k++) {
        unsigned f = kinds[k].flags, n, fit32 = 0, fit128 = 0;
        /* budgets: 24 KiB of a 32 KiB M0+, 112 KiB of a 128 KiB M4F (the
         * rest for stack, the protocol and the application) */
        for (n = 1; n <= 255; n++) {
            if (bs_bytes(n, f) <= 24u * 1024u) fit32 = n;
            if (bs_bytes(n, f) <= 112u * 1024u) fit128 = n;
        }
        assert_true(bs_bytes(63, f) > bs_bytes(62, f));
        printf("[bspline] memory %-13s %3zu B/point + model %5.1f B/point at 64x64;"
               " 64x64 %7.1f KiB, 256x256 %6.1f MiB; largest square in 24 KiB %ux%u,"
               " in 112 KiB %ux%u\n",
               kinds[k].name, IT2N_BSPLINE_NFP(f) * sizeof(it2n_bspline_rec),
               (double)(IT2N_BSPLINE_MODEL_WORDS(63, 63, f) * 4) / (64.0 * 64.0),
               (double)bs_bytes(63, f) / 1024.0, (double)bs_bytes(255, f) / 1048576.0,
               fit32 + 1, fit32 + 1, fit128 + 1, fit128 + 1);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pivot_table),
        cmocka_unit_test(test_reference_self),
        cmocka_unit_test(test_small_n_polynomials),
        cmocka_unit_test(test_small_grids),
        cmocka_unit_test(test_64x64),
        cmocka_unit_test(test_256x256),
        cmocka_unit_test(test_extreme),
        cmocka_unit_test(test_derivatives),
        cmocka_unit_test(test_update_vs_solve),
        cmocka_unit_test(test_sample),
        cmocka_unit_test(test_validation),
        cmocka_unit_test(test_local_support),
        cmocka_unit_test(test_random_shapes),
        cmocka_unit_test(test_locate),
        cmocka_unit_test(test_memory),
    };
    int rc = cmocka_run_group_tests_name("core bspline", tests, NULL, NULL);
    for (unsigned k = 0; k < 256; k++) {
        if (lu_cache[k] != NULL) {
            free(lu_cache[k]->a);
            free(lu_cache[k]->piv);
            free(lu_cache[k]->lo);
            free(lu_cache[k]->hi);
            free(lu_cache[k]);
        }
    }
    return rc;
}
