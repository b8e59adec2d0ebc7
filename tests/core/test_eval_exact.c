/*
 * it2n_eval against its own definition, exactly (issue 22): every surface
 * value is the two-stage integer sum documented in it2n_eval.c,
 *   q_j = floor((sum_i B_i(u) P_ij + 2^29) / 2^30),
 *   v = round(sum_j B_j(w) q_j / 2^(6 + frac)) (ties up; a left shift for
 *       6 + frac <= 0, 0 from 63 up),
 * with B the Q30 basis of it2n.h (de Casteljau, one rounding per step, the
 * largest value taking the residue). The reference below is plain int64
 * code, so any evaluation path (the x86-64 SSE2 one evaluates every net
 * biased by 2^31, in 4-column blocks with 1- to 3-column tails) must give
 * the same integers: every degree pair, nets of random and extreme
 * mantissas (INT32_MIN, INT32_MAX), scales from a left shift to zero, and
 * (u, w) at the ends, next to them and spread in between. The summary and
 * out_of_range are checked against their definitions too.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "it2n.h"

static uint64_t rng = 0x9E3779B97F4A7C15u;

static uint32_t rnd32(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (uint32_t)(rng >> 16);
}

/* The Q30 basis of degree deg at t (Q32), as documented for the core. */
static void ref_basis(unsigned deg, int64_t t, int64_t b[IT2N_DIM])
{
    int64_t t30 = (t + 2) >> 2, s30 = ((int64_t)1 << 30) - t30, sum = 0;
    unsigned k, i, big = 0;
    b[0] = (int64_t)1 << 30;
    for (k = 1; k <= deg; k++) {
        b[k] = (t30 * b[k - 1] + ((int64_t)1 << 29)) >> 30;
        for (i = k - 1; i >= 1; i--)
            b[i] = (s30 * b[i] + t30 * b[i - 1] + ((int64_t)1 << 29)) >> 30;
        b[0] = (s30 * b[0] + ((int64_t)1 << 29)) >> 30;
    }
    for (i = 0; i <= deg; i++) {
        sum += b[i];
        big = b[i] > b[big] ? i : big;
    }
    b[big] += ((int64_t)1 << 30) - sum;
}

static int64_t ref_value(const it2n_model *mdl, unsigned fp, unsigned ch, const int64_t *bu, const int64_t *bw)
{
    unsigned n1 = mdl->n + 1u, m1 = mdl->m + 1u;
    const int32_t *net = mdl->net[fp][ch];
    int64_t acc = 0;
    int s = 6 + mdl->frac[fp][ch];
    for (unsigned j = 0; j < m1; j++) {
        int64_t q = 0;
        for (unsigned i = 0; i < n1; i++)
            q += bu[i] * net[i * m1 + j];
        q = (q + ((int64_t)1 << 29)) >> 30;
        acc += bw[j] * q;
    }
    if (s <= 0)
        return (int64_t)((uint64_t)acc << -s);
    if (s >= 63)
        return 0;
    return (acc + ((int64_t)1 << (s - 1))) >> s;
}

/* A model with nets of mantissa kind `kind`: random, all INT32_MIN, all
 * INT32_MAX, alternating extremes, random small. */
static void make_model(it2n_model *mdl, unsigned n, unsigned m, unsigned flags, unsigned kind)
{
    static const int8_t fracs[] = { -8, -6, -5, 0, 16, 20, 24, 31, 40, 56, 57, 127 };
    it2n_model_init(mdl);
    mdl->n = (uint8_t)n;
    mdl->m = (uint8_t)m;
    mdl->flags = (uint8_t)flags;
    mdl->solved = 1;
    for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
        for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++) {
            int8_t f = fracs[rnd32() % (sizeof fracs / sizeof fracs[0])];
            /* A left shift (frac < -6) only where the solve makes one: a
             * net far below 2^31 (Q39.24 holds every value). */
            mdl->frac[fp][ch] = kind != 4 && f < -6 ? -6 : f;
            for (unsigned k = 0; k < (n + 1u) * (m + 1u); k++) {
                uint32_t r = rnd32();
                int32_t v;
                switch (kind) {
                case 1: v = INT32_MIN; break;
                case 2: v = INT32_MAX; break;
                case 3: v = (k + fp + ch) % 2 ? INT32_MIN : INT32_MAX; break;
                case 4: v = (int32_t)(r % 2001u) - 1000; break;
                default: v = (int32_t)r; break;
                }
                mdl->net[fp][ch][k] = v;
            }
        }
}

static void check_point(const it2n_model *mdl, int64_t u, int64_t w)
{
    static const unsigned char upper[3] = { IT2N_FP_LL, IT2N_FP_D, IT2N_FP_RR };
    static const unsigned char lower[3] = { IT2N_FP_LR, IT2N_FP_D, IT2N_FP_RL };
    int64_t bu[IT2N_DIM], bw[IT2N_DIM];
    it2n_point pt;
    int type1 = (mdl->flags & IT2N_F_TYPE1) != 0;
    uint32_t oor = 0;
    memset(&pt, 0x5A, sizeof pt);
    assert_int_equal(it2n_eval(mdl, u, w, &pt, NULL), IT2N_OK);
    ref_basis(mdl->n, u, bu);
    ref_basis(mdl->m, w, bw);
    for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
        for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++) {
            int used = (!type1 || fp == IT2N_FP_D) && (ch != IT2N_CH_Z || (mdl->flags & IT2N_F_Z));
            int64_t want = used ? ref_value(mdl, fp, ch, bu, bw) : 0;
            if (pt.v[fp][ch] != want)
                fail_msg("%ux%u flags %u, u %lld w %lld, fp %u ch %u (frac %d): %lld, expected %lld", mdl->n + 1u,
                         mdl->m + 1u, mdl->flags, (long long)u, (long long)w, fp, ch, mdl->frac[fp][ch],
                         (long long)pt.v[fp][ch], (long long)want);
            if (ch >= IT2N_CH_T && used && (want < 0 || want > IT2N_VAL_ONE))
                oor |= 1u << (fp * 3 + ch - IT2N_CH_T);
        }
    assert_int_equal(pt.out_of_range, oor);
    for (unsigned k = 0; k < 3; k++) {
        unsigned ch = IT2N_CH_T + k;
        int64_t umin = pt.v[IT2N_FP_D][ch], umax = umin, lmin = umin, lmax = umin;
        for (unsigned f = 0; f < 3 && !type1; f++) {
            int64_t a = pt.v[upper[f]][ch], b = pt.v[lower[f]][ch];
            umin = a < umin ? a : umin;
            umax = a > umax ? a : umax;
            lmin = b < lmin ? b : lmin;
            lmax = b > lmax ? b : lmax;
        }
        assert_true(pt.sum.upper_min[k] == umin && pt.sum.upper_max[k] == umax);
        assert_true(pt.sum.lower_min[k] == lmin && pt.sum.lower_max[k] == lmax);
    }
}

static void test_every_degree(void **state)
{
    static it2n_model mdl;
    static const unsigned flag_sets[] = { 0, IT2N_F_Z, IT2N_F_TYPE1 };
    const int64_t one = IT2N_PAR_ONE;
    const int64_t fixed[] = { 0, 1, 3, one / 2, one - 3, one - 1, one };
    /* Where the degree-5 basis has two equal largest values and a rounding
     * residue (-2): the residue goes to the first of them (found by a
     * search near the crossings; random points almost never hit one). */
    const int64_t ties[] = { 715827884, 1431655768, 2863311528, 3579139412 };
    unsigned cases = 0;
    (void)state;
    for (unsigned n = 1; n <= IT2N_MAX_DEGREE; n++)
        for (unsigned m = 1; m <= IT2N_MAX_DEGREE; m++)
            for (unsigned kind = 0; kind < 5; kind++) {
                make_model(&mdl, n, m, flag_sets[(n + m + kind) % 3], kind);
                for (unsigned a = 0; a < sizeof fixed / sizeof fixed[0]; a++)
                    check_point(&mdl, fixed[a], fixed[(a * 3 + 1) % (sizeof fixed / sizeof fixed[0])]);
                for (unsigned k = 0; k < 12; k++)
                    check_point(&mdl, (int64_t)(((uint64_t)rnd32() << 32 | rnd32()) % (uint64_t)(one + 1)),
                                (int64_t)(((uint64_t)rnd32() << 32 | rnd32()) % (uint64_t)(one + 1)));
                for (unsigned a = 0; a < sizeof ties / sizeof ties[0]; a++)
                    check_point(&mdl, ties[a], ties[(a + 1) % (sizeof ties / sizeof ties[0])]);
                cases++;
            }
    printf("eval exact: %u models (every degree pair up to %d), 23 points each, every value as defined\n", cases,
           IT2N_MAX_DEGREE);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_degree),
    };
    return cmocka_run_group_tests_name("core eval exact", tests, NULL, NULL);
}
