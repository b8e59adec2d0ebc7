/* Shared helpers of the core tests; see tc_util.h. */
#include "tc_util.h"

#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

it2n_val tc_q24(const char *s)
{
    long double x = strtold(s, NULL);
    it2n_val expect = (it2n_val)llroundl(x * TC_Q24);
#ifndef TC_NO_TEXT
    it2n_val got = 0;
    int rc = it2n_parse_val(s, strlen(s), &got);
    if (rc != IT2N_OK || got != expect)
        fail_msg("it2n_parse_val(\"%s\") = %d, %lld; expected 0, %lld", s, rc,
                 (long long)got, (long long)expect);
#endif
    return expect;
}

it2n_val tc_q30(const char *s)
{
    long double x = strtold(s, NULL);
    it2n_val expect = (it2n_val)llroundl(x * TC_Q30);
#ifndef TC_NO_TEXT
    it2n_val got = 0;
    int rc = it2n_parse_memb(s, strlen(s), &got);
    if (rc != IT2N_OK || got != expect)
        fail_msg("it2n_parse_memb(\"%s\") = %d, %lld; expected 0, %lld", s, rc,
                 (long long)got, (long long)expect);
#endif
    return expect;
}

it2n_par tc_q32(const char *s)
{
    long double x = strtold(s, NULL);
    it2n_par expect = (it2n_par)llroundl(x * TC_Q32);
#ifndef TC_NO_TEXT
    it2n_par got = 0;
    int rc = it2n_parse_par(s, strlen(s), &got);
    if (rc != IT2N_OK || got != expect)
        fail_msg("it2n_parse_par(\"%s\") = %d, %lld; expected 0, %lld", s, rc,
                 (long long)got, (long long)expect);
#endif
    return expect;
}

it2n_val tc_q24_dec6(long double x, long double *exact)
{
    char buf[64];
    snprintf(buf, sizeof buf, "%.6Lf", x);
    if (strcmp(buf, "-0.000000") == 0)
        strcpy(buf, "0.000000");
    *exact = strtold(buf, NULL);
    return tc_q24(buf);
}

it2n_val tc_fine_dec6(unsigned ch, long double x, long double *exact)
{
    char buf[64];
    if (ch < IT2N_CH_T)
        return tc_q24_dec6(x, exact);
    snprintf(buf, sizeof buf, "%.6Lf", x);
    if (strcmp(buf, "-0.000000") == 0)
        strcpy(buf, "0.000000");
    *exact = strtold(buf, NULL);
    return tc_q30(buf);
}

void tc_set(tc_case *c, unsigned i, unsigned j, unsigned fp, unsigned ch,
            long double x)
{
    c->q[i][j][fp][ch] = tc_fine_dec6(ch, x, &c->v[i][j][fp][ch]);
}

void tc_init(tc_case *c, unsigned n, unsigned m, unsigned flags)
{
    memset(c, 0, sizeof *c);
    c->n = n;
    c->m = m;
    c->flags = flags;
}

/* Rows of examples/paper_4x4.csv as (x, y) of LL (the other footprints step
 * by +2 on both axes) and T, I, F (equal for every footprint). */
static const struct { int x, y; const char *t, *i, *f; } paper[4][4] = {
    {{-23, 11, "0.4", "0.7", "0.2"}, {-23, 1, "0.9", "0.3", "0.1"},
     {-23, -13, "0.4", "0.4", "0.5"}, {-23, -23, "0.6", "0.5", "0.2"}},
    {{-13, 11, "0.6", "0.4", "0.3"}, {-13, 1, "0.8", "0.2", "0.3"},
     {-13, -13, "0.5", "0.5", "0.3"}, {-13, -23, "0.7", "0.4", "0.2"}},
    {{1, 11, "0.6", "0.2", "0.5"}, {1, 1, "0.8", "0.4", "0.1"},
     {1, -13, "0.5", "0.7", "0.1"}, {1, -23, "0.5", "0.3", "0.5"}},
    {{11, 11, "0.7", "0.3", "0.3"}, {11, 1, "0.4", "0.6", "0.3"},
     {11, -13, "0.4", "0.6", "0.3"}, {11, -23, "0.7", "0.4", "0.2"}},
};

void tc_paper(tc_case *c)
{
    tc_init(c, 3, 3, 0);
    for (unsigned i = 0; i < 4; i++)
        for (unsigned j = 0; j < 4; j++)
            for (unsigned fp = 0; fp < REF_FP; fp++) {
                tc_set(c, i, j, fp, IT2N_CH_X, (long double)(paper[i][j].x + 2 * (int)fp));
                tc_set(c, i, j, fp, IT2N_CH_Y, (long double)(paper[i][j].y + 2 * (int)fp));
                tc_set(c, i, j, fp, IT2N_CH_T, strtold(paper[i][j].t, NULL));
                tc_set(c, i, j, fp, IT2N_CH_I, strtold(paper[i][j].i, NULL));
                tc_set(c, i, j, fp, IT2N_CH_F, strtold(paper[i][j].f, NULL));
            }
}

void tc_smooth(tc_case *c, unsigned n, unsigned m, unsigned flags,
               long double scale, unsigned seed)
{
    tc_init(c, n, m, flags);
    long double sd = (long double)seed;
    for (unsigned i = 0; i <= n; i++)
        for (unsigned j = 0; j <= m; j++) {
            long double a = (long double)i / (long double)n;
            long double b = (long double)j / (long double)m;
            long double x = scale * (a + 0.02L * sinl(1.3L * a + 0.7L * b + sd));
            long double y = scale * (b + 0.02L * cosl(0.9L * a - 1.1L * b + sd));
            long double z = scale * (0.3L * sinl(2.0L * a + sd) * cosl(1.5L * b));
            for (unsigned fp = 0; fp < REF_FP; fp++) {
                if ((flags & IT2N_F_TYPE1) && fp != IT2N_FP_D)
                    continue;
                /* Same offset per footprint everywhere keeps the nesting. */
                long double off = ((long double)fp - 3.0L) * scale / 40.0L;
                long double f = (long double)fp;
                tc_set(c, i, j, fp, IT2N_CH_X, x + off);
                tc_set(c, i, j, fp, IT2N_CH_Y, y + 0.5L * off);
                if (flags & IT2N_F_Z)
                    tc_set(c, i, j, fp, IT2N_CH_Z, z + 0.25L * off);
                tc_set(c, i, j, fp, IT2N_CH_T,
                       0.5L + 0.3L * sinl(2.1L * a + 1.7L * b + 0.2L * f + sd));
                tc_set(c, i, j, fp, IT2N_CH_I,
                       0.5L + 0.3L * cosl(1.4L * a - 2.3L * b + 0.3L * f + sd));
                tc_set(c, i, j, fp, IT2N_CH_F,
                       0.5L + 0.3L * sinl(0.7L * a * b + 2.9L * a + 0.1L * f - sd));
            }
        }
}

void tc_extreme(tc_case *c)
{
    unsigned n = IT2N_MAX_DEGREE, m = IT2N_MAX_DEGREE;
    long double lim = (long double)IT2N_COORD_LIMIT;
    tc_init(c, n, m, IT2N_F_Z);
    for (unsigned i = 0; i <= n; i++)
        for (unsigned j = 0; j <= m; j++)
            for (unsigned fp = 0; fp < REF_FP; fp++) {
                long double sgn = ((i + j) & 1u) ? -1.0L : 1.0L;
                /* nested: LL <= ... <= RR, all within the limit */
                long double base = sgn * (lim - 8.0L) + (long double)fp;
                tc_set(c, i, j, fp, IT2N_CH_X, base);
                tc_set(c, i, j, fp, IT2N_CH_Y, -sgn * (lim - 8.0L) + (long double)fp);
                tc_set(c, i, j, fp, IT2N_CH_Z, base);
                tc_set(c, i, j, fp, IT2N_CH_T, (i + j) & 1u ? 0.0L : 1.0L);
                tc_set(c, i, j, fp, IT2N_CH_I, 0.5L);
                tc_set(c, i, j, fp, IT2N_CH_F, (i * j) & 1u ? 1.0L : 0.0L);
            }
}

bool tc_has_fp(const tc_case *c, unsigned fp)
{
    return (c->flags & IT2N_F_TYPE1) ? fp == IT2N_FP_D : fp < IT2N_FP_COUNT;
}

long double tc_maxabs(const tc_case *c)
{
    long double mx = 0.0L;
    for (unsigned i = 0; i <= c->n; i++)
        for (unsigned j = 0; j <= c->m; j++)
            for (unsigned fp = 0; fp < REF_FP; fp++)
                for (unsigned ch = IT2N_CH_X; ch <= IT2N_CH_Z; ch++)
                    if (tc_has_fp(c, fp) && fabsl(c->v[i][j][fp][ch]) > mx)
                        mx = fabsl(c->v[i][j][fp][ch]);
    return mx;
}

void tc_q24_vals(const it2n_val fine[IT2N_CH_COUNT], it2n_val out[IT2N_CH_COUNT])
{
    for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++)
        out[ch] = ch < IT2N_CH_T ? fine[ch] : (fine[ch] + 32) >> 6;
}

void tc_dataset(const tc_case *c, it2n_dataset *ds)
{
    it2n_errinfo err;
    int rc = it2n_dataset_init(ds, c->n, c->m, c->flags, &err);
    assert_int_equal(rc, IT2N_OK);
    for (unsigned i = 0; i <= c->n; i++)
        for (unsigned j = 0; j <= c->m; j++)
            for (unsigned fp = 0; fp < REF_FP; fp++) {
                if (!tc_has_fp(c, fp))
                    continue;
                rc = it2n_dataset_put_fine(ds, i, j, fp, c->q[i][j][fp], false, &err);
                if (rc != IT2N_OK)
                    fail_msg("put (%u,%u,%u) -> %d (ch %d)", i, j, fp, rc, err.ch);
            }
    assert_int_equal(it2n_dataset_missing(ds), 0);
}

void tc_model(const tc_case *c, it2n_model *mdl)
{
    static it2n_dataset ds; /* test-only scratch; tests are single-threaded */
    it2n_errinfo err;
    tc_dataset(c, &ds);
    it2n_model_init(mdl);
    int rc = it2n_model_solve(mdl, &ds, &err);
    if (rc != IT2N_OK)
        fail_msg("solve %ux%u flags %u -> %d (%s) at i=%d j=%d fp=%d ch=%d",
                 c->n, c->m, c->flags, rc, it2n_strerror(rc), err.i, err.j,
                 err.fp, err.ch);
}

void tc_model_ds(const tc_case *c, it2n_model *mdl, it2n_dataset *ds)
{
    it2n_errinfo err;
    tc_dataset(c, ds);
    it2n_model_init(mdl);
    int rc = it2n_model_solve(mdl, ds, &err);
    if (rc != IT2N_OK)
        fail_msg("solve %ux%u flags %u -> %d (%s)", c->n, c->m, c->flags, rc,
                 it2n_strerror(rc));
}

bool tc_nets_equal(const it2n_model *a, const it2n_model *b)
{
    return a->n == b->n && a->m == b->m && a->flags == b->flags &&
           a->solved == b->solved &&
           memcmp(a->frac, b->frac, sizeof a->frac) == 0 &&
           memcmp(a->net, b->net, sizeof a->net) == 0;
}

void tc_params(const tc_case *c, it2n_par u[IT2N_DIM], it2n_par w[IT2N_DIM])
{
    static it2n_dataset ds;
    it2n_errinfo err;
    tc_dataset(c, &ds);
    assert_int_equal(it2n_params(&ds, u, w, &err), IT2N_OK);
}

void tc_ref(const tc_case *c, ref_model *r)
{
    memset(r, 0, sizeof *r);
    r->n = c->n;
    r->m = c->m;
    r->flags = c->flags;
    memcpy(r->data, c->v, sizeof r->data);
    assert_int_equal(ref_solve(r, IT2N_FP_D), 0);
}

long double tc_tol_memb(unsigned n, unsigned m)
{
    return (n <= 3 && m <= 3) ? 2e-5L : 1e-4L;
}

long double tc_tol_coord(unsigned n, unsigned m, long double maxabs)
{
    return 1e-4L + ((n <= 3 && m <= 3) ? 1e-5L : 1e-4L) * maxabs;
}

uint64_t tc_rand(uint64_t *s)
{
    uint64_t x = *s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *s = x;
    return x * 0x2545F4914F6CDD1DULL;
}

long double tc_rand_par(uint64_t *s, it2n_par *q)
{
    unsigned k = (unsigned)(tc_rand(s) % 1000001u);
    char buf[32];
    snprintf(buf, sizeof buf, "%u.%06u", k / 1000000u, k % 1000000u);
    *q = tc_q32(buf);
    return strtold(buf, NULL);
}
