/* test_regmap — the register map library (regmap/): every word order
 * against golden bytes, float32, scaled integers and parameters against a
 * 128-bit reference, and the table's own invariants (blocks ordered and
 * apart, every field inside its block, lookups at the edges). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "it2n_regmap.h"

/* 128-bit reference of the rounding rules (test only: the library keeps
 * to 64 bits). */
__extension__ typedef __int128 i128;

static int64_t ref_to_scaled(int64_t v, int64_t scale, int64_t lo, int64_t hi, int *sat)
{
    i128 s = (i128)v * scale, half = (i128)1 << 23;
    i128 q = (s >= 0 ? s + half : s - half) >> 24;
    if (s < 0)
        q = -((-s + half) >> 24);
    if (q > hi) {
        *sat = 1;
        return hi;
    }
    if (q < lo) {
        *sat = 1;
        return lo;
    }
    return (int64_t)q;
}

static int64_t ref_from_scaled(int64_t raw, int64_t scale)
{
    i128 s = (i128)raw * ((i128)1 << 24);
    return (int64_t)((s >= 0 ? s + scale / 2 : s - scale / 2) / scale);
}

/* 0x11223344: A = 0x11 ... D = 0x44, every byte distinct. */
static void test_u32_golden(void **st)
{
    static const uint16_t want[4][2] = {
        { 0x1122, 0x3344 }, /* ABCD */
        { 0x3344, 0x1122 }, /* CDAB */
        { 0x2211, 0x4433 }, /* BADC */
        { 0x4433, 0x2211 }, /* DCBA */
    };
    (void)st;
    for (unsigned o = 0; o < 4; o++) {
        uint16_t r[2];
        it2n_regmap_put_u32(r, 0x11223344u, o);
        assert_int_equal(r[0], want[o][0]);
        assert_int_equal(r[1], want[o][1]);
        assert_int_equal(it2n_regmap_get_u32(want[o], o), 0x11223344u);
    }
    /* An unknown order is ABCD, both ways. */
    {
        uint16_t r[2];
        it2n_regmap_put_u32(r, 0x11223344u, 7u);
        assert_int_equal(r[0], 0x1122);
        assert_int_equal(it2n_regmap_get_u32(want[0], 9u), 0x11223344u);
    }
}

/* -123.456f = 0xC2F6E979. */
static void test_f32_golden(void **st)
{
    static const uint16_t want[4][2] = {
        { 0xC2F6, 0xE979 }, { 0xE979, 0xC2F6 }, { 0xF6C2, 0x79E9 }, { 0x79E9, 0xF6C2 },
    };
    (void)st;
    for (unsigned o = 0; o < 4; o++) {
        uint16_t r[2];
        it2n_regmap_put_f32(r, -123.456f, o);
        assert_int_equal(r[0], want[o][0]);
        assert_int_equal(r[1], want[o][1]);
        assert_true(it2n_regmap_get_f32(want[o], o) == -123.456f);
    }
}

/* The bulk encoder writes what the single one does, in every order. */
static void test_q24_f32s(void **st)
{
    static const int64_t v[5] = { 0, 1 << 24, -(1 << 23), 123456789, -((int64_t)23 << 24) };
    (void)st;
    assert_true(it2n_regmap_q24_to_f32((int64_t)3 << 23) == 1.5f);
    assert_true(it2n_regmap_q24_to_f32(-((int64_t)23 << 24)) == -23.0f);
    for (unsigned o = 0; o < 4; o++) {
        uint16_t bulk[10], one[2];
        it2n_regmap_put_q24_f32s(bulk, v, 5, o);
        for (unsigned k = 0; k < 5; k++) {
            it2n_regmap_put_f32(one, it2n_regmap_q24_to_f32(v[k]), o);
            assert_memory_equal(&bulk[2 * k], one, sizeof one);
        }
    }
}

/* The bulk encoder's fast paths (AVX2 or SSE2 on x86-64, regmap-unit runs both: four or two values per step,
 * exact below 2^51 in magnitude, else all values the scalar way) writes
 * what the single encoder does: rounding ties and the values next to
 * 2^51, at every length and position, in every order. */
static void test_q24_f32s_edges(void **st)
{
    static int64_t v[64];
    const int64_t b51 = (int64_t)1 << 51;
    const int64_t edge[] = { b51 - 1, -b51, b51, -b51 - 1, INT64_MAX, INT64_MIN, ((int64_t)1 << 25) + 1,
                             ((int64_t)1 << 25) + 3, -(((int64_t)1 << 26) + 2), ((int64_t)1 << 53) + 1, 1, -1 };
    uint64_t x = 0x9E3779B97F4A7C15u;
    (void)st;
    for (unsigned k = 0; k < 64; k++) {
        x = x * 6364136223846793005u + 1442695040888963407u;
        /* magnitudes from 2^0 to 2^63: every exponent, both signs */
        v[k] = (int64_t)(x >> (k % 64u));
    }
    for (unsigned e = 0; e < sizeof edge / sizeof edge[0]; e++)
        for (unsigned pos = 0; pos < 9; pos++)
            for (unsigned n = pos + 1u; n <= 10u; n++) {
                int64_t w[10];
                for (unsigned k = 0; k < 10; k++)
                    w[k] = v[(e * 7u + k) % 64u] >> 13; /* below 2^51: the fast path */
                w[pos] = edge[e];
                for (unsigned o = 0; o < 4; o++) {
                    uint16_t bulk[20], one[2];
                    it2n_regmap_put_q24_f32s(bulk, w, n, o);
                    for (unsigned k = 0; k < n; k++) {
                        it2n_regmap_put_f32(one, it2n_regmap_q24_to_f32(w[k]), o);
                        assert_memory_equal(&bulk[2 * k], one, sizeof one);
                    }
                }
            }
    for (unsigned o = 0; o < 4; o++) {
        uint16_t bulk[128], one[2];
        it2n_regmap_put_q24_f32s(bulk, v, 64, o);
        for (unsigned k = 0; k < 64; k++) {
            it2n_regmap_put_f32(one, it2n_regmap_q24_to_f32(v[k]), o);
            assert_memory_equal(&bulk[2 * k], one, sizeof one);
        }
    }
}

static void test_scaled(void **st)
{
    const int64_t one = (int64_t)1 << 24;
    int sat = 0;
    (void)st;
    /* 0.5 -> 5000; 1/3 -> 3333; -0.00005000x -> -1 (half away from zero) */
    assert_int_equal(it2n_regmap_q24_to_scaled(one / 2, 10000, -32767, 32767, &sat), 5000);
    assert_int_equal(it2n_regmap_q24_to_scaled(one / 3, 10000, -32767, 32767, &sat), 3333);
    assert_int_equal(it2n_regmap_q24_to_scaled(-(one / 20000 + 1), 10000, -32767, 32767, &sat), -1);
    assert_int_equal(sat, 0);
    assert_int_equal(it2n_regmap_q24_to_scaled(4 * one, 10000, -32767, 32767, &sat), 32767);
    assert_int_equal(sat, 1);
    sat = 0;
    assert_int_equal(it2n_regmap_q24_to_scaled(-8000000 * one, 1000, INT32_MIN, INT32_MAX, &sat), INT32_MIN);
    assert_int_equal(sat, 1);
    /* far beyond 64-bit products: saturates, never wraps */
    sat = 0;
    assert_int_equal(it2n_regmap_q24_to_scaled(INT64_MAX, 10000, INT32_MIN, INT32_MAX, &sat), INT32_MAX);
    assert_int_equal(sat, 1);
    sat = 0;
    assert_int_equal(it2n_regmap_q24_to_scaled(INT64_MIN, 10000, INT32_MIN, INT32_MAX, &sat), INT32_MIN);
    assert_int_equal(sat, 1);
    /* back: -2300 / 100 = -23 exactly; 1 / 3 rounds half away from zero */
    assert_int_equal(it2n_regmap_q24_from_scaled(-2300, 100), -23 * one);
    assert_int_equal(it2n_regmap_q24_from_scaled(1, 3), (one + 1) / 3);
    assert_int_equal(it2n_regmap_q24_from_scaled(-1, 3), -((one + 1) / 3));
}

/* Against the 128-bit reference over values a model can hold (|v| < 2^47)
 * and every scale the daemon accepts. */
static void test_scaled_reference(void **st)
{
    static const int64_t scales[] = { 1, 2, 3, 7, 100, 1000, 9999, 10000, 65535 };
    uint64_t x = 0x9E3779B97F4A7C15u;
    (void)st;
    for (int n = 0; n < 200000; n++) {
        int64_t scale = scales[n % 9];
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        int64_t v = (int64_t)(x >> 16) - ((int64_t)1 << 47);
        if (n % 4 == 0)
            v = (v % 4096) * ((int64_t)1 << 12) + (int64_t)(x & 1u ? 1 << 11 : 0); /* near halves */
        int s1 = 0, s2 = 0;
        int64_t got = it2n_regmap_q24_to_scaled(v, (int32_t)scale, INT32_MIN, INT32_MAX, &s1);
        int64_t want = ref_to_scaled(v, scale, INT32_MIN, INT32_MAX, &s2);
        if (got != want || s1 != s2)
            fail_msg("to_scaled(%lld, %lld) = %lld sat %d, reference %lld sat %d", (long long)v, (long long)scale,
                     (long long)got, s1, (long long)want, s2);
        int64_t raw = (int64_t)(int32_t)(uint32_t)x;
        if (it2n_regmap_q24_from_scaled(raw, (int32_t)scale) != ref_from_scaled(raw, scale))
            fail_msg("from_scaled(%lld, %lld)", (long long)raw, (long long)scale);
    }
}

static void test_par(void **st)
{
    const int64_t one = (int64_t)1 << 32;
    (void)st;
    for (unsigned reg = 0; reg <= 10000; reg++) {
        int64_t p = it2n_regmap_par_from_u16(reg);
        assert_true(p == (int64_t)(((i128)reg * one + 5000) / 10000));
        assert_int_equal(it2n_regmap_par_to_u16(p), reg);
    }
    assert_int_equal(it2n_regmap_par_to_u16(one / 3), 3333);
    assert_int_equal(it2n_regmap_par_to_u16(-5), 0);
    assert_int_equal(it2n_regmap_par_to_u16(one + 1), 10000);
}

static void test_table(void **st)
{
    (void)st;
    assert_true(it2n_regmap_nblocks > 0);
    for (size_t b = 0; b < it2n_regmap_nblocks; b++) {
        const it2n_regmap_block *bl = &it2n_regmap_blocks[b];
        assert_true(bl->start < bl->end);
        assert_true(bl->end <= IT2N_REGMAP_REG_MAP_END);
        for (size_t c = 0; c < it2n_regmap_nblocks; c++)
            if (c != b) /* apart */
                assert_true(bl->end <= it2n_regmap_blocks[c].start || it2n_regmap_blocks[c].end <= bl->start);
        for (size_t k = 0; k < bl->nfields; k++) {
            const it2n_regmap_field *f = &bl->fields[k];
            unsigned words = it2n_regmap_type_words(f->type);
            unsigned last = f->addr + (f->count - 1u) * (f->count > 1u ? f->stride : 0u) + words;
            assert_true(f->addr >= bl->start);
            assert_true(last <= bl->end);
            assert_true(f->count == 1u || f->stride >= words);
            assert_string_not_equal(it2n_regmap_type_name(f->type), "?");
        }
        assert_ptr_equal(it2n_regmap_find(bl->start, bl->end - bl->start), bl);
        assert_ptr_equal(it2n_regmap_find(bl->end - 1u, 1), bl);
        assert_null(it2n_regmap_find(bl->start, bl->end - bl->start + 1u));
    }
    /* it2n_regmap_find searches the table by address: in address order,
     * and every address finds the block holding it (or none, in a gap). */
    for (size_t b = 1; b < it2n_regmap_nblocks; b++)
        assert_true(it2n_regmap_blocks[b - 1u].end <= it2n_regmap_blocks[b].start);
    for (unsigned a = 0; a <= IT2N_REGMAP_REG_MAP_END; a++) {
        const it2n_regmap_block *want = NULL;
        for (size_t b = 0; b < it2n_regmap_nblocks; b++)
            if (a >= it2n_regmap_blocks[b].start && a < it2n_regmap_blocks[b].end)
                want = &it2n_regmap_blocks[b];
        assert_ptr_equal(it2n_regmap_find(a, 1), want);
    }
    assert_null(it2n_regmap_find(IT2N_REGMAP_REG_MAP_VERSION, 0));
    assert_null(it2n_regmap_find(IT2N_REGMAP_REG_MAP_END, 1));
    assert_null(it2n_regmap_find(IT2N_REGMAP_REG_STATUS_END - 1u, 2)); /* spans status and configuration */
    assert_string_equal(it2n_regmap_type_name(99), "?");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_u32_golden),
        cmocka_unit_test(test_f32_golden),
        cmocka_unit_test(test_q24_f32s),
        cmocka_unit_test(test_q24_f32s_edges),
        cmocka_unit_test(test_scaled),
        cmocka_unit_test(test_scaled_reference),
        cmocka_unit_test(test_par),
        cmocka_unit_test(test_table),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
