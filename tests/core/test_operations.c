/*
 * Operations at the C API level (issue 2, "Operations"): derivatives against
 * central differences of the long-double reference, it2n_sample against
 * it2n_eval (bit-identical) with early stop, incremental update against a
 * full re-solve (1 LSB), chord-length parameters against The NURBS Book's
 * averaged chord lengths, locate, the out-of-range flag and the generation
 * counter.
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
#include "ref.h"
#include "tc_util.h"

#define ONE IT2N_VAL_ONE

/* ---- derivatives ------------------------------------------------------- */

/*
 * d/du of a degree-n Bernstein surface is n * sum (P[i+1]-P[i]) B^{n-1}: the
 * control-point error is amplified by at most 2n, so the tolerance is
 * 2 * max(n, m) times the value tolerance.
 */
static void deriv_case(const tc_case *c, uint64_t seed, long double *worst)
{
    static it2n_model mdl;
    static ref_model r;
    tc_model(c, &mdl);
    tc_ref(c, &r);
    unsigned deg = c->n > c->m ? c->n : c->m;
    long double tm = 2.0L * deg * tc_tol_memb(c->n, c->m);
    long double tcd = 2.0L * deg * tc_tol_coord(c->n, c->m, tc_maxabs(c));
    uint64_t s = seed;
    for (unsigned k = 0; k < 30; k++) {
        it2n_par uq, wq;
        long double ue = tc_rand_par(&s, &uq), we = tc_rand_par(&s, &wq);
        if (k == 0) { ue = 0.0L; uq = 0; we = 1.0L; wq = IT2N_PAR_ONE; }
        if (k == 1) { ue = 1.0L; uq = IT2N_PAR_ONE; }
        it2n_point du, dw;
        long double rdu[REF_FP][REF_CH], rdw[REF_FP][REF_CH];
        int rc = it2n_deriv(&mdl, uq, wq, &du, &dw, NULL);
        if (rc != IT2N_OK)
            fail_msg("deriv %ux%u at (%.6Lf,%.6Lf) -> %d", c->n, c->m, ue, we, rc);
        ref_deriv_fd(&r, ue, we, 1e-5L, rdu, rdw);
        for (unsigned fp = 0; fp < REF_FP; fp++) {
            if (!tc_has_fp(c, fp))
                continue;
            for (unsigned ch = 0; ch < REF_CH; ch++) {
                if (ch == IT2N_CH_Z && !(c->flags & IT2N_F_Z))
                    continue;
                long double tol = ch >= IT2N_CH_T ? tm : tcd;
                long double eu = fabsl(tc_ld(du.v[fp][ch]) - rdu[fp][ch]);
                long double ew = fabsl(tc_ld(dw.v[fp][ch]) - rdw[fp][ch]);
                long double e = eu > ew ? eu : ew;
                if (e / tol > *worst)
                    *worst = e / tol;
                if (!(e <= tol))
                    fail_msg("deriv %ux%u (u=%.6Lf,w=%.6Lf) %s.%s: du %.9Lf vs "
                             "%.9Lf, dw %.9Lf vs %.9Lf (tol %.3Le)", c->n, c->m,
                             ue, we, it2n_fp_name(fp), it2n_ch_name(ch),
                             tc_ld(du.v[fp][ch]), rdu[fp][ch],
                             tc_ld(dw.v[fp][ch]), rdw[fp][ch], tol);
            }
        }
    }
}

static void test_derivatives(void **state)
{
    (void)state;
    static tc_case c;
    long double worst = 0.0L;
    tc_paper(&c);
    deriv_case(&c, 11, &worst);
    for (unsigned n = 1; n <= IT2N_MAX_DEGREE; n += 2)
        for (unsigned m = 1; m <= IT2N_MAX_DEGREE; m += 3) {
            tc_smooth(&c, n, m, (n + m) & 1u ? IT2N_F_Z : 0u, 10.0L, n + m);
            deriv_case(&c, n * 10u + m, &worst);
        }
    tc_smooth(&c, 5, 7, IT2N_F_CHORD | IT2N_F_Z, 10.0L, 3);
    deriv_case(&c, 99, &worst);
    tc_smooth(&c, 4, 2, IT2N_F_TYPE1, 10.0L, 3);
    deriv_case(&c, 98, &worst);
    printf("  [operations] derivatives: worst error %.3f of tolerance\n",
           (double)worst);
}

/* ---- sample ------------------------------------------------------------ */

typedef struct sample_ctx {
    const it2n_model *mdl;
    unsigned rows, cols, calls, stop_at;
    unsigned bad;
} sample_ctx;

static int sample_cb(void *vctx, unsigned r, unsigned c, it2n_par u, it2n_par w,
                     const it2n_point *pt)
{
    sample_ctx *x = vctx;
    unsigned idx = x->calls++;
    it2n_point ref;
    /* row-major order and exact end points */
    if (r != idx / x->cols || c != idx % x->cols)
        x->bad++;
    it2n_par eu = (it2n_par)llroundl((long double)r / (x->rows - 1) * TC_Q32);
    it2n_par ew = (it2n_par)llroundl((long double)c / (x->cols - 1) * TC_Q32);
    if (llabs(u - eu) > 1 || llabs(w - ew) > 1)
        x->bad++;
    if ((r == 0 && u != 0) || (r == x->rows - 1 && u != IT2N_PAR_ONE) ||
        (c == 0 && w != 0) || (c == x->cols - 1 && w != IT2N_PAR_ONE))
        x->bad++;
    if (it2n_eval(x->mdl, u, w, &ref, NULL) != IT2N_OK ||
        memcmp(ref.v, pt->v, sizeof ref.v) != 0 ||
        memcmp(&ref.sum, &pt->sum, sizeof ref.sum) != 0 ||
        ref.out_of_range != pt->out_of_range) {
        if (x->bad < 5)
            fprintf(stderr, "  sample node (%u,%u) differs from it2n_eval\n", r, c);
        x->bad++;
    }
    return idx == x->stop_at ? 42 : 0;
}

static void test_sample(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl;
    static const unsigned grids[][2] = {{2, 2}, {5, 9}, {33, 17}, {2, 101}};
    for (unsigned variant = 0; variant < 3; variant++) {
        if (variant == 0)
            tc_paper(&c);
        else
            tc_smooth(&c, variant == 1 ? 7u : 2u, variant == 1 ? 5u : 6u,
                      variant == 1 ? IT2N_F_Z : IT2N_F_TYPE1, 10.0L, variant);
        tc_model(&c, &mdl);
        for (unsigned g = 0; g < sizeof grids / sizeof grids[0]; g++) {
            sample_ctx x = {&mdl, grids[g][0], grids[g][1], 0, UINT32_MAX, 0};
            assert_int_equal(it2n_sample(&mdl, x.rows, x.cols, sample_cb, &x, NULL),
                             IT2N_OK);
            assert_int_equal(x.calls, x.rows * x.cols);
            assert_int_equal(x.bad, 0);
            /* early stop: the callback's value comes back, no more calls */
            sample_ctx y = {&mdl, grids[g][0], grids[g][1], 0, x.rows * x.cols / 2, 0};
            assert_int_equal(it2n_sample(&mdl, y.rows, y.cols, sample_cb, &y, NULL), 42);
            assert_int_equal(y.calls, y.stop_at + 1u);
            assert_int_equal(y.bad, 0);
        }
    }
    /* bad grid sizes and unsolved model */
    sample_ctx z = {&mdl, 2, 2, 0, UINT32_MAX, 0};
    assert_true(it2n_sample(&mdl, 1, 5, sample_cb, &z, NULL) < 0);
    assert_true(it2n_sample(&mdl, 5, 0, sample_cb, &z, NULL) < 0);
    assert_true(it2n_sample(&mdl, 65536, 2, sample_cb, &z, NULL) < 0);
    assert_int_equal(z.calls, 0);
    static it2n_model empty;
    it2n_model_init(&empty);
    assert_int_equal(it2n_sample(&empty, 3, 3, sample_cb, &z, NULL), IT2N_ERR_STATE);
    assert_int_equal(z.calls, 0);
}

/* ---- incremental update ------------------------------------------------ */

static long long max_ctrl_diff(const it2n_model *a, const it2n_model *b,
                               unsigned *at)
{
    long long worst = 0;
    for (unsigned i = 0; i < IT2N_DIM; i++)
        for (unsigned j = 0; j < IT2N_DIM; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
                for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    long long d = llabs(it2n_model_ctrl(a, i, j, fp, ch) - it2n_model_ctrl(b, i, j, fp, ch));
                    if (d > worst) {
                        worst = d;
                        *at = ((i * IT2N_DIM + j) * IT2N_FP_COUNT + fp) * 8u + ch;
                    }
                }
    return worst;
}

/* New values for (i, j, fp) that keep the nesting: move the whole point. */
static void moved_vals(const tc_case *c, unsigned i, unsigned j, unsigned fp,
                       uint64_t *s, tc_case *out)
{
    *out = *c;
    long double dx = ((long double)(tc_rand(s) % 1000u) - 500.0L) * 1e-5L;
    unsigned lo = tc_has_fp(c, IT2N_FP_LL) ? 0u : IT2N_FP_D;
    unsigned hi = tc_has_fp(c, IT2N_FP_LL) ? IT2N_FP_COUNT - 1u : IT2N_FP_D;
    (void)fp;
    for (unsigned f = lo; f <= hi; f++)
        for (unsigned ch = IT2N_CH_X; ch <= IT2N_CH_Z; ch++)
            if (ch != IT2N_CH_Z || (c->flags & IT2N_F_Z))
                tc_set(out, i, j, f, ch, c->v[i][j][f][ch] + dx);
    tc_set(out, i, j, fp, IT2N_CH_T, (long double)(tc_rand(s) % 1000001u) * 1e-6L);
    tc_set(out, i, j, fp, IT2N_CH_I, (long double)(tc_rand(s) % 1000001u) * 1e-6L);
    tc_set(out, i, j, fp, IT2N_CH_F, (long double)(tc_rand(s) % 1000001u) * 1e-6L);
}

static void test_update_vs_resolve(void **state)
{
    (void)state;
    static tc_case c, c2;
    static it2n_model inc, full;
    static it2n_dataset ids, fds;
    static const unsigned pairs[][2] = {{1, 1}, {2, 3}, {3, 3}, {5, 4}, {7, 2}, {7, 7}};
    it2n_errinfo err;
    long long worst = 0;
    uint64_t s = 2024;
    for (unsigned p = 0; p < sizeof pairs / sizeof pairs[0]; p++)
        for (unsigned zf = 0; zf < 2; zf++) {
            unsigned flags = zf ? IT2N_F_Z : (p & 1u ? IT2N_F_TYPE1 : 0u);
            tc_smooth(&c, pairs[p][0], pairs[p][1], flags, 10.0L, p);
            for (unsigned t = 0; t < 6; t++) {
                unsigned i = (unsigned)(tc_rand(&s) % (c.n + 1u));
                unsigned j = (unsigned)(tc_rand(&s) % (c.m + 1u));
                unsigned fp = (flags & IT2N_F_TYPE1) ? IT2N_FP_D
                            : (unsigned)(tc_rand(&s) % IT2N_FP_COUNT);
                tc_model_ds(&c, &inc, &ids);
                uint32_t gen = inc.generation;
                moved_vals(&c, i, j, fp, &s, &c2);
                /* coordinates of all footprints moved: update each */
                unsigned lo = (flags & IT2N_F_TYPE1) ? IT2N_FP_D : 0u;
                unsigned hi = (flags & IT2N_F_TYPE1) ? IT2N_FP_D : IT2N_FP_COUNT - 1u;
                /* Move outward-first so nesting holds after every step. */
                long double dx = c2.v[i][j][lo][IT2N_CH_X] - c.v[i][j][lo][IT2N_CH_X];
                for (unsigned k = lo; k <= hi; k++) {
                    unsigned f = dx > 0 ? hi - (k - lo) : k;
                    int rc = it2n_model_update_fine(&inc, &ids, i, j, f, c2.q[i][j][f], &err);
                    if (rc != IT2N_OK)
                        fail_msg("update %ux%u (%u,%u,%u) -> %d", c.n, c.m, i, j, f, rc);
                }
                assert_true(inc.generation != gen);
                tc_model_ds(&c2, &full, &fds);
                assert_memory_equal(&ids, &fds, sizeof fds);
                unsigned at = 0;
                long long d = max_ctrl_diff(&inc, &full, &at);
                if (d > worst)
                    worst = d;
                if (!tc_nets_equal(&inc, &full))
                    fail_msg("update %ux%u flags %u at (%u,%u): control points "
                             "not bit-identical to a full re-solve (%lld LSB, entry %u)",
                             c.n, c.m, flags, i, j, d, at);
            }
        }
    printf("  [operations] single-point update vs re-solve: worst %lld LSB\n", worst);
}

/* A long run of updates must not drift from the full re-solve: after every
 * update the model is what a full re-solve of its data gives (1 LSB). */
static void test_update_chain(void **state)
{
    (void)state;
    static tc_case c, c2;
    static it2n_model inc, full;
    static it2n_dataset ids, fds;
    it2n_errinfo err;
    uint64_t s = 99;
    tc_smooth(&c, 7, 7, 0, 10.0L, 5);
    tc_model_ds(&c, &inc, &ids);
    long long first_bad = -1, worst = 0;
    for (unsigned t = 0; t < 50; t++) {
        unsigned i = (unsigned)(tc_rand(&s) % 8u), j = (unsigned)(tc_rand(&s) % 8u);
        c2 = c;
        for (unsigned ch = IT2N_CH_T; ch <= IT2N_CH_F; ch++)
            tc_set(&c2, i, j, IT2N_FP_D, ch, (long double)(tc_rand(&s) % 1000001u) * 1e-6L);
        assert_int_equal(it2n_model_update_fine(&inc, &ids, i, j, IT2N_FP_D,
                                           c2.q[i][j][IT2N_FP_D], &err), IT2N_OK);
        c = c2;
        tc_model_ds(&c, &full, &fds);
        unsigned at = 0;
        long long d = max_ctrl_diff(&inc, &full, &at);
        if (d > worst)
            worst = d;
        if (!tc_nets_equal(&inc, &full) && first_bad < 0)
            first_bad = t + 1;
    }
    printf("  [operations] 50 chained updates 7x7 vs re-solve: worst %lld LSB\n",
           worst);
    if (first_bad >= 0)
        fail_msg("chained updates drift from a full re-solve: not bit-identical "
                 "from update #%lld on, %lld LSB worst in 50", first_bad, worst);
}

static void test_update_chord(void **state)
{
    (void)state;
    static tc_case c, c2;
    static it2n_model inc, full;
    static it2n_dataset ids, fds;
    it2n_errinfo err;
    uint64_t s = 7;
    for (unsigned variant = 0; variant < 2; variant++) {
        unsigned flags = IT2N_F_CHORD | (variant ? IT2N_F_Z : IT2N_F_TYPE1);
        tc_smooth(&c, 4, 5, flags, 10.0L, 1);
        tc_model_ds(&c, &inc, &ids);
        for (unsigned t = 0; t < 4; t++) {
            unsigned i = (unsigned)(tc_rand(&s) % 5u), j = (unsigned)(tc_rand(&s) % 6u);
            moved_vals(&c, i, j, IT2N_FP_D, &s, &c2);
            /* D alone moves within its neighbours' gap */
            static tc_case c3;
            c3 = c;
            for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++) {
                c3.v[i][j][IT2N_FP_D][ch] = c2.v[i][j][IT2N_FP_D][ch];
                c3.q[i][j][IT2N_FP_D][ch] = c2.q[i][j][IT2N_FP_D][ch];
            }
            uint32_t gen = inc.generation;
            assert_int_equal(it2n_model_update_fine(&inc, &ids, i, j, IT2N_FP_D,
                                               c3.q[i][j][IT2N_FP_D], &err), IT2N_OK);
            assert_true(inc.generation != gen);
            tc_model_ds(&c3, &full, &fds);
            assert_memory_equal(&ids, &fds, sizeof fds);
            if (!tc_nets_equal(&inc, &full))
                fail_msg("chord update: the model differs from the full re-solve");
            c = c3;
        }
    }
}

/* ---- chord-length parameters ------------------------------------------ */

static void test_chord_params(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl;
    static ref_model r;
    long double worst = 0.0L;
    for (unsigned n = 1; n <= IT2N_MAX_DEGREE; n++)
        for (unsigned m = 1; m <= IT2N_MAX_DEGREE; m++) {
            unsigned flags = IT2N_F_CHORD | ((n + m) % 3u == 0 ? IT2N_F_Z : 0u);
            tc_smooth(&c, n, m, flags, 10.0L, n * m);
            /* uneven spacing so chord params differ from uniform ones */
            for (unsigned i = 0; i <= n; i++)
                for (unsigned j = 0; j <= m; j++)
                    for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                        long double a = (long double)i / n, b = (long double)j / m;
                        tc_set(&c, i, j, fp, IT2N_CH_X, 10.0L * a * a + 0.25L * fp);
                        tc_set(&c, i, j, fp, IT2N_CH_Y, 8.0L * b * sqrtl(b) + a + 0.25L * fp);
                    }
            tc_model(&c, &mdl);
            tc_ref(&c, &r);
            it2n_par mu[IT2N_DIM], mw[IT2N_DIM];
            tc_params(&c, mu, mw);
            for (unsigned i = 0; i <= n; i++) {
                long double e = fabsl(tc_ldp(mu[i]) - r.u[i]);
                worst = fmaxl(worst, e);
                if (e > 1e-6L)
                    fail_msg("chord %ux%u: u[%u] = %.9Lf, reference %.9Lf", n, m,
                             i, tc_ldp(mu[i]), r.u[i]);
            }
            for (unsigned j = 0; j <= m; j++) {
                long double e = fabsl(tc_ldp(mw[j]) - r.w[j]);
                worst = fmaxl(worst, e);
                if (e > 1e-6L)
                    fail_msg("chord %ux%u: w[%u] = %.9Lf, reference %.9Lf", n, m,
                             j, tc_ldp(mw[j]), r.w[j]);
            }
            assert_true(mu[0] == 0 && mu[n] == IT2N_PAR_ONE);
            assert_true(mw[0] == 0 && mw[m] == IT2N_PAR_ONE);
        }
    printf("  [operations] chord-length parameters: worst |err| %.3Le\n", worst);
}

/* Rows degenerate one by one: skipped while any row has length. */
static void test_chord_degenerate(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_dataset ds;
    static it2n_model mdl;
    static ref_model r;
    it2n_errinfo err;
    for (unsigned dir = 0; dir < 2; dir++) {
        tc_init(&c, 3, 4, IT2N_F_CHORD);
        for (unsigned i = 0; i <= 3; i++)
            for (unsigned j = 0; j <= 4; j++)
                for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                    /* dir 0: points move only with j (rows along u collapse) */
                    long double t = dir == 0 ? (long double)j : (long double)i;
                    tc_set(&c, i, j, fp, IT2N_CH_X, 3.0L * t + 0.5L * fp);
                    tc_set(&c, i, j, fp, IT2N_CH_Y, t * t + 0.5L * fp);
                    tc_set(&c, i, j, fp, IT2N_CH_T, 0.5L);
                    tc_set(&c, i, j, fp, IT2N_CH_I, 0.5L);
                    tc_set(&c, i, j, fp, IT2N_CH_F, 0.5L);
                }
        tc_dataset(&c, &ds);
        it2n_model_init(&mdl);
        memset(&err, 0, sizeof err);
        assert_int_equal(it2n_model_solve(&mdl, &ds, &err), IT2N_ERR_DEGENERATE);
        assert_int_equal(err.code, IT2N_ERR_DEGENERATE);
        assert_int_equal(mdl.solved, 0);
        /* One line with strictly increasing, uneven chords makes it valid
         * again: A9.3 skips the degenerate lines and uses that one alone. */
        static const long double step[5] = {0.0L, 0.5L, 0.75L, 1.5L, 1.75L};
        for (unsigned k = 0; k <= (dir == 0 ? 3u : 4u); k++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (dir == 0)
                    tc_set(&c, k, 4, fp, IT2N_CH_X, 12.0L + 0.5L * fp + step[k]);
                else
                    tc_set(&c, 3, k, fp, IT2N_CH_Y, 9.0L + 0.5L * fp + step[k]);
            }
        tc_model(&c, &mdl);
        tc_ref(&c, &r);
        it2n_par mu[IT2N_DIM], mw[IT2N_DIM];
        tc_params(&c, mu, mw);
        for (unsigned i = 0; i <= 3; i++)
            if (fabsl(tc_ldp(mu[i]) - r.u[i]) > 1e-6L)
                fail_msg("dir %u: u[%u] = %.9Lf, reference %.9Lf", dir, i,
                         tc_ldp(mu[i]), r.u[i]);
        for (unsigned j = 0; j <= 4; j++)
            if (fabsl(tc_ldp(mw[j]) - r.w[j]) > 1e-6L)
                fail_msg("dir %u: w[%u] = %.9Lf, reference %.9Lf", dir, j,
                         tc_ldp(mw[j]), r.w[j]);
    }
}

/* ---- locate ------------------------------------------------------------ */

static void locate_case(const tc_case *c, uint64_t seed, long double *worst_uw)
{
    static it2n_model mdl;
    static ref_model r;
    tc_model(c, &mdl);
    tc_ref(c, &r);
    long double tm = tc_tol_memb(c->n, c->m);
    uint64_t s = seed;
    for (unsigned k = 0; k < 12; k++) {
        it2n_par uq, wq;
        long double ue = tc_rand_par(&s, &uq), we = tc_rand_par(&s, &wq);
        if (k == 0) { ue = 0.0L; we = 0.0L; }
        if (k == 1) { ue = 1.0L; we = 0.5L; }
        long double ref[REF_FP][REF_CH], rdu[REF_FP][REF_CH], rdw[REF_FP][REF_CH];
        ref_eval(&r, ue, we, ref);
        ref_deriv_fd(&r, ue, we, 1e-5L, rdu, rdw);
        for (unsigned fp = 0; fp < REF_FP; fp++) {
            if (!tc_has_fp(c, fp))
                continue;
            it2n_locate_result res;
            it2n_val x = (it2n_val)llroundl(ref[fp][IT2N_CH_X] * TC_Q24);
            it2n_val y = (it2n_val)llroundl(ref[fp][IT2N_CH_Y] * TC_Q24);
            int rc = it2n_locate(&mdl, x, y, &res, NULL);
            if (rc != IT2N_OK)
                fail_msg("locate -> %d", rc);
            const it2n_locate_fp *f = &res.fp[fp];
            long double du = fabsl(tc_ldp(f->u) - ue), dw = fabsl(tc_ldp(f->w) - we);
            *worst_uw = fmaxl(*worst_uw, fmaxl(du, dw));
            if (f->status != IT2N_LOC_INSIDE || du > 1e-5L || dw > 1e-5L)
                fail_msg("locate %ux%u %s at (x=%.6Lf,y=%.6Lf): status %u u=%.9Lf "
                         "w=%.9Lf, expected inside u=%.6Lf w=%.6Lf", c->n, c->m,
                         it2n_fp_name(fp), ref[fp][IT2N_CH_X], ref[fp][IT2N_CH_Y],
                         f->status, tc_ldp(f->u), tc_ldp(f->w), ue, we);
            /* memberships there: tolerance plus the slope times the (u,w) miss */
            for (unsigned ch = IT2N_CH_T; ch <= IT2N_CH_F; ch++) {
                long double tol = tm + fabsl(rdu[fp][ch]) * du + fabsl(rdw[fp][ch]) * dw;
                long double e = fabsl(tc_ld(f->v[ch]) - ref[fp][ch]);
                if (!(e <= tol))
                    fail_msg("locate %s.%s = %.9Lf, reference %.9Lf (tol %.3Le)",
                             it2n_fp_name(fp), it2n_ch_name(ch), tc_ld(f->v[ch]),
                             ref[fp][ch], tol);
            }
            /* values and residual consistent with it2n_eval at the (u,w) found */
            it2n_point pt;
            assert_int_equal(it2n_eval(&mdl, f->u, f->w, &pt, NULL), IT2N_OK);
            for (unsigned ch = 0; ch < REF_CH; ch++)
                if (llabs(pt.v[fp][ch] - f->v[ch]) > 1)
                    fail_msg("locate %s.%s %lld != eval %lld", it2n_fp_name(fp),
                             it2n_ch_name(ch), (long long)f->v[ch],
                             (long long)pt.v[fp][ch]);
            it2n_val rx = llabs(pt.v[fp][IT2N_CH_X] - x), ry = llabs(pt.v[fp][IT2N_CH_Y] - y);
            it2n_val res_inf = rx > ry ? rx : ry;
            if (llabs(f->residual - res_inf) > 2)
                fail_msg("locate residual %lld, eval says %lld",
                         (long long)f->residual, (long long)res_inf);
        }
    }
    /* far away: outside for every footprint, parameters still in [0,1] */
    it2n_locate_result res;
    long double far = tc_maxabs(c) * 4.0L + 100.0L;
    assert_int_equal(it2n_locate(&mdl, (it2n_val)llroundl(far * TC_Q24),
                                 (it2n_val)llroundl(-far * TC_Q24), &res, NULL), IT2N_OK);
    for (unsigned fp = 0; fp < REF_FP; fp++) {
        if (!tc_has_fp(c, fp))
            continue;
        if (res.fp[fp].status != IT2N_LOC_OUTSIDE)
            fail_msg("far point: %s status %u, expected outside", it2n_fp_name(fp),
                     res.fp[fp].status);
        assert_true(res.fp[fp].u >= 0 && res.fp[fp].u <= IT2N_PAR_ONE);
        assert_true(res.fp[fp].w >= 0 && res.fp[fp].w <= IT2N_PAR_ONE);
        assert_true(res.fp[fp].residual > 0);
    }
}

static void test_locate(void **state)
{
    (void)state;
    static tc_case c;
    long double worst = 0.0L;
    tc_paper(&c);
    locate_case(&c, 3, &worst);
    tc_smooth(&c, 5, 4, IT2N_F_Z, 10.0L, 1);
    locate_case(&c, 4, &worst);
    tc_smooth(&c, 7, 7, 0, 100.0L, 2);
    locate_case(&c, 5, &worst);
    tc_smooth(&c, 2, 6, IT2N_F_TYPE1, 10.0L, 3);
    locate_case(&c, 6, &worst);
    tc_smooth(&c, 3, 3, IT2N_F_CHORD, 10.0L, 4);
    locate_case(&c, 7, &worst);
    printf("  [operations] locate: worst |du|,|dw| %.3Le\n", worst);
    static it2n_model empty;
    it2n_locate_result res;
    it2n_model_init(&empty);
    assert_int_equal(it2n_locate(&empty, 0, 0, &res, NULL), IT2N_ERR_STATE);
}

/* ---- out-of-range flag, parameter range, generation ------------------- */

static void test_out_of_range_flag(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl;
    /* memberships alternate 0/1: the degree-6 interpolant overshoots */
    tc_smooth(&c, 6, 6, 0, 10.0L, 1);
    for (unsigned i = 0; i <= 6; i++)
        for (unsigned j = 0; j <= 6; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                tc_set(&c, i, j, fp, IT2N_CH_T, (i + j) & 1u ? 1.0L : 0.0L);
                tc_set(&c, i, j, fp, IT2N_CH_I, 0.5L);
                tc_set(&c, i, j, fp, IT2N_CH_F, i & 1u ? 0.0L : 1.0L);
            }
    tc_model(&c, &mdl);
    unsigned seen_hi = 0, seen_lo = 0, seen_in = 0;
    for (unsigned a = 0; a <= 60; a++)
        for (unsigned b = 0; b <= 60; b++) {
            it2n_point pt;
            it2n_par u = (it2n_par)(((uint64_t)a << IT2N_PAR_FRAC) / 60u);
            it2n_par w = (it2n_par)(((uint64_t)b << IT2N_PAR_FRAC) / 60u);
            assert_int_equal(it2n_eval(&mdl, u, w, &pt, NULL), IT2N_OK);
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
                for (unsigned k = 0; k < 3; k++) {
                    it2n_val v = pt.v[fp][IT2N_CH_T + k];
                    bool bit = (pt.out_of_range >> (fp * 3u + k)) & 1u;
                    if (v > IT2N_VAL_ONE) seen_hi++;
                    else if (v < 0) seen_lo++;
                    else seen_in++;
                    if (bit != (v < 0 || v > IT2N_VAL_ONE))
                        fail_msg("(a=%u,b=%u) %s.%s = %lld: flag %d", a, b,
                                 it2n_fp_name(fp), it2n_ch_name(IT2N_CH_T + k),
                                 (long long)v, (int)bit);
                }
            assert_true(pt.out_of_range < (1u << 21));
        }
    /* the data must really exercise both sides */
    assert_true(seen_hi > 0);
    assert_true(seen_lo > 0);
    assert_true(seen_in > 0);
    /* the raw values are kept, e.g. the middle of the first cell */
    it2n_point pt;
    long double ref[REF_FP][REF_CH];
    static ref_model r;
    tc_ref(&c, &r);
    ref_eval(&r, 1.0L / 12.0L, 1.0L / 12.0L, ref);
    it2n_par h = (it2n_par)llroundl(TC_Q32 / 12.0L);
    assert_int_equal(it2n_eval(&mdl, h, h, &pt, NULL), IT2N_OK);
    printf("  [operations] overshoot T(1/12,1/12) core %.6Lf reference %.6Lf\n",
           tc_ld(pt.v[IT2N_FP_D][IT2N_CH_T]), ref[IT2N_FP_D][IT2N_CH_T]);
    assert_true(fabsl(tc_ld(pt.v[IT2N_FP_D][IT2N_CH_T]) - ref[IT2N_FP_D][IT2N_CH_T]) <= 1e-4L);
}

static void test_eval_param_range_and_state(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl;
    it2n_point pt, du, dw;
    it2n_model_init(&mdl);
    assert_int_equal(mdl.solved, 0);
    assert_int_equal(it2n_eval(&mdl, 0, 0, &pt, NULL), IT2N_ERR_STATE);
    assert_int_equal(it2n_deriv(&mdl, 0, 0, &du, &dw, NULL), IT2N_ERR_STATE);
    tc_paper(&c);
    tc_model(&c, &mdl);
    assert_int_equal(mdl.solved, 1);
    assert_int_equal(it2n_eval(&mdl, -1, 0, &pt, NULL), IT2N_ERR_RANGE);
    assert_int_equal(it2n_eval(&mdl, 0, IT2N_PAR_ONE + 1, &pt, NULL), IT2N_ERR_RANGE);
    assert_int_equal(it2n_eval(&mdl, INT64_MIN, 0, &pt, NULL), IT2N_ERR_RANGE);
    assert_int_equal(it2n_eval(&mdl, 0, INT64_MAX, &pt, NULL), IT2N_ERR_RANGE);
    assert_int_equal(it2n_deriv(&mdl, IT2N_PAR_ONE + 1, 0, &du, &dw, NULL), IT2N_ERR_RANGE);
    assert_int_equal(it2n_eval(&mdl, IT2N_PAR_ONE, IT2N_PAR_ONE, &pt, NULL), IT2N_OK);
    /* S(1,1) is the corner data (3,3,D) = (17,-17) T 0.7 */
    assert_true(llabs(pt.v[IT2N_FP_D][IT2N_CH_X] - 17 * ONE) <= 2);
    assert_true(llabs(pt.v[IT2N_FP_D][IT2N_CH_Y] + 17 * ONE) <= 2);
    assert_true(llabs(pt.v[IT2N_FP_D][IT2N_CH_T] - tc_q24("0.7")) <= 2);
}

/* Every evaluation entry point reports what, where and which limit in
 * it2n_errinfo (issue 7), and a NULL err is allowed. */
static int never_cb(void *ctx, unsigned r, unsigned c, it2n_par u, it2n_par w,
                    const it2n_point *pt)
{
    (void)ctx; (void)r; (void)c; (void)u; (void)w; (void)pt;
    return 0;
}

static void test_errinfo_eval_family(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl;
    it2n_point pt, du, dw;
    it2n_locate_result res;
    it2n_errinfo err;
    it2n_model_init(&mdl);
    memset(&err, 0x55, sizeof err);
    assert_int_equal(it2n_eval(&mdl, 0, 0, &pt, &err), IT2N_ERR_STATE);
    assert_int_equal(err.code, IT2N_ERR_STATE);
    assert_int_equal(it2n_locate(&mdl, 0, 0, &res, &err), IT2N_ERR_STATE);
    assert_int_equal(err.code, IT2N_ERR_STATE);
    assert_int_equal(it2n_sample(&mdl, 3, 3, never_cb, NULL, &err), IT2N_ERR_STATE);
    assert_int_equal(err.code, IT2N_ERR_STATE);
    assert_int_equal(it2n_eval(NULL, 0, 0, &pt, &err), IT2N_ERR_INVAL);
    assert_int_equal(err.code, IT2N_ERR_INVAL);
    tc_paper(&c);
    tc_model(&c, &mdl);
    /* u out of range: channel 0 names u, value in Q24, range [0, 1] */
    assert_int_equal(it2n_eval(&mdl, IT2N_PAR_ONE + 256, 0, &pt, &err), IT2N_ERR_RANGE);
    assert_int_equal(err.code, IT2N_ERR_RANGE);
    assert_int_equal(err.ch, 0);
    assert_true(err.value == IT2N_VAL_ONE + 1);
    assert_true(err.lo == 0 && err.hi == IT2N_VAL_ONE);
    /* w out of range: channel 1 */
    assert_int_equal(it2n_deriv(&mdl, 0, -256, &du, &dw, &err), IT2N_ERR_RANGE);
    assert_int_equal(err.ch, 1);
    assert_true(err.value == -1);
    /* far-off parameters saturate instead of wrapping */
    assert_int_equal(it2n_eval(&mdl, INT64_MIN, 0, &pt, &err), IT2N_ERR_RANGE);
    assert_true(err.value < 0);
    /* sample sizes: rows in i, cols in j, limits 2..65535 */
    assert_int_equal(it2n_sample(&mdl, 1, 5, never_cb, NULL, &err), IT2N_ERR_RANGE);
    assert_true(err.i == 1 && err.j == -1 && err.value == 1 && err.lo == 2 && err.hi == 65535);
    assert_int_equal(it2n_sample(&mdl, 5, 70000, never_cb, NULL, &err), IT2N_ERR_RANGE);
    assert_true(err.i == -1 && err.value == 70000 && err.hi == 65535);
    /* locate: which coordinate, and the limit */
    it2n_val lim = (it2n_val)IT2N_COORD_LIMIT << IT2N_VAL_FRAC;
    assert_int_equal(it2n_locate(&mdl, 0, lim + 1, &res, &err), IT2N_ERR_RANGE);
    assert_true(err.ch == IT2N_CH_Y && err.value == lim + 1 && err.lo == -lim && err.hi == lim);
    assert_int_equal(it2n_locate(&mdl, -lim - 1, 0, &res, &err), IT2N_ERR_RANGE);
    assert_true(err.ch == IT2N_CH_X);
    /* NULL err is fine */
    assert_int_equal(it2n_eval(&mdl, -1, 0, &pt, NULL), IT2N_ERR_RANGE);
}

static void test_generation(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl;
    static it2n_dataset ds;
    it2n_errinfo err;
    it2n_point pt;
    it2n_model_init(&mdl);
    uint32_t g0 = mdl.generation;
    tc_paper(&c);
    tc_dataset(&c, &ds);
    assert_int_equal(it2n_model_solve(&mdl, &ds, &err), IT2N_OK);
    uint32_t g1 = mdl.generation;
    assert_true(g1 != g0);
    /* read-only operations leave it */
    assert_int_equal(it2n_eval(&mdl, 0, 0, &pt, NULL), IT2N_OK);
    assert_true(mdl.generation == g1);
    assert_int_equal(it2n_model_update_fine(&mdl, &ds, 1, 1, IT2N_FP_D,
                                       c.q[1][1][IT2N_FP_D], &err), IT2N_OK);
    uint32_t g2 = mdl.generation;
    assert_true(g2 != g1);
    assert_int_equal(it2n_model_solve(&mdl, &ds, &err), IT2N_OK);
    assert_true(mdl.generation != g2 && mdl.generation != g1);
    /* a failed update does not bump */
    it2n_val v[IT2N_CH_COUNT];
    memcpy(v, c.q[0][0][IT2N_FP_D], sizeof v);
    v[IT2N_CH_T] = -5;
    uint32_t g3 = mdl.generation;
    assert_int_equal(it2n_model_update_fine(&mdl, &ds, 0, 0, IT2N_FP_D, v, &err), IT2N_ERR_RANGE);
    assert_true(mdl.generation == g3);
}

/*
 * Operations on the value-range worst case (7x7, +-IT2N_COORD_LIMIT
 * alternating): each either works (and is accurate) or reports
 * IT2N_ERR_OVERFLOW; never a wrapped result (UBSan build) and failures
 * change nothing.
 */
static void test_extreme_operations(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl, copy;
    static it2n_dataset ds, dscopy;
    static ref_model r;
    it2n_errinfo err;
    tc_extreme(&c);
    tc_model_ds(&c, &mdl, &ds);
    tc_ref(&c, &r);
    uint64_t s = 31;
    unsigned ok = 0, ovf = 0;
    for (unsigned k = 0; k < 20; k++) {
        it2n_par uq, wq;
        long double ue = tc_rand_par(&s, &uq), we = tc_rand_par(&s, &wq);
        it2n_point du, dw;
        long double rdu[REF_FP][REF_CH], rdw[REF_FP][REF_CH];
        int rc = it2n_deriv(&mdl, uq, wq, &du, &dw, NULL);
        if (rc == IT2N_ERR_OVERFLOW) {
            ovf++;
            continue;
        }
        assert_int_equal(rc, IT2N_OK);
        ok++;
        ref_deriv_fd(&r, ue, we, 1e-6L, rdu, rdw);
        long double tol = 2.0L * 7.0L * tc_tol_coord(7, 7, tc_maxabs(&c));
        for (unsigned fp = 0; fp < REF_FP; fp++)
            for (unsigned ch = IT2N_CH_X; ch <= IT2N_CH_Z; ch++) {
                long double e = fmaxl(fabsl(tc_ld(du.v[fp][ch]) - rdu[fp][ch]),
                                      fabsl(tc_ld(dw.v[fp][ch]) - rdw[fp][ch]));
                if (!(e <= tol))
                    fail_msg("extreme deriv (u=%.6Lf,w=%.6Lf) %s.%s: du %.3Lf vs "
                             "%.3Lf, dw %.3Lf vs %.3Lf", ue, we, it2n_fp_name(fp),
                             it2n_ch_name(ch), tc_ld(du.v[fp][ch]), rdu[fp][ch],
                             tc_ld(dw.v[fp][ch]), rdw[fp][ch]);
            }
    }
    printf("  [operations] extreme 7x7 derivatives: %u ok, %u overflow\n", ok, ovf);
    /* locate: any status, but a defined one */
    it2n_locate_result res;
    int rc = it2n_locate(&mdl, 12345 * ONE, -54321 * ONE, &res, NULL);
    assert_int_equal(rc, IT2N_OK);
    for (unsigned fp = 0; fp < REF_FP; fp++) {
        assert_true(res.fp[fp].status <= IT2N_LOC_NOCONV);
        assert_true(res.fp[fp].u >= 0 && res.fp[fp].u <= IT2N_PAR_ONE);
        assert_true(res.fp[fp].w >= 0 && res.fp[fp].w <= IT2N_PAR_ONE);
    }
    /* update a middle point to the other extreme: ok and == re-solve within
     * 1 LSB, or overflow with the model untouched */
    static tc_case c2;
    c2 = c;
    for (unsigned fp = 0; fp < REF_FP; fp++) {
        tc_set(&c2, 3, 4, fp, IT2N_CH_X, -(long double)IT2N_COORD_LIMIT + (long double)fp);
        tc_set(&c2, 3, 4, fp, IT2N_CH_Z, -(long double)IT2N_COORD_LIMIT + (long double)fp);
    }
    copy = mdl;
    dscopy = ds;
    rc = it2n_model_update_fine(&mdl, &ds, 3, 4, IT2N_FP_LL, c2.q[3][4][IT2N_FP_LL], &err);
    printf("  [operations] extreme 7x7 update to -limit: %d (%s)\n", rc,
           it2n_strerror(rc));
    if (rc == IT2N_ERR_OVERFLOW) {
        assert_memory_equal(&mdl, &copy, sizeof mdl);
        assert_memory_equal(&ds, &dscopy, sizeof ds);
    } else {
        assert_int_equal(rc, IT2N_OK);
        static tc_case c3;
        static it2n_model full;
        c3 = c;
        memcpy(c3.q[3][4][IT2N_FP_LL], c2.q[3][4][IT2N_FP_LL], sizeof c3.q[3][4][0]);
        memcpy(c3.v[3][4][IT2N_FP_LL], c2.v[3][4][IT2N_FP_LL], sizeof c3.v[3][4][0]);
        tc_model(&c3, &full);
        if (!tc_nets_equal(&mdl, &full))
            fail_msg("extreme update is not bit-identical to a re-solve");
    }
}

/*
 * Locate with locations far beyond any coordinate (up to INT64_MIN/MAX): the
 * residual x(u,w) - x must not overflow. Either IT2N_ERR_RANGE, or OK with
 * every footprint outside.
 */
static void test_locate_huge_location(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl;
    static const it2n_val xs[][2] = {
        {INT64_MAX, INT64_MIN}, {INT64_MIN, INT64_MAX}, {INT64_MIN, 0},
        {0, INT64_MAX}, {INT64_MAX / 2, -(INT64_MAX / 2)}};
    tc_paper(&c);
    tc_model(&c, &mdl);
    for (unsigned k = 0; k < sizeof xs / sizeof xs[0]; k++) {
        it2n_locate_result res;
        int rc = it2n_locate(&mdl, xs[k][0], xs[k][1], &res, NULL);
        if (rc == IT2N_ERR_RANGE)
            continue;
        if (rc != IT2N_OK)
            fail_msg("locate(%lld, %lld) -> %d", (long long)xs[k][0],
                     (long long)xs[k][1], rc);
        for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
            if (res.fp[fp].status != IT2N_LOC_OUTSIDE)
                fail_msg("locate(%lld, %lld) %s: status %u, expected outside",
                         (long long)xs[k][0], (long long)xs[k][1],
                         it2n_fp_name(fp), res.fp[fp].status);
            assert_true(res.fp[fp].residual > 0);
        }
    }
}

/*
 * A solved model is a function of its data set: solving the same data into
 * structs that held different bytes before it2n_model_init, from different
 * stack contents, gives byte-identical models (no stale or uninitialised
 * memory in unused nets or entries beyond the degrees).
 */
static void dirty_stack(unsigned char fill)
{
    volatile unsigned char junk[16384];
    for (size_t k = 0; k < sizeof junk; k++)
        junk[k] = fill;
}

static void test_model_bytes(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_dataset ds;
    static it2n_model a, b;
    it2n_errinfo err;
    static const unsigned cases[][3] = {
        {3, 3, 0}, {2, 5, IT2N_F_CHORD}, {4, 1, IT2N_F_CHORD | IT2N_F_Z},
        {1, 1, IT2N_F_TYPE1}};
    for (unsigned k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        tc_smooth(&c, cases[k][0], cases[k][1], cases[k][2], 10.0L, k);
        tc_dataset(&c, &ds);
        memset(&a, 0x00, sizeof a);
        memset(&b, 0xFF, sizeof b);
        it2n_model_init(&a);
        it2n_model_init(&b);
        a.generation = b.generation = 0; /* counters may legitimately differ */
        dirty_stack(0x00);
        assert_int_equal(it2n_model_solve(&a, &ds, &err), IT2N_OK);
        dirty_stack(0xA7);
        assert_int_equal(it2n_model_solve(&b, &ds, &err), IT2N_OK);
        const unsigned char *pa = (const void *)&a, *pb = (const void *)&b;
        for (size_t off = 0; off < sizeof a; off++)
            if (pa[off] != pb[off])
                fail_msg("%ux%u flags %u: models differ at byte %zu (frac at "
                         "%zu, net at %zu)", c.n, c.m, c.flags, off,
                         offsetof(it2n_model, frac), offsetof(it2n_model, net));
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_eval_param_range_and_state),
        cmocka_unit_test(test_errinfo_eval_family),
        cmocka_unit_test(test_derivatives),
        cmocka_unit_test(test_sample),
        cmocka_unit_test(test_update_vs_resolve),
        cmocka_unit_test(test_update_chain),
        cmocka_unit_test(test_update_chord),
        cmocka_unit_test(test_chord_params),
        cmocka_unit_test(test_chord_degenerate),
        cmocka_unit_test(test_locate),
        cmocka_unit_test(test_out_of_range_flag),
        cmocka_unit_test(test_generation),
        cmocka_unit_test(test_extreme_operations),
        cmocka_unit_test(test_locate_huge_location),
        cmocka_unit_test(test_model_bytes),
    };
    return cmocka_run_group_tests_name("core operations", tests, NULL, NULL);
}
