/*
 * Validation at the C API level (issue 2, "Validation"): every rejected input
 * returns the documented negative code with the detail fields (i, j, fp, ch,
 * value, lo, hi) filled, and a failed it2n_dataset_put / it2n_model_solve /
 * it2n_model_update leaves its struct byte-identical.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "it2n.h"
#include "tc_util.h"

#define ONE IT2N_VAL_ONE
#define LIM ((it2n_val)IT2N_COORD_LIMIT * IT2N_VAL_ONE)

static void expect_err(const it2n_errinfo *e, int code, int i, int j, int fp,
                       int ch)
{
    assert_int_equal(e->code, code);
    assert_int_equal(e->i, i);
    assert_int_equal(e->j, j);
    assert_int_equal(e->fp, fp);
    assert_int_equal(e->ch, ch);
}

/* A valid D-footprint value vector. */
static void vals_ok(it2n_val v[IT2N_CH_COUNT])
{
    v[IT2N_CH_X] = 3 * ONE;
    v[IT2N_CH_Y] = -2 * ONE;
    v[IT2N_CH_Z] = ONE / 2;
    v[IT2N_CH_T] = ONE / 4;
    v[IT2N_CH_I] = ONE / 2;
    v[IT2N_CH_F] = ONE;
}

static void test_dataset_init_bad_degree(void **state)
{
    (void)state;
    static it2n_dataset ds, copy;
    it2n_errinfo err;
    memset(&ds, 0xA5, sizeof ds);
    copy = ds;
    static const unsigned bad[][2] = {
        {0, 1}, {1, 0}, {IT2N_MAX_DEGREE + 1, 1}, {1, IT2N_MAX_DEGREE + 1}, {0, 0},
        {255, 3}, {3, 256}};
    for (unsigned k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        memset(&err, 0, sizeof err);
        assert_int_equal(it2n_dataset_init(&ds, bad[k][0], bad[k][1], 0, &err),
                         IT2N_ERR_INVAL);
        assert_int_equal(err.code, IT2N_ERR_INVAL);
        /* which limit: the offending degree and the accepted range */
        unsigned badv = (bad[k][0] < 1u || bad[k][0] > IT2N_MAX_DEGREE) ? bad[k][0]
                                                                        : bad[k][1];
        assert_true(err.value == (it2n_val)badv);
        assert_true(err.lo == 1 && err.hi == IT2N_MAX_DEGREE);
        assert_memory_equal(&ds, &copy, sizeof ds);
    }
    /* unknown flag bits */
    assert_int_equal(it2n_dataset_init(&ds, 2, 2, 0x80u, &err), IT2N_ERR_INVAL);
    assert_int_equal(it2n_dataset_init(&ds, 2, 2, IT2N_F_ALL + 1u, &err),
                     IT2N_ERR_INVAL);
    assert_memory_equal(&ds, &copy, sizeof ds);
    /* limits accepted */
    assert_int_equal(it2n_dataset_init(&ds, 1, IT2N_MAX_DEGREE, IT2N_F_ALL, &err),
                     IT2N_OK);
    assert_int_equal(ds.n, 1);
    assert_int_equal(ds.m, IT2N_MAX_DEGREE);
    assert_int_equal(it2n_dataset_missing(&ds), 2u * (IT2N_MAX_DEGREE + 1u));
    assert_int_equal(it2n_dataset_init(&ds, 2, 3, 0, &err), IT2N_OK);
    assert_int_equal(it2n_dataset_missing(&ds), 3u * 4u * 7u);
}

/* One put that must fail; checks code, detail and that ds is unchanged. */
static void put_fails(it2n_dataset *ds, unsigned i, unsigned j, unsigned fp,
                      const it2n_val v[IT2N_CH_COUNT], bool replace, int code,
                      int ch)
{
    static it2n_dataset copy;
    it2n_errinfo err;
    copy = *ds;
    memset(&err, 0x5A, sizeof err);
    int rc = it2n_dataset_put(ds, i, j, fp, v, replace, &err);
    if (rc != code)
        fail_msg("put(%u,%u,%u) -> %d, expected %d", i, j, fp, rc, code);
    assert_int_equal(err.code, code);
    assert_memory_equal(ds, &copy, sizeof *ds);
    if (code == IT2N_ERR_RANGE) {
        assert_int_equal(err.i, (int)i);
        assert_int_equal(err.j, (int)j);
        assert_int_equal(err.fp, (int)fp);
        assert_int_equal(err.ch, ch);
        assert_true(err.value == v[ch]);
        if (ch >= IT2N_CH_T) {
            assert_true(err.lo == 0);
            assert_true(err.hi == ONE);
        } else {
            assert_true(err.lo == -LIM);
            assert_true(err.hi == LIM);
        }
    }
}

static void test_put_membership_range(void **state)
{
    (void)state;
    static it2n_dataset ds;
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    assert_int_equal(it2n_dataset_init(&ds, 3, 2, 0, &err), IT2N_OK);
    for (unsigned ch = IT2N_CH_T; ch <= IT2N_CH_F; ch++) {
        vals_ok(v);
        v[ch] = ONE + 1; /* 1 + 2^-24 */
        put_fails(&ds, 2, 1, IT2N_FP_RL, v, false, IT2N_ERR_RANGE, (int)ch);
        v[ch] = tc_q24("1.2");
        put_fails(&ds, 3, 0, IT2N_FP_LL, v, true, IT2N_ERR_RANGE, (int)ch);
        v[ch] = -1;
        put_fails(&ds, 0, 2, IT2N_FP_D, v, false, IT2N_ERR_RANGE, (int)ch);
        v[ch] = tc_q24("-0.5");
        put_fails(&ds, 1, 1, IT2N_FP_RR, v, false, IT2N_ERR_RANGE, (int)ch);
        /* the bounds themselves are fine */
        v[ch] = 0;
        assert_int_equal(it2n_dataset_put(&ds, 1, 1, IT2N_FP_L, v, true, &err),
                         IT2N_OK);
        v[ch] = ONE;
        assert_int_equal(it2n_dataset_put(&ds, 1, 1, IT2N_FP_L, v, true, &err),
                         IT2N_OK);
    }
    /* the first bad channel in order x..F is reported */
    vals_ok(v);
    v[IT2N_CH_I] = 2 * ONE;
    v[IT2N_CH_F] = -ONE;
    put_fails(&ds, 0, 0, IT2N_FP_D, v, false, IT2N_ERR_RANGE, IT2N_CH_I);
}

static void test_put_coordinate_limit(void **state)
{
    (void)state;
    static it2n_dataset ds;
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    assert_int_equal(it2n_dataset_init(&ds, 2, 2, IT2N_F_Z, &err), IT2N_OK);
    for (unsigned ch = IT2N_CH_X; ch <= IT2N_CH_Z; ch++) {
        vals_ok(v);
        v[ch] = LIM + 1;
        put_fails(&ds, 1, 2, IT2N_FP_LR, v, false, IT2N_ERR_RANGE, (int)ch);
        v[ch] = -LIM - 1;
        put_fails(&ds, 2, 0, IT2N_FP_R, v, false, IT2N_ERR_RANGE, (int)ch);
        v[ch] = INT64_MAX;
        put_fails(&ds, 0, 0, IT2N_FP_D, v, false, IT2N_ERR_RANGE, (int)ch);
        v[ch] = INT64_MIN;
        put_fails(&ds, 0, 0, IT2N_FP_D, v, false, IT2N_ERR_RANGE, (int)ch);
        v[ch] = LIM;
        assert_int_equal(it2n_dataset_put(&ds, 0, 0, IT2N_FP_D, v, true, &err),
                         IT2N_OK);
        v[ch] = -LIM;
        assert_int_equal(it2n_dataset_put(&ds, 0, 0, IT2N_FP_D, v, true, &err),
                         IT2N_OK);
    }
    /* Without IT2N_F_Z the z value is ignored (and stored as zero). */
    assert_int_equal(it2n_dataset_init(&ds, 2, 2, 0, &err), IT2N_OK);
    vals_ok(v);
    v[IT2N_CH_Z] = INT64_MAX;
    assert_int_equal(it2n_dataset_put(&ds, 1, 1, IT2N_FP_D, v, false, &err),
                     IT2N_OK);
    assert_true(it2n_dataset_value(&ds, 1, 1, IT2N_FP_D, IT2N_CH_Z) == 0);
    assert_true(it2n_dataset_value(&ds, 1, 1, IT2N_FP_D, IT2N_CH_X) == v[IT2N_CH_X]);
}

static void test_put_index_and_duplicate(void **state)
{
    (void)state;
    static it2n_dataset ds;
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT], v2[IT2N_CH_COUNT];
    vals_ok(v);
    vals_ok(v2);
    v2[IT2N_CH_T] = ONE / 8;
    assert_int_equal(it2n_dataset_init(&ds, 3, 2, 0, &err), IT2N_OK);
    put_fails(&ds, 4, 0, IT2N_FP_D, v, false, IT2N_ERR_INVAL, -1);
    put_fails(&ds, 0, 3, IT2N_FP_D, v, false, IT2N_ERR_INVAL, -1);
    put_fails(&ds, 0, 0, IT2N_FP_COUNT, v, false, IT2N_ERR_INVAL, -1);
    put_fails(&ds, 0, 0, 1000u, v, false, IT2N_ERR_INVAL, -1);
    assert_int_equal(it2n_dataset_put(&ds, 2, 1, IT2N_FP_R, v, false, &err), IT2N_OK);
    assert_int_equal(ds.present[2][1], 1u << IT2N_FP_R);
    put_fails(&ds, 2, 1, IT2N_FP_R, v2, false, IT2N_ERR_DUPLICATE, -1);
    memset(&err, 0, sizeof err);
    assert_int_equal(it2n_dataset_put(&ds, 2, 1, IT2N_FP_R, v2, false, &err),
                     IT2N_ERR_DUPLICATE);
    expect_err(&err, IT2N_ERR_DUPLICATE, 2, 1, IT2N_FP_R, -1);
    assert_true(it2n_dataset_value(&ds, 2, 1, IT2N_FP_R, IT2N_CH_T) == v[IT2N_CH_T]);
    /* replace = true overwrites */
    assert_int_equal(it2n_dataset_put(&ds, 2, 1, IT2N_FP_R, v2, true, &err), IT2N_OK);
    assert_true(it2n_dataset_value(&ds, 2, 1, IT2N_FP_R, IT2N_CH_T) == v2[IT2N_CH_T]);
    assert_int_equal(it2n_dataset_missing(&ds), 4u * 3u * 7u - 1u);
}

static void test_type1_wrong_footprint(void **state)
{
    (void)state;
    static it2n_dataset ds;
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    vals_ok(v);
    assert_int_equal(it2n_dataset_init(&ds, 2, 2, IT2N_F_TYPE1, &err), IT2N_OK);
    assert_int_equal(it2n_dataset_missing(&ds), 9u);
    for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (fp == IT2N_FP_D)
            continue;
        put_fails(&ds, 1, 1, fp, v, false, IT2N_ERR_INVAL, -1);
        memset(&err, 0, sizeof err);
        assert_int_equal(it2n_dataset_put(&ds, 1, 1, fp, v, false, &err),
                         IT2N_ERR_INVAL);
        expect_err(&err, IT2N_ERR_INVAL, 1, 1, (int)fp, -1);
    }
    assert_int_equal(it2n_dataset_put(&ds, 1, 1, IT2N_FP_D, v, false, &err), IT2N_OK);
    assert_int_equal(it2n_dataset_missing(&ds), 8u);
}

static void test_missing(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_dataset ds;
    static it2n_model mdl, copy;
    it2n_errinfo err;
    tc_smooth(&c, 3, 2, 0, 10.0L, 1);
    it2n_model_init(&mdl);
    /* Leave out (2,1,RL) and (3,2,LL): the first in row-major order wins. */
    assert_int_equal(it2n_dataset_init(&ds, 3, 2, 0, &err), IT2N_OK);
    for (unsigned i = 0; i <= 3; i++)
        for (unsigned j = 0; j <= 2; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if ((i == 2 && j == 1 && fp == IT2N_FP_RL) ||
                    (i == 3 && j == 2 && fp == IT2N_FP_LL))
                    continue;
                assert_int_equal(it2n_dataset_put_fine(&ds, i, j, fp, c.q[i][j][fp],
                                                       false, &err), IT2N_OK);
            }
    assert_int_equal(it2n_dataset_missing(&ds), 2u);
    memset(&err, 0, sizeof err);
    assert_int_equal(it2n_dataset_check(&ds, &err), IT2N_ERR_MISSING);
    expect_err(&err, IT2N_ERR_MISSING, 2, 1, IT2N_FP_RL, -1);
    copy = mdl;
    memset(&err, 0, sizeof err);
    assert_int_equal(it2n_model_solve(&mdl, &ds, &err), IT2N_ERR_MISSING);
    expect_err(&err, IT2N_ERR_MISSING, 2, 1, IT2N_FP_RL, -1);
    assert_memory_equal(&mdl, &copy, sizeof mdl);
    /* empty data set: (0,0,LL) is first */
    assert_int_equal(it2n_dataset_init(&ds, 1, 1, 0, &err), IT2N_OK);
    assert_int_equal(it2n_dataset_check(&ds, &err), IT2N_ERR_MISSING);
    expect_err(&err, IT2N_ERR_MISSING, 0, 0, IT2N_FP_LL, -1);
}

/*
 * Nesting LL <= LR <= L <= D <= R <= RL <= RR on x, y, z: make footprint k
 * one LSB smaller than k-1 at (i, j) and expect IT2N_ERR_ORDER there. Which
 * of the two footprints is named is the core's choice; value/lo/hi must be
 * consistent with it.
 */
static void test_order(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_dataset ds;
    static it2n_model mdl, copy;
    it2n_errinfo err;
    static const unsigned where[][3] = {
        {0, 0, IT2N_FP_LR}, {2, 3, IT2N_FP_L}, {3, 4, IT2N_FP_RR}, {1, 2, IT2N_FP_D},
        {3, 0, IT2N_FP_R}, {0, 4, IT2N_FP_RL}};
    for (unsigned ch = IT2N_CH_X; ch <= IT2N_CH_Z; ch++)
        for (unsigned k = 0; k < sizeof where / sizeof where[0]; k++) {
            unsigned flags = ch == IT2N_CH_Z ? IT2N_F_Z : (k & 1u ? IT2N_F_Z : 0u);
            tc_smooth(&c, 3, 4, flags, 10.0L, 3);
            it2n_val lower = c.q[where[k][0]][where[k][1]][where[k][2] - 1][ch];
            c.q[where[k][0]][where[k][1]][where[k][2]][ch] = lower - 1;
            tc_dataset(&c, &ds);
            memset(&err, 0, sizeof err);
            int rc = it2n_dataset_check(&ds, &err);
            if (rc != IT2N_ERR_ORDER)
                fail_msg("order on %s at (%u,%u) fp %u: check -> %d",
                         it2n_ch_name(ch), where[k][0], where[k][1], where[k][2], rc);
            assert_int_equal(err.code, IT2N_ERR_ORDER);
            assert_int_equal(err.i, (int)where[k][0]);
            assert_int_equal(err.j, (int)where[k][1]);
            assert_int_equal(err.ch, (int)ch);
            if (err.fp == (int)where[k][2]) {
                assert_true(err.value == lower - 1);
                assert_true(err.lo == lower);
            } else {
                assert_int_equal(err.fp, (int)where[k][2] - 1);
                assert_true(err.value == lower);
                assert_true(err.hi == lower - 1);
            }
            /* solve on top of a solved model: rejected, model byte-identical */
            static tc_case good;
            tc_smooth(&good, 2, 2, 0, 10.0L, 9);
            tc_model(&good, &mdl);
            copy = mdl;
            memset(&err, 0, sizeof err);
            assert_int_equal(it2n_model_solve(&mdl, &ds, &err), IT2N_ERR_ORDER);
            assert_int_equal(err.code, IT2N_ERR_ORDER);
            assert_memory_equal(&mdl, &copy, sizeof mdl);
        }
    /* Equal neighbours are nested (<=). */
    tc_smooth(&c, 2, 2, IT2N_F_Z, 10.0L, 4);
    for (unsigned ch = IT2N_CH_X; ch <= IT2N_CH_Z; ch++)
        c.q[1][1][IT2N_FP_RL][ch] = c.q[1][1][IT2N_FP_R][ch];
    tc_dataset(&c, &ds);
    assert_int_equal(it2n_dataset_check(&ds, &err), IT2N_OK);
}

/* it2n_model_update: every kind of rejection leaves the model unchanged. */
static void test_update_atomic(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl, copy;
    static it2n_dataset ds, dscopy;
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    int rc;

    /* unsolved model */
    it2n_model_init(&mdl);
    copy = mdl;
    vals_ok(v);
    assert_int_equal(it2n_model_update(&mdl, &ds, 0, 0, IT2N_FP_D, v, &err),
                     IT2N_ERR_STATE);
    assert_int_equal(err.code, IT2N_ERR_STATE);
    assert_memory_equal(&mdl, &copy, sizeof mdl);
        assert_memory_equal(&ds, &dscopy, sizeof ds);

    for (unsigned variant = 0; variant < 3; variant++) {
        unsigned flags = variant == 0 ? 0u : variant == 1 ? IT2N_F_CHORD | IT2N_F_Z
                                                          : IT2N_F_TYPE1;
        tc_smooth(&c, 4, 3, flags, 10.0L, 7);
        tc_model_ds(&c, &mdl, &ds);
        copy = mdl;
        dscopy = ds;
        unsigned fp = (flags & IT2N_F_TYPE1) ? IT2N_FP_D : IT2N_FP_L;

        /* membership out of range */
        tc_q24_vals(c.q[2][1][fp], v);
        v[IT2N_CH_F] = ONE + 1;
        memset(&err, 0, sizeof err);
        rc = it2n_model_update(&mdl, &ds, 2, 1, fp, v, &err);
        assert_int_equal(rc, IT2N_ERR_RANGE);
        expect_err(&err, IT2N_ERR_RANGE, 2, 1, (int)fp, IT2N_CH_F);
        assert_memory_equal(&mdl, &copy, sizeof mdl);
        assert_memory_equal(&ds, &dscopy, sizeof ds);

        /* the same in the fine layout: one Q30 step above 1, shown in Q24
         * above 1 as well */
        memcpy(v, c.q[2][1][fp], sizeof v);
        v[IT2N_CH_F] = IT2N_MEMB_ONE + 1;
        memset(&err, 0, sizeof err);
        rc = it2n_model_update_fine(&mdl, &ds, 2, 1, fp, v, &err);
        assert_int_equal(rc, IT2N_ERR_RANGE);
        expect_err(&err, IT2N_ERR_RANGE, 2, 1, (int)fp, IT2N_CH_F);
        assert_true(err.value == ONE + 1 && err.hi == ONE);
        v[IT2N_CH_F] = -1;
        rc = it2n_model_update_fine(&mdl, &ds, 2, 1, fp, v, &err);
        assert_int_equal(rc, IT2N_ERR_RANGE);
        assert_true(err.value == -1 && err.lo == 0);
        assert_memory_equal(&mdl, &copy, sizeof mdl);
        assert_memory_equal(&ds, &dscopy, sizeof ds);

        /* coordinate beyond the limit */
        tc_q24_vals(c.q[2][1][fp], v);
        v[IT2N_CH_Y] = -LIM - 1;
        rc = it2n_model_update(&mdl, &ds, 2, 1, fp, v, &err);
        assert_int_equal(rc, IT2N_ERR_RANGE);
        expect_err(&err, IT2N_ERR_RANGE, 2, 1, (int)fp, IT2N_CH_Y);
        assert_memory_equal(&mdl, &copy, sizeof mdl);
        assert_memory_equal(&ds, &dscopy, sizeof ds);

        /* bad index / footprint */
        tc_q24_vals(c.q[2][1][fp], v);
        assert_int_equal(it2n_model_update(&mdl, &ds, 5, 1, fp, v, &err), IT2N_ERR_INVAL);
        assert_int_equal(it2n_model_update(&mdl, &ds, 1, 4, fp, v, &err), IT2N_ERR_INVAL);
        assert_int_equal(it2n_model_update(&mdl, &ds, 1, 1, IT2N_FP_COUNT, v, &err),
                         IT2N_ERR_INVAL);
        if (flags & IT2N_F_TYPE1)
            assert_int_equal(it2n_model_update(&mdl, &ds, 1, 1, IT2N_FP_RR, v, &err),
                             IT2N_ERR_INVAL);
        assert_memory_equal(&mdl, &copy, sizeof mdl);
        assert_memory_equal(&ds, &dscopy, sizeof ds);

        /* nesting broken by the new value */
        if (!(flags & IT2N_F_TYPE1)) {
            tc_q24_vals(c.q[2][1][fp], v);
            v[IT2N_CH_X] = c.q[2][1][IT2N_FP_D][IT2N_CH_X] + 1; /* L > D */
            memset(&err, 0, sizeof err);
            rc = it2n_model_update(&mdl, &ds, 2, 1, fp, v, &err);
            assert_int_equal(rc, IT2N_ERR_ORDER);
            assert_int_equal(err.code, IT2N_ERR_ORDER);
            assert_int_equal(err.i, 2);
            assert_int_equal(err.j, 1);
            assert_int_equal(err.ch, IT2N_CH_X);
            assert_memory_equal(&mdl, &copy, sizeof mdl);
        assert_memory_equal(&ds, &dscopy, sizeof ds);
        }
        /* a good update does change it (the copy is meaningful) */
        tc_q24_vals(c.q[2][1][fp], v);
        v[IT2N_CH_T] = ONE / 3;
        assert_int_equal(it2n_model_update(&mdl, &ds, 2, 1, fp, v, &err), IT2N_OK);
        assert_memory_not_equal(&mdl, &copy, sizeof mdl);
    }
}

/* A degenerate chord-length parameterisation fails the solve atomically. */
static void test_solve_degenerate_atomic(void **state)
{
    (void)state;
    static tc_case c, good;
    static it2n_dataset ds;
    static it2n_model mdl, copy;
    it2n_errinfo err;
    /* x, y depend on j only: every row along u collapses to one point. */
    tc_init(&c, 3, 3, IT2N_F_CHORD);
    for (unsigned i = 0; i <= 3; i++)
        for (unsigned j = 0; j <= 3; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                tc_set(&c, i, j, fp, IT2N_CH_X, (long double)j + 0.1L * fp);
                tc_set(&c, i, j, fp, IT2N_CH_Y, 2.0L * j + 0.1L * fp);
                tc_set(&c, i, j, fp, IT2N_CH_T, 0.1L * (i + j));
                tc_set(&c, i, j, fp, IT2N_CH_I, 0.5L);
                tc_set(&c, i, j, fp, IT2N_CH_F, 0.2L);
            }
    tc_dataset(&c, &ds);
    assert_int_equal(it2n_dataset_check(&ds, &err), IT2N_OK);
    tc_smooth(&good, 3, 3, IT2N_F_CHORD, 10.0L, 2);
    tc_model(&good, &mdl);
    copy = mdl;
    assert_int_equal(it2n_model_solve(&mdl, &ds, &err), IT2N_ERR_DEGENERATE);
    assert_int_equal(err.code, IT2N_ERR_DEGENERATE);
    assert_memory_equal(&mdl, &copy, sizeof mdl);
    /* the same data with uniform parameters is fine */
    ds.flags = 0;
    assert_int_equal(it2n_model_solve(&mdl, &ds, &err), IT2N_OK);
}

/* A chord-length update that would collapse every line along u is rejected
 * (the update re-solves) and leaves the model byte-identical. */
static void test_update_chord_degenerate_atomic(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_model mdl, copy;
    static it2n_dataset ds, dscopy;
    it2n_errinfo err;
    tc_init(&c, 1, 1, IT2N_F_CHORD);
    for (unsigned i = 0; i <= 1; i++)
        for (unsigned j = 0; j <= 1; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                long double bump = (i == 1 && j == 0 && fp == IT2N_FP_D) ? 0.05L : 0.0L;
                tc_set(&c, i, j, fp, IT2N_CH_X, 5.0L * j + 0.1L * fp);
                tc_set(&c, i, j, fp, IT2N_CH_Y, 0.1L * fp + bump);
                tc_set(&c, i, j, fp, IT2N_CH_T, 0.25L * (i + j));
                tc_set(&c, i, j, fp, IT2N_CH_I, 0.5L);
                tc_set(&c, i, j, fp, IT2N_CH_F, 0.5L);
            }
    tc_model_ds(&c, &mdl, &ds);
    copy = mdl;
    dscopy = ds;
    it2n_val v[IT2N_CH_COUNT];
    tc_q24_vals(c.q[1][0][IT2N_FP_D], v);
    v[IT2N_CH_Y] = c.q[0][0][IT2N_FP_D][IT2N_CH_Y]; /* D(1,0) onto D(0,0) */
    memset(&err, 0, sizeof err);
    assert_int_equal(it2n_model_update(&mdl, &ds, 1, 0, IT2N_FP_D, v, &err),
                     IT2N_ERR_DEGENERATE);
    assert_int_equal(err.code, IT2N_ERR_DEGENERATE);
    assert_memory_equal(&mdl, &copy, sizeof mdl);
    assert_memory_equal(&ds, &dscopy, sizeof ds);
    /* evaluation still works on the old model */
    it2n_point pt;
    assert_int_equal(it2n_eval(&mdl, IT2N_PAR_ONE, 0, &pt, NULL), IT2N_OK);
    assert_true(pt.v[IT2N_FP_D][IT2N_CH_Y] == c.q[1][0][IT2N_FP_D][IT2N_CH_Y]);
}

/*
 * A data set filled by hand (the struct is public): it2n_dataset_check and
 * it2n_model_solve re-check what it2n_dataset_put would have refused, with
 * the same detail, and a bad struct never reaches the solver.
 */
static void test_hand_filled_dataset(void **state)
{
    (void)state;
    static tc_case c;
    static it2n_dataset ds, bad;
    static it2n_model mdl, copy;
    it2n_errinfo err;
    tc_smooth(&c, 2, 3, 0, 10.0L, 8);
    tc_dataset(&c, &ds);
    tc_model(&c, &mdl);
    copy = mdl;

    /* memberships are stored in Q30; errors report Q24 */
    bad = ds;
    bad.memb[1][2][IT2N_FP_RL][IT2N_CH_T - 3] = (uint32_t)tc_q24("1.2") << 6;
    memset(&err, 0, sizeof err);
    assert_int_equal(it2n_dataset_check(&bad, &err), IT2N_ERR_RANGE);
    expect_err(&err, IT2N_ERR_RANGE, 1, 2, IT2N_FP_RL, IT2N_CH_T);
    assert_true(err.value == tc_q24("1.2") && err.lo == 0 && err.hi == ONE);
    assert_int_equal(it2n_model_solve(&mdl, &bad, &err), IT2N_ERR_RANGE);
    assert_memory_equal(&mdl, &copy, sizeof mdl);

    /* one Q30 step above 1 is refused and shown above 1 in Q24 too */
    bad = ds;
    bad.memb[2][0][IT2N_FP_D][IT2N_CH_F - 3] = (uint32_t)IT2N_MEMB_ONE + 1u;
    assert_int_equal(it2n_dataset_check(&bad, &err), IT2N_ERR_RANGE);
    expect_err(&err, IT2N_ERR_RANGE, 2, 0, IT2N_FP_D, IT2N_CH_F);
    assert_true(err.value == ONE + 1 && err.lo == 0 && err.hi == ONE);
    assert_int_equal(it2n_model_solve(&mdl, &bad, &err), IT2N_ERR_RANGE);
    assert_memory_equal(&mdl, &copy, sizeof mdl);

    bad = ds;
    bad.coord_hi[0][3][IT2N_FP_LL][IT2N_CH_X] = INT16_MIN; /* -2^47 */
    bad.coord_lo[0][3][IT2N_FP_LL][IT2N_CH_X] = 0;
    assert_int_equal(it2n_dataset_check(&bad, &err), IT2N_ERR_RANGE);
    expect_err(&err, IT2N_ERR_RANGE, 0, 3, IT2N_FP_LL, IT2N_CH_X);
    assert_int_equal(it2n_model_solve(&mdl, &bad, &err), IT2N_ERR_RANGE);
    assert_memory_equal(&mdl, &copy, sizeof mdl);

    static const uint8_t degs[][2] = {{0, 2}, {2, 0}, {IT2N_MAX_DEGREE + 1, 1}};
    for (unsigned k = 0; k < 3; k++) {
        bad = ds;
        bad.n = degs[k][0];
        bad.m = degs[k][1];
        assert_int_equal(it2n_dataset_check(&bad, &err), IT2N_ERR_INVAL);
        assert_int_equal(it2n_model_solve(&mdl, &bad, &err), IT2N_ERR_INVAL);
        assert_memory_equal(&mdl, &copy, sizeof mdl);
    }
    bad = ds;
    bad.flags = 0x40u;
    assert_int_equal(it2n_model_solve(&mdl, &bad, &err), IT2N_ERR_INVAL);
    assert_memory_equal(&mdl, &copy, sizeof mdl);

    /* z of a model without IT2N_F_Z is documented as zero; garbage there must
     * be refused or ignored, never turned into a z surface or an overflow. */
    static const int16_t junk_hi[] = {INT16_MIN, INT16_MAX, 0};
    static const uint32_t junk_lo[] = {0u, UINT32_MAX, 5u << 24};
    for (unsigned k = 0; k < 3; k++) {
        bad = ds;
        bad.coord_hi[2][1][IT2N_FP_D][IT2N_CH_Z] = junk_hi[k];
        bad.coord_lo[2][1][IT2N_FP_D][IT2N_CH_Z] = junk_lo[k];
        it2n_val junk_k = it2n_dataset_value(&bad, 2, 1, IT2N_FP_D, IT2N_CH_Z);
        int rc = it2n_model_solve(&mdl, &bad, &err);
        if (rc < 0) {
            assert_memory_equal(&mdl, &copy, sizeof mdl);
            continue;
        }
        if (rc != IT2N_OK)
            fail_msg("solve with junk z -> %d", rc);
        it2n_point pt;
        assert_int_equal(it2n_eval(&mdl, IT2N_PAR_ONE, IT2N_PAR_ONE / 3, &pt, NULL), IT2N_OK);
        for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
            if (pt.v[fp][IT2N_CH_Z] != 0)
                fail_msg("unused z %lld in the data gave a z surface (%s z = %lld)",
                         (long long)junk_k, it2n_fp_name(fp),
                         (long long)pt.v[fp][IT2N_CH_Z]);
        tc_model(&c, &mdl);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_dataset_init_bad_degree),
        cmocka_unit_test(test_put_membership_range),
        cmocka_unit_test(test_put_coordinate_limit),
        cmocka_unit_test(test_put_index_and_duplicate),
        cmocka_unit_test(test_type1_wrong_footprint),
        cmocka_unit_test(test_missing),
        cmocka_unit_test(test_order),
        cmocka_unit_test(test_update_atomic),
        cmocka_unit_test(test_solve_degenerate_atomic),
        cmocka_unit_test(test_update_chord_degenerate_atomic),
        cmocka_unit_test(test_hand_filled_dataset),
    };
    return cmocka_run_group_tests_name("core validation", tests, NULL, NULL);
}
