/*
 * it2n_regmap_codec.c — how values travel in registers: the four 32-bit
 * word orders, float32, scaled integers and parameters x10000. The one
 * copy of each: the daemon encodes with it, it2nctl and the simulator
 * decode with it, and tests/regmap pins every byte against golden values.
 *
 * No 128-bit arithmetic: every product is split so it fits 64 bits, which
 * keeps the library C99 for any compiler.
 */
#include "it2n_regmap.h"

#include <string.h>

static uint16_t swap16(uint16_t v)
{
    return (uint16_t)((unsigned)(v >> 8) | (unsigned)(v << 8));
}

void it2n_regmap_put_u32(uint16_t out[2], uint32_t v, unsigned order)
{
    uint16_t hi = (uint16_t)(v >> 16), lo = (uint16_t)v;
    switch (order) {
    case IT2N_REGMAP_WO_CDAB:
        out[0] = lo;
        out[1] = hi;
        break;
    case IT2N_REGMAP_WO_BADC:
        out[0] = swap16(hi);
        out[1] = swap16(lo);
        break;
    case IT2N_REGMAP_WO_DCBA:
        out[0] = swap16(lo);
        out[1] = swap16(hi);
        break;
    default:
        out[0] = hi;
        out[1] = lo;
        break;
    }
}

uint32_t it2n_regmap_get_u32(const uint16_t in[2], unsigned order)
{
    uint16_t hi, lo;
    switch (order) {
    case IT2N_REGMAP_WO_CDAB:
        hi = in[1];
        lo = in[0];
        break;
    case IT2N_REGMAP_WO_BADC:
        hi = swap16(in[0]);
        lo = swap16(in[1]);
        break;
    case IT2N_REGMAP_WO_DCBA:
        hi = swap16(in[1]);
        lo = swap16(in[0]);
        break;
    default:
        hi = in[0];
        lo = in[1];
        break;
    }
    return ((uint32_t)hi << 16) | lo;
}

void it2n_regmap_put_f32(uint16_t out[2], float f, unsigned order)
{
    uint32_t b;
    memcpy(&b, &f, sizeof b);
    it2n_regmap_put_u32(out, b, order);
}

float it2n_regmap_get_f32(const uint16_t in[2], unsigned order)
{
    uint32_t b = it2n_regmap_get_u32(in, order);
    float f;
    memcpy(&f, &b, sizeof f);
    return f;
}

float it2n_regmap_q24_to_f32(int64_t v)
{
    /* v * 2^-24: exactly v / 2^24 (a power of two), without a division */
    return (float)((double)v * (1.0 / (double)((int64_t)1 << IT2N_REGMAP_Q24_FRAC)));
}

#if defined(__x86_64__) && defined(__SSE2__) && defined(__GNUC__) && __STDC_HOSTED__ && !defined(IT2N_NO_SIMD)
/*
 * x86-64 hosts (every FC 23 answer of it2nd carries 54 of these): four
 * values per step with SSE2. A Q24 value v below 2^51 in magnitude, added
 * to the bits of the double 1.5 2^28 (whose unit in the last place is
 * 2^-24), gives the double 1.5 2^28 + v 2^-24 exactly; subtracting
 * 1.5 2^28 leaves v 2^-24 exactly, and CVTPD2PS rounds it to float as the
 * scalar conversion does (MXCSR, nearest): the same bits as
 * it2n_regmap_q24_to_f32. Then the word order on the floats' 16-bit
 * halves. Returns the number of values done: all, or 0 when one of them
 * is 2^51 or more in magnitude (the caller's scalar loop does them all).
 */
#include <emmintrin.h>
#define IT2N_REGMAP_F32S_SSE2 1

/* Two values at p as two floats in the low half; *bad collects their high
 * 32 bits plus 2^19, shifted right by 20 (nonzero: 2^51 or more). */
static __m128i f32x2(const int64_t *p, __m128i *bad)
{
    const __m128i magic_i = _mm_set1_epi64x(0x41B8000000000000LL); /* 1.5 2^28 */
    const __m128d magic_d = _mm_set1_pd(402653184.0);
    __m128i x = _mm_loadu_si128((const __m128i *)(const void *)p);
    *bad = _mm_or_si128(*bad, _mm_srli_epi32(_mm_add_epi32(x, _mm_set1_epi32(1 << 19)), 20));
    return _mm_castps_si128(_mm_cvtpd_ps(_mm_sub_pd(_mm_castsi128_pd(_mm_add_epi64(x, magic_i)), magic_d)));
}

/* The word order of 4 floats (a constant where used: one loop per order). */
static __m128i f32_order(__m128i f, unsigned order)
{
    if (order == IT2N_REGMAP_WO_ABCD || order == IT2N_REGMAP_WO_BADC)
        f = _mm_shufflehi_epi16(_mm_shufflelo_epi16(f, 0xB1), 0xB1);
    if (order == IT2N_REGMAP_WO_BADC || order == IT2N_REGMAP_WO_DCBA)
        f = _mm_or_si128(_mm_slli_epi16(f, 8), _mm_srli_epi16(f, 8));
    return f;
}

#ifndef IT2N_NO_AVX2
/*
 * With AVX2 (checked at run time): the same sum and subtraction on four
 * values per instruction, one CVTPD2PS of four doubles (the same rounding,
 * MXCSR), and the word order (with the byte swaps of BADC and DCBA) one
 * byte shuffle: about 9 instructions per 4 values where SSE2 takes 23.
 * The same bits as put_q24_f32s_sse2 and the scalar conversion
 * (tests/regmap checks every order against it2n_regmap_put_f32).
 */
#include <immintrin.h>
#define IT2N_REGMAP_F32S_AVX2 1

__attribute__((target("avx2"))) static size_t put_q24_f32s_avx2(uint16_t *out, const int64_t *v, size_t n,
                                                                unsigned order)
{
    const __m256i magic_i = _mm256_set1_epi64x(0x41B8000000000000LL); /* 1.5 2^28 */
    const __m256d magic_d = _mm256_set1_pd(402653184.0);
    const __m256i r19 = _mm256_set1_epi32(1 << 19);
    /* bytes of each float (little-endian in the lane) into the order's
     * registers: ABCD high word first, CDAB as in memory, BADC / DCBA
     * those with each register's bytes swapped (registers are host-order
     * 16-bit values) */
    __m128i m;
    __m256i bad = _mm256_setzero_si256();
    __m128i bad2 = _mm_setzero_si128();
    size_t k = 0;
    switch (order) {
    case IT2N_REGMAP_WO_CDAB: m = _mm_setr_epi8(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15); break;
    case IT2N_REGMAP_WO_BADC: m = _mm_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12); break;
    case IT2N_REGMAP_WO_DCBA: m = _mm_setr_epi8(1, 0, 3, 2, 5, 4, 7, 6, 9, 8, 11, 10, 13, 12, 15, 14); break;
    default: m = _mm_setr_epi8(2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9, 14, 15, 12, 13); break;
    }
    for (; k + 4u <= n; k += 4u) {
        __m256i x = _mm256_loadu_si256((const __m256i *)(const void *)(v + k));
        __m128 f = _mm256_cvtpd_ps(_mm256_sub_pd(_mm256_castsi256_pd(_mm256_add_epi64(x, magic_i)), magic_d));
        bad = _mm256_or_si256(bad, _mm256_srli_epi32(_mm256_add_epi32(x, r19), 20));
        _mm_storeu_si128((__m128i *)(void *)(out + 2u * k), _mm_shuffle_epi8(_mm_castps_si128(f), m));
    }
    if (k + 2u <= n) { /* two more (54 results: 13 steps of four, then two) */
        __m128i x = _mm_loadu_si128((const __m128i *)(const void *)(v + k));
        __m128 f = _mm_cvtpd_ps(_mm_sub_pd(_mm_castsi128_pd(_mm_add_epi64(x, _mm256_castsi256_si128(magic_i))),
                                           _mm256_castpd256_pd128(magic_d)));
        bad2 = _mm_srli_epi32(_mm_add_epi32(x, _mm256_castsi256_si128(r19)), 20);
        _mm_storel_epi64((__m128i *)(void *)(out + 2u * k), _mm_shuffle_epi8(_mm_castps_si128(f), m));
        k += 2u;
    }
    /* the high halves' flags (odd 32-bit lanes) */
    if (!_mm256_testz_si256(bad, _mm256_set1_epi64x((int64_t)0xFFFFFFFF00000000LL)) ||
        !_mm_testz_si128(bad2, _mm_set1_epi64x((int64_t)0xFFFFFFFF00000000LL)))
        return 0u;
    if (k < n) /* the odd last value: the scalar conversion */
        it2n_regmap_put_f32(&out[2u * k], it2n_regmap_q24_to_f32(v[k]), order);
    return n;
}
#endif

static size_t put_q24_f32s_sse2(uint16_t *out, const int64_t *v, size_t n, unsigned order)
{
    __m128i bad = _mm_setzero_si128();
    size_t k = 0;
#define IT2N_REGMAP_F32S_LOOP(wo)                                                                         \
    for (k = 0; k + 4u <= n; k += 4u) {                                                                   \
        __m128i lo = f32x2(v + k, &bad), hi = f32x2(v + k + 2u, &bad);                                    \
        _mm_storeu_si128((__m128i *)(void *)(out + 2u * k), f32_order(_mm_unpacklo_epi64(lo, hi), (wo))); \
    }                                                                                                     \
    if (k + 2u <= n) {                                                                                    \
        _mm_storel_epi64((__m128i *)(void *)(out + 2u * k), f32_order(f32x2(v + k, &bad), (wo)));         \
        k += 2u;                                                                                          \
    }
    switch (order) {
    case IT2N_REGMAP_WO_CDAB: IT2N_REGMAP_F32S_LOOP(IT2N_REGMAP_WO_CDAB); break;
    case IT2N_REGMAP_WO_BADC: IT2N_REGMAP_F32S_LOOP(IT2N_REGMAP_WO_BADC); break;
    case IT2N_REGMAP_WO_DCBA: IT2N_REGMAP_F32S_LOOP(IT2N_REGMAP_WO_DCBA); break;
    default: IT2N_REGMAP_F32S_LOOP(IT2N_REGMAP_WO_ABCD); break;
    }
#undef IT2N_REGMAP_F32S_LOOP
    if (k < n) /* the odd last value: the scalar conversion */
        it2n_regmap_put_f32(&out[2u * k], it2n_regmap_q24_to_f32(v[k]), order);
    /* the high halves' flags (odd 32-bit lanes) */
    bad = _mm_and_si128(bad, _mm_set_epi32(-1, 0, -1, 0));
    bad = _mm_or_si128(bad, _mm_srli_si128(bad, 8));
    return _mm_cvtsi128_si32(_mm_srli_si128(bad, 4)) != 0 ? 0u : n;
}
#endif

void it2n_regmap_put_q24_f32s(uint16_t *out, const int64_t *v, size_t n, unsigned order)
{
    size_t k;
#if defined(IT2N_REGMAP_F32S_AVX2)
    if ((__builtin_cpu_supports("avx2") ? put_q24_f32s_avx2(out, v, n, order) : put_q24_f32s_sse2(out, v, n, order)) ==
        n)
        return;
#elif defined(IT2N_REGMAP_F32S_SSE2)
    if (put_q24_f32s_sse2(out, v, n, order) == n)
        return;
#endif
        /* One loop per order, so the order is a constant inside it (the result
     * block is read with every query). */
#define IT2N_REGMAP_PUT_F32S(wo) \
    for (k = 0; k < n; k++)      \
    it2n_regmap_put_f32(&out[2 * k], it2n_regmap_q24_to_f32(v[k]), (wo))
    switch (order) {
    case IT2N_REGMAP_WO_CDAB: IT2N_REGMAP_PUT_F32S(IT2N_REGMAP_WO_CDAB); break;
    case IT2N_REGMAP_WO_BADC: IT2N_REGMAP_PUT_F32S(IT2N_REGMAP_WO_BADC); break;
    case IT2N_REGMAP_WO_DCBA: IT2N_REGMAP_PUT_F32S(IT2N_REGMAP_WO_DCBA); break;
    default: IT2N_REGMAP_PUT_F32S(IT2N_REGMAP_WO_ABCD); break;
    }
#undef IT2N_REGMAP_PUT_F32S
}

/* Magnitudes beyond this saturate (2^62: a sum of two of them still fits). */
#define MAG_LIMIT ((uint64_t)1 << 62)

static uint64_t magnitude(int64_t v)
{
    return v < 0 ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
}

/* round(|v| * scale / 2^frac), half up, for frac <= 32 and scale < 2^31;
 * MAG_LIMIT when larger. |v| = ip * 2^frac + fp: fp * scale < 2^63. */
static uint64_t fixed_to_scaled(uint64_t a, unsigned frac, uint64_t scale)
{
    uint64_t ip = a >> frac, fp = a & (((uint64_t)1 << frac) - 1u);
    uint64_t part = (fp * scale + ((uint64_t)1 << (frac - 1u))) >> frac;
    if (ip != 0u && scale > (MAG_LIMIT - part) / ip)
        return MAG_LIMIT;
    return ip * scale + part;
}

/* round(|raw| * 2^frac / scale), half up (scale / 2 as the half, as the
 * daemon always rounded); MAG_LIMIT when larger. |raw| = q * scale + r:
 * r * 2^frac < 2^63. */
static uint64_t scaled_to_fixed(uint64_t a, unsigned frac, uint64_t scale)
{
    uint64_t q = a / scale, r = a % scale;
    uint64_t part = ((r << frac) + scale / 2u) / scale;
    if (q >= (MAG_LIMIT >> frac))
        return MAG_LIMIT;
    return (q << frac) + part;
}

int64_t it2n_regmap_q24_to_scaled(int64_t v, int32_t scale, int64_t lo, int64_t hi, int *sat)
{
    uint64_t m = fixed_to_scaled(magnitude(v), IT2N_REGMAP_Q24_FRAC, (uint64_t)(scale > 0 ? scale : 1));
    if (v < 0) {
        if (m > magnitude(lo)) {
            *sat = 1;
            return lo;
        }
        return -(int64_t)m;
    }
    if (m > (uint64_t)hi) {
        *sat = 1;
        return hi;
    }
    return (int64_t)m;
}

int64_t it2n_regmap_q24_from_scaled(int64_t raw, int32_t scale)
{
    uint64_t m = scaled_to_fixed(magnitude(raw), IT2N_REGMAP_Q24_FRAC, (uint64_t)(scale > 0 ? scale : 1));
    return raw < 0 ? -(int64_t)m : (int64_t)m;
}

uint16_t it2n_regmap_par_to_u16(int64_t par)
{
    if (par <= 0)
        return 0u;
    if (par >= (int64_t)1 << IT2N_REGMAP_PAR_FRAC)
        return (uint16_t)IT2N_REGMAP_MEMB_SCALE;
    return (uint16_t)fixed_to_scaled((uint64_t)par, IT2N_REGMAP_PAR_FRAC, IT2N_REGMAP_MEMB_SCALE);
}

int64_t it2n_regmap_par_from_u16(unsigned reg)
{
    return (int64_t)scaled_to_fixed(reg, IT2N_REGMAP_PAR_FRAC, IT2N_REGMAP_MEMB_SCALE);
}
