/*
 * cmocka tests of the decimal text conversion (firmware_core/it2n_text.c):
 * exact rounding (ties away from zero), limits, bad input, round trips.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "it2n.h"

static int pv(const char *s, it2n_val *v)
{
    return it2n_parse_val(s, strlen(s), v);
}

static int pp(const char *s, it2n_par *p)
{
    return it2n_parse_par(s, strlen(s), p);
}

static void test_parse_val_exact(void **state)
{
    static const struct {
        const char *s;
        it2n_val raw;
    } cases[] = {
        {"0", 0},
        {"-0", 0},
        {"+1", IT2N_VAL_ONE},
        {"1", IT2N_VAL_ONE},
        {"-12.5", -(25 * IT2N_VAL_ONE) / 2},
        {"0.5", IT2N_VAL_ONE / 2},
        {".5", IT2N_VAL_ONE / 2},
        {"5.", 5 * IT2N_VAL_ONE},
        {"3e-2", 503316},        /* 0.03 * 2^24 = 503316.48 */
        {"3E-2", 503316},
        {"0.03", 503316},
        {"12e3", 12000 * IT2N_VAL_ONE},
        {"1.5e+2", 150 * IT2N_VAL_ONE},
        {"0.000001", 17},        /* 16.777216 */
        {"-0.000001", -17},
        {"0.4", 6710886},        /* 6710886.4 */
        {"0.7", 11744051},       /* 11744051.2 */
        {"0.9", 15099494},       /* 15099494.4 */
        {"0.1", 1677722},        /* 1677721.6 */
        /* Ties: exactly k + 1/2 LSB round away from zero. */
        {"0.0000000298023223876953125", 1},   /* 2^-25          */
        {"-0.0000000298023223876953125", -1},
        {"0.0000000894069671630859375", 2},   /* 1.5 * 2^-24    */
        /* Just below a tie rounds down, however many digits follow. */
        {"0.00000002980232238769531249999999999999999999999", 0},
        {"0.00000002980232238769531250000000000000000000001", 1},
        {"8388607", (it2n_val)8388607 * IT2N_VAL_ONE},
        {"-8388607", -(it2n_val)8388607 * IT2N_VAL_ONE},
        {"8388607.000", (it2n_val)8388607 * IT2N_VAL_ONE},
        {"1e-100", 0},
        {"0e999999", 0},
        {"000000000000000000000000000001", IT2N_VAL_ONE},
    };
    size_t k;
    (void)state;
    for (k = 0; k < sizeof(cases) / sizeof(cases[0]); k++) {
        it2n_val v = 12345;
        int rc = pv(cases[k].s, &v);
        if (rc != IT2N_OK || v != cases[k].raw) {
            print_error("case '%s': rc %d raw %lld, want %lld\n", cases[k].s,
                        rc, (long long)v, (long long)cases[k].raw);
        }
        assert_int_equal(rc, IT2N_OK);
        assert_true(v == cases[k].raw);
    }
}

static void test_parse_val_bad(void **state)
{
    static const char *const inval[] = {
        "", "-", "+", ".", "e5", "1e", "1e+", "1.2.3", "abc", " 1", "1 ",
        "+-1", "0x10", "inf", "nan", "1,5", "--1", "1e5.0", "\t", "1f"};
    static const char *const range[] = {
        "8388607.0000001", "8388608", "-8388608", "9e9", "1e12",
        "-8388607.5", "100000000000000000000000000"};
    size_t k;
    (void)state;
    for (k = 0; k < sizeof(inval) / sizeof(inval[0]); k++) {
        it2n_val v = 777;
        assert_int_equal(pv(inval[k], &v), IT2N_ERR_INVAL);
        assert_true(v == 777); /* untouched */
    }
    for (k = 0; k < sizeof(range) / sizeof(range[0]); k++) {
        it2n_val v = 777;
        assert_int_equal(pv(range[k], &v), IT2N_ERR_RANGE);
        assert_true(v == 777);
    }
    /* Length is honoured: "12" of "123". */
    {
        it2n_val v;
        assert_int_equal(it2n_parse_val("123", 2, &v), IT2N_OK);
        assert_true(v == 12 * IT2N_VAL_ONE);
        assert_int_equal(it2n_parse_val("1", 0, &v), IT2N_ERR_INVAL);
    }
}

/* Memberships in Q30: the same decimal rounding at 2^-30, the same
 * magnitudes and errors as it2n_parse_val (the [0, 1] check is the data
 * set's). */
static void test_parse_memb(void **state)
{
    static const struct {
        const char *s;
        it2n_val raw;
    } cases[] = {
        {"0", 0},
        {"1", IT2N_MEMB_ONE},
        {"0.5", IT2N_MEMB_ONE / 2},
        {"0.1", 107374182},              /* 107374182.4 */
        {"0.7", 751619277},              /* 751619276.8 */
        {"0.123456789", 132560718},      /* 132560717.81 */
        {"0.000000001", 1},              /* 1.07 */
        {"0.0000000004656612873077392578125", 1}, /* 2^-31: a tie, away */
        {"-0.0000000004656612873077392578125", -1},
        {"0.00000000046566128730773925781249", 0},
        {"1.2", 1288490189},             /* 1288490188.8 */
        {"-8388607", -(it2n_val)8388607 * IT2N_MEMB_ONE},
    };
    static const char *const range[] = {"8388608", "-8388607.0000001", "1e12"};
    size_t k;
    (void)state;
    for (k = 0; k < sizeof(cases) / sizeof(cases[0]); k++) {
        it2n_val v = 12345;
        int rc = it2n_parse_memb(cases[k].s, strlen(cases[k].s), &v);
        if (rc != IT2N_OK || v != cases[k].raw) {
            print_error("case '%s': rc %d raw %lld, want %lld\n", cases[k].s,
                        rc, (long long)v, (long long)cases[k].raw);
        }
        assert_int_equal(rc, IT2N_OK);
        assert_true(v == cases[k].raw);
    }
    for (k = 0; k < sizeof(range) / sizeof(range[0]); k++) {
        it2n_val v = 777;
        assert_int_equal(it2n_parse_memb(range[k], strlen(range[k]), &v),
                         IT2N_ERR_RANGE);
        assert_true(v == 777);
    }
    {
        it2n_val v = 777;
        assert_int_equal(it2n_parse_memb("0.5x", 4, &v), IT2N_ERR_INVAL);
        assert_int_equal(it2n_parse_memb("", 0, &v), IT2N_ERR_INVAL);
        assert_int_equal(it2n_parse_memb(NULL, 1, &v), IT2N_ERR_INVAL);
        assert_true(v == 777);
        assert_int_equal(it2n_parse_memb("0.5", 3, NULL), IT2N_ERR_INVAL);
    }
}

static void test_parse_par(void **state)
{
    it2n_par p = 0;
    (void)state;
    assert_int_equal(pp("0", &p), IT2N_OK);
    assert_true(p == 0);
    assert_int_equal(pp("1", &p), IT2N_OK);
    assert_true(p == IT2N_PAR_ONE);
    assert_int_equal(pp("1.000000000000", &p), IT2N_OK);
    assert_true(p == IT2N_PAR_ONE);
    assert_int_equal(pp("0.5", &p), IT2N_OK);
    assert_true(p == IT2N_PAR_ONE / 2);
    assert_int_equal(pp("-0", &p), IT2N_OK);
    assert_true(p == 0);
    /* round(0.333333 * 2^32) = round(1431654333.677568) */
    assert_int_equal(pp("0.333333", &p), IT2N_OK);
    assert_true(p == 1431654334);
    /* Tie at 2^-33 rounds up. */
    assert_int_equal(pp("0.000000000116415321826934814453125", &p), IT2N_OK);
    assert_true(p == 1);
    assert_int_equal(pp("0.000000000116415321826934814453124", &p), IT2N_OK);
    assert_true(p == 0);
    p = 99;
    assert_int_equal(pp("1.0000000001", &p), IT2N_ERR_RANGE);
    assert_int_equal(pp("-0.000001", &p), IT2N_ERR_RANGE);
    assert_int_equal(pp("2", &p), IT2N_ERR_RANGE);
    assert_int_equal(pp("x", &p), IT2N_ERR_INVAL);
    assert_true(p == 99);
}

static void fmt_val(it2n_val v, unsigned d, const char *want)
{
    char buf[64];
    int n = it2n_format_val(buf, sizeof(buf), v, d);
    if (n < 0 || strcmp(buf, want) != 0) {
        print_error("format %lld/%u: got '%s' want '%s'\n", (long long)v, d,
                    n < 0 ? "(error)" : buf, want);
    }
    assert_int_equal(n, (int)strlen(want));
    assert_string_equal(buf, want);
}

static void test_format(void **state)
{
    char buf[64];
    (void)state;
    fmt_val(0, 6, "0.000000");
    fmt_val(IT2N_VAL_ONE, 6, "1.000000");
    fmt_val(-IT2N_VAL_ONE / 2, 6, "-0.500000");
    fmt_val(IT2N_VAL_ONE, 0, "1");
    fmt_val(IT2N_VAL_ONE / 2, 0, "1");    /* tie away from zero */
    fmt_val(-IT2N_VAL_ONE / 2, 0, "-1");
    fmt_val(IT2N_VAL_ONE / 2 - 1, 0, "0");
    fmt_val(-1, 6, "0.000000");           /* no "-0.000000" */
    fmt_val(-1, 9, "-0.000000060");       /* 5.96e-8 */
    fmt_val(1, 9, "0.000000060");
    fmt_val(6710886, 6, "0.400000");      /* nearest Q24 to 0.4 */
    fmt_val(6710886, 9, "0.399999976");
    fmt_val(IT2N_VAL_ONE - 1, 6, "1.000000"); /* carry into integer */
    fmt_val((it2n_val)8388607 * IT2N_VAL_ONE, 6, "8388607.000000");
    fmt_val(INT64_MAX, 9, "549755813887.999999940");
    fmt_val(INT64_MIN, 6, "-549755813888.000000");
    /* Buffer exactly big enough, and one byte short (untouched). */
    assert_int_equal(it2n_format_val(buf, 9, IT2N_VAL_ONE, 6), 8);
    memset(buf, 'z', sizeof(buf));
    assert_int_equal(it2n_format_val(buf, 8, IT2N_VAL_ONE, 6), IT2N_ERR_RANGE);
    assert_int_equal(buf[0], 'z');
    assert_int_equal(it2n_format_val(buf, sizeof(buf), 0, 10), IT2N_ERR_INVAL);
    /* Parameters. */
    assert_int_equal(it2n_format_par(buf, sizeof(buf), IT2N_PAR_ONE, 6), 8);
    assert_string_equal(buf, "1.000000");
    assert_int_equal(it2n_format_par(buf, sizeof(buf), IT2N_PAR_ONE / 3, 9),
                     11);
    assert_string_equal(buf, "0.333333333");
    assert_int_equal(it2n_format_par(buf, sizeof(buf), 1, 9), 11);
    assert_string_equal(buf, "0.000000000"); /* 2.3e-10 */
}

/* Deterministic xorshift so the sweep is reproducible. */
static uint64_t rng(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return *s;
}

static void test_round_trip(void **state)
{
    uint64_t seed = 0x9E3779B97F4A7C15u;
    const it2n_val lim = (it2n_val)IT2N_COORD_LIMIT * IT2N_VAL_ONE;
    char buf[64];
    int k;
    (void)state;
    for (k = 0; k < 200000; k++) {
        uint64_t r = rng(&seed);
        it2n_val v, back;
        it2n_par p, pback;
        int n;
        /* Mix full-range values and small ones near 0 and 1. */
        v = (it2n_val)(r % (2u * (uint64_t)lim + 1u)) - lim;
        if (k & 1) {
            v = (it2n_val)(r % (uint64_t)(4 * IT2N_VAL_ONE)) - 2 * IT2N_VAL_ONE;
        }
        /* 9 decimals resolve Q24 (LSB 6e-8) exactly. */
        n = it2n_format_val(buf, sizeof(buf), v, 9);
        assert_true(n > 0);
        assert_int_equal(it2n_parse_val(buf, (size_t)n, &back), IT2N_OK);
        if (back != v) {
            print_error("round trip %lld -> %s -> %lld\n", (long long)v, buf,
                        (long long)back);
        }
        assert_true(back == v);
        /* 6 decimals: within half a unit of the 6th decimal + 1 LSB. */
        n = it2n_format_val(buf, sizeof(buf), v, 6);
        assert_int_equal(it2n_parse_val(buf, (size_t)n, &back), IT2N_OK);
        assert_true(back - v <= 9 && v - back <= 9); /* 0.5e-6 * 2^24 = 8.4 */
        /* Q32 parameters: 9 decimals are within 2.2 LSB. */
        p = (it2n_par)(r % ((uint64_t)IT2N_PAR_ONE + 1u));
        n = it2n_format_par(buf, sizeof(buf), p, 9);
        assert_int_equal(it2n_parse_par(buf, (size_t)n, &pback), IT2N_OK);
        assert_true(pback - p <= 3 && p - pback <= 3);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_parse_val_exact),
        cmocka_unit_test(test_parse_val_bad),
        cmocka_unit_test(test_parse_memb),
        cmocka_unit_test(test_parse_par),
        cmocka_unit_test(test_format),
        cmocka_unit_test(test_round_trip),
    };
    return cmocka_run_group_tests_name("cli_text", tests, NULL, NULL);
}
