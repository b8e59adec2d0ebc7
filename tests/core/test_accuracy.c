/*
 * Accuracy of the core against the long-double reference (issue 2,
 * "Accuracy"): the paper's data set and generated smooth data for every
 * degree pair 1..7 x 1..7 (seven nested footprints with and without z,
 * type-1, chord-length), evaluated at random 6-decimal (u, w) and on the
 * borders; plus the paper's properties: interpolation of every data point,
 * corner control points, convex hull of the control net, affine invariance.
 * Prints the worst error seen per degree class.
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

/* Worst errors, [0] = degree <= 3 both ways, [1] = degree <= 7. */
typedef struct acc_stats {
    long double memb[2], coord[2], coord_ratio[2], hull_lsb;
    unsigned long checks, failures;
} acc_stats;

static acc_stats g_stats;

#define MAX_REPORTS 12

static void acc_fail(acc_stats *st, const char *fmt, ...)
{
    st->failures++;
    if (st->failures > MAX_REPORTS)
        return;
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "  MISMATCH: ");
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

static unsigned n_channels_checked(const tc_case *c, unsigned ch)
{
    return ch == IT2N_CH_Z && !(c->flags & IT2N_F_Z) ? 0u : 1u;
}

/* Compare one core evaluation with the reference at exact (ue, we). */
static void acc_point(const tc_case *c, const it2n_model *mdl,
                      const ref_model *r, long double ue, long double we,
                      it2n_par uq, it2n_par wq, acc_stats *st,
                      const char *label)
{
    it2n_point pt;
    long double ref[REF_FP][REF_CH];
    int cls = (c->n <= 3 && c->m <= 3) ? 0 : 1;
    long double tm = tc_tol_memb(c->n, c->m);
    long double maxabs = tc_maxabs(c);
    long double tcd = tc_tol_coord(c->n, c->m, maxabs);

    int rc = it2n_eval(mdl, uq, wq, &pt, NULL);
    if (rc != IT2N_OK) {
        acc_fail(st, "%s: it2n_eval(u=%.6Lf, w=%.6Lf, NULL) -> %d", label, ue, we, rc);
        return;
    }
    ref_eval(r, ue, we, ref);
    for (unsigned fp = 0; fp < REF_FP; fp++) {
        if (!tc_has_fp(c, fp))
            continue;
        for (unsigned ch = 0; ch < REF_CH; ch++) {
            st->checks++;
            if (!n_channels_checked(c, ch)) {
                if (pt.v[fp][ch] != 0)
                    acc_fail(st, "%s: z of a model without z is %lld, not 0",
                             label, (long long)pt.v[fp][ch]);
                continue;
            }
            long double got = tc_ld(pt.v[fp][ch]);
            long double e = fabsl(got - ref[fp][ch]);
            bool memb = ch >= IT2N_CH_T;
            long double tol = memb ? tm : tcd;
            if (memb) {
                if (e > st->memb[cls])
                    st->memb[cls] = e;
            } else {
                if (e > st->coord[cls])
                    st->coord[cls] = e;
                if (e / tcd > st->coord_ratio[cls])
                    st->coord_ratio[cls] = e / tcd;
            }
            if (!(e <= tol))
                acc_fail(st, "%s %ux%u flags %u: (u=%.6Lf, w=%.6Lf) %s.%s got "
                         "%.9Lf expected %.9Lf err %.3Le > tol %.3Le",
                         label, c->n, c->m, c->flags, ue, we, it2n_fp_name(fp),
                         it2n_ch_name(ch), got, ref[fp][ch], e, tol);

            /* Convex hull of this channel's control net (exact maths; the
             * fixed-point sum may round by a couple of LSB). */
            it2n_val lo = it2n_model_ctrl(mdl, 0, 0, fp, ch), hi = lo;
            for (unsigned i = 0; i <= c->n; i++)
                for (unsigned j = 0; j <= c->m; j++) {
                    it2n_val p = it2n_model_ctrl(mdl, i, j, fp, ch);
                    lo = p < lo ? p : lo;
                    hi = p > hi ? p : hi;
                }
            it2n_val v = pt.v[fp][ch];
            long double out = v < lo ? (long double)(lo - v)
                            : v > hi ? (long double)(v - hi) : 0.0L;
            if (out > st->hull_lsb)
                st->hull_lsb = out;
            if (out > 2.0L)
                acc_fail(st, "%s %ux%u: (u=%.6Lf, w=%.6Lf) %s.%s = %lld outside "
                         "control hull [%lld, %lld]", label, c->n, c->m, ue, we,
                         it2n_fp_name(fp), it2n_ch_name(ch), (long long)v,
                         (long long)lo, (long long)hi);
        }
        /* out_of_range bit k of footprint fp <=> membership outside [0,1]. */
        for (unsigned k = 0; k < 3; k++) {
            it2n_val v = pt.v[fp][IT2N_CH_T + k];
            bool oor = v < 0 || v > IT2N_VAL_ONE;
            bool bit = (pt.out_of_range >> (fp * 3u + k)) & 1u;
            if (oor != bit)
                acc_fail(st, "%s: out_of_range bit %u is %d for value %lld",
                         label, fp * 3u + k, (int)bit, (long long)v);
        }
    }
    if (c->flags & IT2N_F_TYPE1)
        return;
    /* Interval summary: exact min/max over {LL,D,RR} and {LR,D,RL}. */
    for (unsigned k = 0; k < 3; k++) {
        unsigned ch = IT2N_CH_T + k;
        it2n_val a = pt.v[IT2N_FP_LL][ch], d = pt.v[IT2N_FP_D][ch],
                 b = pt.v[IT2N_FP_RR][ch];
        it2n_val umin = a < d ? (a < b ? a : b) : (d < b ? d : b);
        it2n_val umax = a > d ? (a > b ? a : b) : (d > b ? d : b);
        a = pt.v[IT2N_FP_LR][ch];
        b = pt.v[IT2N_FP_RL][ch];
        it2n_val lmin = a < d ? (a < b ? a : b) : (d < b ? d : b);
        it2n_val lmax = a > d ? (a > b ? a : b) : (d > b ? d : b);
        if (pt.sum.upper_min[k] != umin || pt.sum.upper_max[k] != umax ||
            pt.sum.lower_min[k] != lmin || pt.sum.lower_max[k] != lmax)
            acc_fail(st, "%s: summary %s upper [%lld,%lld] lower [%lld,%lld], "
                     "expected [%lld,%lld] [%lld,%lld]", label,
                     it2n_ch_name(ch), (long long)pt.sum.upper_min[k],
                     (long long)pt.sum.upper_max[k],
                     (long long)pt.sum.lower_min[k],
                     (long long)pt.sum.lower_max[k], (long long)umin,
                     (long long)umax, (long long)lmin, (long long)lmax);
    }
}

/* Interpolation of every data point and corner control points. */
static void acc_nodes(const tc_case *c, const it2n_model *mdl,
                      const ref_model *r, acc_stats *st, const char *label)
{
    it2n_par mu[REF_D], mw[REF_D];
    tc_params(c, mu, mw);
    long double tm = tc_tol_memb(c->n, c->m);
    long double tcd = tc_tol_coord(c->n, c->m, tc_maxabs(c));
    for (unsigned i = 0; i <= c->n; i++) {
        long double e = fabsl(tc_ldp(mu[i]) - r->u[i]);
        if (e > 1e-6L)
            acc_fail(st, "%s %ux%u: u[%u] = %.9Lf, reference %.9Lf", label,
                     c->n, c->m, i, tc_ldp(mu[i]), r->u[i]);
    }
    for (unsigned j = 0; j <= c->m; j++) {
        long double e = fabsl(tc_ldp(mw[j]) - r->w[j]);
        if (e > 1e-6L)
            acc_fail(st, "%s %ux%u: w[%u] = %.9Lf, reference %.9Lf", label,
                     c->n, c->m, j, tc_ldp(mw[j]), r->w[j]);
    }
    for (unsigned i = 0; i <= c->n; i++)
        for (unsigned j = 0; j <= c->m; j++) {
            it2n_point pt;
            int rc = it2n_eval(mdl, mu[i], mw[j], &pt, NULL);
            if (rc != IT2N_OK) {
                acc_fail(st, "%s: eval at node (%u,%u) -> %d", label, i, j, rc);
                continue;
            }
            bool corner = (i == 0 || i == c->n) && (j == 0 || j == c->m);
            for (unsigned fp = 0; fp < REF_FP; fp++) {
                if (!tc_has_fp(c, fp))
                    continue;
                for (unsigned ch = 0; ch < REF_CH; ch++) {
                    if (!n_channels_checked(c, ch))
                        continue;
                    long double tol = ch >= IT2N_CH_T ? tm : tcd;
                    long double want = c->v[i][j][fp][ch];
                    long double e = fabsl(tc_ld(pt.v[fp][ch]) - want);
                    st->checks++;
                    if (!(e <= tol))
                        acc_fail(st, "%s %ux%u: S(u_%u, w_%u) %s.%s = %.9Lf, data "
                                 "%.6Lf (err %.3Le)", label, c->n, c->m, i, j,
                                 it2n_fp_name(fp), it2n_ch_name(ch),
                                 tc_ld(pt.v[fp][ch]), want, e);
                    if (corner) {
                        e = fabsl(tc_ld(it2n_model_ctrl(mdl, i, j, fp, ch)) - want);
                        if (!(e <= tol))
                            acc_fail(st, "%s %ux%u: corner control P[%u][%u] "
                                     "%s.%s = %.9Lf, data %.6Lf", label, c->n,
                                     c->m, i, j, it2n_fp_name(fp),
                                     it2n_ch_name(ch),
                                     tc_ld(it2n_model_ctrl(mdl, i, j, fp, ch)), want);
                    }
                }
            }
        }
}

static void acc_case(const tc_case *c, acc_stats *st, uint64_t seed,
                     unsigned npts, const char *label)
{
    static it2n_model mdl;
    static ref_model r;
    tc_model(c, &mdl);
    tc_ref(c, &r);
    acc_nodes(c, &mdl, &r, st, label);
    uint64_t s = seed * 0x9E3779B97F4A7C15ULL + 1u;
    for (unsigned k = 0; k < npts + 8u; k++) {
        it2n_par uq, wq;
        long double ue = tc_rand_par(&s, &uq), we = tc_rand_par(&s, &wq);
        /* Borders: u or w exactly 0 or 1, and the four corners. */
        if (k >= npts) {
            unsigned b = k - npts;
            if (b < 4) {
                ue = (b & 1u) ? 1.0L : 0.0L;
                uq = (b & 1u) ? IT2N_PAR_ONE : 0;
                if (b & 2u) {
                    we = ue;
                    wq = uq;
                }
            } else {
                we = (b & 1u) ? 1.0L : 0.0L;
                wq = (b & 1u) ? IT2N_PAR_ONE : 0;
                if (b & 2u) {
                    ue = 1.0L - we;
                    uq = IT2N_PAR_ONE - wq;
                }
            }
        }
        acc_point(c, &mdl, &r, ue, we, uq, wq, st, label);
    }
}

/*
 * Control nets against the exact solution of the data the core was given
 * (Q24 coordinates, Q30 memberships, the core's own parameters): every control point within
 * 1e-6 * max|control point of its net| + 1e-7 (issue 7). Returns the worst
 * err / tolerance ratio.
 */
static long double net_case(const tc_case *c, const char *label,
                            long double *worst_rel)
{
    static it2n_model mdl;
    static ref_model r;
    it2n_par u[REF_D], w[REF_D];
    long double ratio = 0.0L;
    tc_model(c, &mdl);
    tc_params(c, u, w);
    memset(&r, 0, sizeof r);
    r.n = c->n;
    r.m = c->m;
    r.flags = c->flags;
    for (unsigned i = 0; i <= c->n; i++)
        for (unsigned j = 0; j <= c->m; j++)
            for (unsigned fp = 0; fp < REF_FP; fp++)
                for (unsigned ch = 0; ch < REF_CH; ch++)
                    r.data[i][j][fp][ch] = tc_ldq(ch, c->q[i][j][fp][ch]);
    for (unsigned k = 0; k <= c->n; k++)
        r.u[k] = tc_ldp(u[k]);
    for (unsigned k = 0; k <= c->m; k++)
        r.w[k] = tc_ldp(w[k]);
    assert_int_equal(ref_solve_params(&r), 0);
    for (unsigned fp = 0; fp < REF_FP; fp++) {
        if (!tc_has_fp(c, fp))
            continue;
        for (unsigned ch = 0; ch < REF_CH; ch++) {
            if (!n_channels_checked(c, ch))
                continue;
            long double big = 0.0L;
            for (unsigned i = 0; i <= c->n; i++)
                for (unsigned j = 0; j <= c->m; j++)
                    big = fmaxl(big, fabsl(r.ctrl[i][j][fp][ch]));
            long double tol = 1e-6L * big + 1e-7L;
            for (unsigned i = 0; i <= c->n; i++)
                for (unsigned j = 0; j <= c->m; j++) {
                    long double got = tc_ld(it2n_model_ctrl(&mdl, i, j, fp, ch));
                    long double e = fabsl(got - r.ctrl[i][j][fp][ch]);
                    if (e / tol > ratio)
                        ratio = e / tol;
                    if (big > 0.0L && e / big > *worst_rel)
                        *worst_rel = e / big;
                    if (!(e <= tol))
                        fail_msg("%s %ux%u flags %u: P[%u][%u] %s.%s = %.9Lf, exact "
                                 "%.9Lf (err %.3Le > tol %.3Le, net max %.3Le)",
                                 label, c->n, c->m, c->flags, i, j,
                                 it2n_fp_name(fp), it2n_ch_name(ch), got,
                                 r.ctrl[i][j][fp][ch], e, tol, big);
                }
        }
    }
    return ratio;
}

static void test_control_nets(void **state)
{
    (void)state;
    static tc_case c;
    static const unsigned flagsets[] = {0u, IT2N_F_Z, IT2N_F_CHORD,
                                        IT2N_F_CHORD | IT2N_F_Z, IT2N_F_TYPE1};
    static const long double scales[] = {10.0L, 5000.0L};
    long double worst = 0.0L, worst_rel = 0.0L;
    unsigned cases = 0;
    for (unsigned f = 0; f < sizeof flagsets / sizeof flagsets[0]; f++)
        for (unsigned sc = 0; sc < 2; sc++)
            for (unsigned n = 1; n <= 7 && n <= IT2N_MAX_DEGREE; n++)
                for (unsigned m = 1; m <= 7 && m <= IT2N_MAX_DEGREE; m++) {
                    tc_smooth(&c, n, m, flagsets[f], scales[sc], n * 31u + m + f);
                    worst = fmaxl(worst, net_case(&c, "nets", &worst_rel));
                    cases++;
                }
    if (IT2N_MAX_DEGREE >= 7) {
        tc_extreme(&c);
        worst = fmaxl(worst, net_case(&c, "nets extreme", &worst_rel));
        cases++;
    }
    printf("  [accuracy] control nets: %u models, worst err %.3Le of the net's "
           "max|P|, %.3Lf of the tolerance 1e-6 max|P| + 1e-7\n",
           cases, worst_rel, worst);
}

/*
 * Issue 21: memberships are parsed and stored at 2^-30 so that the degree-7
 * control nets of memberships come within 1e-5 of the exact solution of
 * the decimal data (input rounding included; with Q24 input it was up to
 * 5e-4). Every membership control point of 7x7 models (smooth data with
 * and without z, type-1, chord-length; the paper's values on a 7x7 grid;
 * the alternating 0/1 worst case) against the exact decimals solved with
 * the core's own parameters (so coordinates' rounding does not enter
 * through chord-length parameters). Returns the worst |error|.
 */
static long double memb_net_case(const tc_case *c, const char *label,
                                 long double *big_max)
{
    static it2n_model mdl;
    static ref_model r;
    it2n_par u[REF_D], w[REF_D];
    long double worst = 0.0L;
    tc_model(c, &mdl);
    tc_params(c, u, w);
    memset(&r, 0, sizeof r);
    r.n = c->n;
    r.m = c->m;
    r.flags = c->flags;
    memcpy(r.data, c->v, sizeof r.data);
    for (unsigned k = 0; k <= c->n; k++)
        r.u[k] = tc_ldp(u[k]);
    for (unsigned k = 0; k <= c->m; k++)
        r.w[k] = tc_ldp(w[k]);
    assert_int_equal(ref_solve_params(&r), 0);
    for (unsigned fp = 0; fp < REF_FP; fp++) {
        if (!tc_has_fp(c, fp))
            continue;
        for (unsigned ch = IT2N_CH_T; ch <= IT2N_CH_F; ch++) {
            long double big = 0.0L;
            for (unsigned i = 0; i <= c->n; i++)
                for (unsigned j = 0; j <= c->m; j++)
                    big = fmaxl(big, fabsl(r.ctrl[i][j][fp][ch]));
            /* 1e-5, plus the nets' own relative precision (31-bit
             * mantissas, 2^-30 of max|P| with the solve's roundings), which
             * only matters for nets beyond 1e3 (the alternating case) */
            long double tol = 1e-5L + 1e-9L * big;
            if (big > *big_max)
                *big_max = big;
            for (unsigned i = 0; i <= c->n; i++)
                for (unsigned j = 0; j <= c->m; j++) {
                    long double got = tc_ld(it2n_model_ctrl(&mdl, i, j, fp, ch));
                    long double e = fabsl(got - r.ctrl[i][j][fp][ch]);
                    worst = fmaxl(worst, e);
                    if (!(e <= tol))
                        fail_msg("%s %ux%u flags %u: P[%u][%u] %s.%s = %.9Lf, exact "
                                 "solution of the decimal data %.9Lf (err %.3Le > %.3Le)",
                                 label, c->n, c->m, c->flags, i, j,
                                 it2n_fp_name(fp), it2n_ch_name(ch), got,
                                 r.ctrl[i][j][fp][ch], e, tol);
                }
        }
    }
    return worst;
}

static void test_memb_nets_decimal(void **state)
{
    (void)state;
    static tc_case c;
    static const unsigned flagsets[] = {0u, IT2N_F_Z, IT2N_F_CHORD, IT2N_F_TYPE1,
                                        IT2N_F_CHORD | IT2N_F_Z | IT2N_F_TYPE1};
    static const char *const memb[] = {"0.4", "0.7", "0.2", "0.9", "0.3", "0.1",
                                       "0.5", "0.6", "0.8"};
    long double worst = 0.0L, big = 0.0L, xbig = 0.0L, xworst;
    unsigned cases = 0;
    if (IT2N_MAX_DEGREE < 7) {
        printf("test_memb_nets_decimal: skip: IT2N_MAX_DEGREE %d < 7\n",
               IT2N_MAX_DEGREE);
        return;
    }
    for (unsigned f = 0; f < sizeof flagsets / sizeof flagsets[0]; f++)
        for (unsigned seed = 0; seed < 4; seed++) {
            tc_smooth(&c, 7, 7, flagsets[f], 10.0L, 1000u + seed * 7u + f);
            worst = fmaxl(worst, memb_net_case(&c, "smooth", &big));
            cases++;
        }
    /* the paper's membership values (one decimal) spread over 7x7 */
    tc_init(&c, 7, 7, 0);
    for (unsigned i = 0; i <= 7; i++)
        for (unsigned j = 0; j <= 7; j++)
            for (unsigned fp = 0; fp < REF_FP; fp++) {
                tc_set(&c, i, j, fp, IT2N_CH_X, 10.0L * i + 0.5L * fp);
                tc_set(&c, i, j, fp, IT2N_CH_Y, 10.0L * j + 0.5L * fp);
                for (unsigned k = 0; k < 3; k++)
                    tc_set(&c, i, j, fp, IT2N_CH_T + k,
                           strtold(memb[(i * 5u + j * 3u + k * 2u + fp) % 9u], NULL));
            }
    worst = fmaxl(worst, memb_net_case(&c, "paper values 7x7", &big));
    cases++;
    /* exact data (0, 0.5, 1): no input rounding, nets of 8.8e3 */
    tc_extreme(&c);
    xworst = memb_net_case(&c, "alternating 0/1", &xbig);
    printf("  [accuracy] degree-7 membership nets vs the decimal data: %u models "
           "(max|P| %.0Lf), worst |err| %.3Le (goal 1e-5); alternating 0/1 "
           "(max|P| %.0Lf) %.3Le\n", cases, big, worst, xbig, xworst);
    if (!(worst <= 1e-5L))
        fail_msg("membership nets: worst %.3Le > 1e-5", worst);
}

static void acc_report(const char *what, const acc_stats *st)
{
    printf("  [accuracy] %-28s worst |err|: deg<=3 memb %.3Le coord %.3Le "
           "(%.3f of tol); deg<=7 memb %.3Le coord %.3Le (%.3f of tol); "
           "hull overshoot %.0Lf LSB; %lu checks\n",
           what, st->memb[0], st->coord[0], (double)st->coord_ratio[0],
           st->memb[1], st->coord[1], (double)st->coord_ratio[1],
           st->hull_lsb, st->checks);
}

static void acc_merge(const acc_stats *st)
{
    for (int k = 0; k < 2; k++) {
        g_stats.memb[k] = fmaxl(g_stats.memb[k], st->memb[k]);
        g_stats.coord[k] = fmaxl(g_stats.coord[k], st->coord[k]);
        g_stats.coord_ratio[k] = fmaxl(g_stats.coord_ratio[k], st->coord_ratio[k]);
    }
    g_stats.hull_lsb = fmaxl(g_stats.hull_lsb, st->hull_lsb);
    g_stats.checks += st->checks;
    g_stats.failures += st->failures;
}

static void acc_finish(const char *what, const acc_stats *st)
{
    acc_report(what, st);
    acc_merge(st);
    if (st->checks == 0)
        fail_msg("%s: no check ran (a test that checks nothing passes nothing)",
                 what);
    if (st->failures)
        fail_msg("%s: %lu of %lu checks out of tolerance", what, st->failures,
                 st->checks);
}

static void test_paper(void **state)
{
    (void)state;
    static tc_case c;
    acc_stats st = {0};
    tc_paper(&c);
    acc_case(&c, &st, 1, 400, "paper");
    acc_finish("paper 4x4", &st);
}

/* Every degree pair 1..7 x 1..7 with the given flags and coordinate scale. */
static void sweep(unsigned flags, long double scale, const char *what)
{
    static tc_case c;
    acc_stats st = {0};
    char label[64];
    for (unsigned n = 1; n <= IT2N_MAX_DEGREE; n++)
        for (unsigned m = 1; m <= IT2N_MAX_DEGREE; m++) {
            tc_smooth(&c, n, m, flags, scale, n * 16u + m);
            snprintf(label, sizeof label, "%s", what);
            acc_case(&c, &st, n * 131u + m * 7u + flags, 40, label);
        }
    acc_finish(what, &st);
}

static void test_sweep_xy(void **state)
{
    (void)state;
    sweep(0, 10.0L, "smooth x,y scale 10");
}

static void test_sweep_xyz(void **state)
{
    (void)state;
    sweep(IT2N_F_Z, 10.0L, "smooth x,y,z scale 10");
}

static void test_sweep_xyz_large(void **state)
{
    (void)state;
    sweep(IT2N_F_Z, 5000.0L, "smooth x,y,z scale 5000");
}

static void test_sweep_type1(void **state)
{
    (void)state;
    sweep(IT2N_F_TYPE1, 10.0L, "type-1 x,y");
    sweep(IT2N_F_TYPE1 | IT2N_F_Z, 100.0L, "type-1 x,y,z scale 100");
}

static void test_sweep_chord(void **state)
{
    (void)state;
    sweep(IT2N_F_CHORD, 10.0L, "chord x,y");
    sweep(IT2N_F_CHORD | IT2N_F_Z | IT2N_F_TYPE1, 10.0L, "chord type-1 x,y,z");
}

/*
 * Affine invariance: map x,y(,z) by A p + b (non-negative A keeps the
 * nesting), re-solve, compare with A S(u,w) + b of the original model.
 * Memberships are untouched, so their surfaces must be bit-identical.
 */
static void affine_case(const tc_case *c0, acc_stats *st)
{
    static const long double a[3][3] = {
        {1.5L, 0.25L, 0.125L}, {0.5L, 0.75L, 0.0L}, {0.2L, 0.1L, 1.1L}};
    static const long double b[3] = {3.25L, -7.5L, 2.0L};
    static tc_case c1;
    static it2n_model m0, m1;
    unsigned dims = (c0->flags & IT2N_F_Z) ? 3u : 2u;
    c1 = *c0;
    for (unsigned i = 0; i <= c0->n; i++)
        for (unsigned j = 0; j <= c0->m; j++)
            for (unsigned fp = 0; fp < REF_FP; fp++) {
                if (!tc_has_fp(c0, fp))
                    continue;
                for (unsigned d = 0; d < dims; d++) {
                    long double s = b[d];
                    for (unsigned e = 0; e < dims; e++)
                        s += a[d][e] * c0->v[i][j][fp][e];
                    tc_set(&c1, i, j, fp, d, s);
                }
            }
    tc_model(c0, &m0);
    tc_model(&c1, &m1);
    long double t0 = tc_tol_coord(c0->n, c0->m, tc_maxabs(c0));
    long double t1 = tc_tol_coord(c1.n, c1.m, tc_maxabs(&c1));
    /* The transformed data are rounded to 6 decimals: <= 5e-7 per point,
     * amplified by at most the Lebesgue constant (< 100 up to degree 7). */
    long double tol = t1 + 1.75L * t0 + 5e-5L;
    uint64_t s = 77;
    for (unsigned k = 0; k < 60; k++) {
        it2n_par uq, wq;
        long double ue = tc_rand_par(&s, &uq), we = tc_rand_par(&s, &wq);
        it2n_point p0, p1;
        assert_int_equal(it2n_eval(&m0, uq, wq, &p0, NULL), IT2N_OK);
        assert_int_equal(it2n_eval(&m1, uq, wq, &p1, NULL), IT2N_OK);
        for (unsigned fp = 0; fp < REF_FP; fp++) {
            if (!tc_has_fp(c0, fp))
                continue;
            for (unsigned d = 0; d < dims; d++) {
                long double want = b[d];
                for (unsigned e = 0; e < dims; e++)
                    want += a[d][e] * tc_ld(p0.v[fp][e]);
                long double err = fabsl(tc_ld(p1.v[fp][d]) - want);
                st->checks++;
                if (!(err <= tol))
                    acc_fail(st, "affine %ux%u (u=%.6Lf,w=%.6Lf) %s.%s: %.9Lf vs "
                             "%.9Lf (err %.3Le > %.3Le)", c0->n, c0->m, ue, we,
                             it2n_fp_name(fp), it2n_ch_name(d),
                             tc_ld(p1.v[fp][d]), want, err, tol);
            }
            for (unsigned ch = IT2N_CH_T; ch <= IT2N_CH_F; ch++) {
                st->checks++;
                if (p0.v[fp][ch] != p1.v[fp][ch])
                    acc_fail(st, "affine %ux%u: membership %s.%s changed %lld -> "
                             "%lld", c0->n, c0->m, it2n_fp_name(fp),
                             it2n_ch_name(ch), (long long)p0.v[fp][ch],
                             (long long)p1.v[fp][ch]);
            }
        }
    }
}

static void test_affine(void **state)
{
    (void)state;
    static tc_case c;
    acc_stats st = {0};
    tc_paper(&c);
    affine_case(&c, &st);
    static const unsigned pairs[][2] = {{1, 1}, {2, 5}, {3, 3}, {4, 7}, {7, 7}};
    for (unsigned k = 0; k < sizeof pairs / sizeof pairs[0]; k++) {
        tc_smooth(&c, pairs[k][0], pairs[k][1], 0, 10.0L, k);
        affine_case(&c, &st);
        tc_smooth(&c, pairs[k][0], pairs[k][1], IT2N_F_Z, 10.0L, k);
        affine_case(&c, &st);
    }
    printf("  [accuracy] affine invariance: %lu checks, %lu failures\n",
           st.checks, st.failures);
    if (st.failures)
        fail_msg("affine invariance: %lu of %lu checks failed", st.failures,
                 st.checks);
}

/*
 * Worst case for the value range: degree 7x7, coordinates alternating
 * +-IT2N_COORD_LIMIT. The header promises the control points still fit, so
 * the solve must succeed and interpolate (or report IT2N_ERR_OVERFLOW —
 * never wrap).
 */
static void test_extreme_coordinates(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl;
    static ref_model r;
    static it2n_dataset ds;
    acc_stats st = {0};
    tc_extreme(&c);
    tc_dataset(&c, &ds);
    it2n_model_init(&mdl);
    it2n_errinfo err;
    int rc = it2n_model_solve(&mdl, &ds, &err);
    printf("  [accuracy] alternating +-COORD_LIMIT 7x7: solve -> %d (%s)\n", rc,
           it2n_strerror(rc));
    if (rc == IT2N_ERR_OVERFLOW)
        return;
    assert_int_equal(rc, IT2N_OK);
    tc_ref(&c, &r);
    acc_nodes(&c, &mdl, &r, &st, "extreme");
    uint64_t s = 5;
    for (unsigned k = 0; k < 20; k++) {
        it2n_par uq, wq;
        long double ue = tc_rand_par(&s, &uq), we = tc_rand_par(&s, &wq);
        acc_point(&c, &mdl, &r, ue, we, uq, wq, &st, "extreme");
    }
    acc_finish("alternating +-limit 7x7", &st);
}

/* The summary docs/numerics.md quotes: the merged worst case of every test
 * above. It must hold checks, no failure and coordinates within their
 * tolerance (worst ratio <= 1) in both degree classes: the figure the
 * docs print is itself checked, not only printed. */
static void test_print_summary(void **state)
{
    (void)state;
    acc_report("ALL (for docs/numerics.md)", &g_stats);
    assert_true(g_stats.checks > 0);
    assert_int_equal(g_stats.failures, 0);
    assert_true(g_stats.coord_ratio[0] <= 1.0L && g_stats.coord_ratio[1] <= 1.0L);
    assert_true(g_stats.memb[0] <= tc_tol_memb(3, 3) &&
                g_stats.memb[1] <= tc_tol_memb(7, 7));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_paper),
        cmocka_unit_test(test_sweep_xy),
        cmocka_unit_test(test_sweep_xyz),
        cmocka_unit_test(test_sweep_xyz_large),
        cmocka_unit_test(test_sweep_type1),
        cmocka_unit_test(test_sweep_chord),
        cmocka_unit_test(test_affine),
        cmocka_unit_test(test_control_nets),
        cmocka_unit_test(test_memb_nets_decimal),
        cmocka_unit_test(test_extreme_coordinates),
        cmocka_unit_test(test_print_summary),
    };
    return cmocka_run_group_tests_name("core accuracy", tests, NULL, NULL);
}
