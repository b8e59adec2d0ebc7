/*
 * Evaluating the surfaces: Bernstein basis, tensor-product sums,
 * derivatives and grid sampling.
 *
 * At (u, w) the basis values B_i(u), B_j(w) (Q30) are shared by every
 * footprint and channel. Each surface value is two short stages over a
 * net's int32 mantissas, q_j = sum_i B_i(u) P_ij (rounded to the net's
 * mantissa scale) and sum_j B_j(w) q_j (rounded once to Q24), all 32 x 32 ->
 * 64 multiply-accumulates (SMLAL on ARMv7-M, four MULS on ARMv6-M) with a
 * few dozen bytes of stack. it2n_sample calls the same code per node, so a
 * sampled node is bit-identical to it2n_eval at the same (u, w). x86-64
 * hosts compute the same integers two products per instruction (SSE2,
 * apply_values below; tests/core/test_eval_exact.c checks them against
 * this definition).
 */
#include <string.h>

#include "it2n_internal.h"

#define Q30_ONE ((int32_t)1 << 30)
#define Q30_HALF ((int64_t)1 << 29)

/* The basis recurrence's product: one copy of the multiply on ARMv6-M (a
 * handful of calls per evaluation, flash matters more there). */
/* clang-format off */
#if IT2N_MUL_HALVES
__attribute__((noinline))
#endif
static uint64_t q30mul(uint32_t a, uint32_t b)
/* clang-format on */
{
    return it2n_umul32(a, b);
}

/* The recurrence for one degree (a constant where the host inlines it per
 * degree: the loops unroll). */
IT2N_INLINE void basis30(const unsigned deg, it2n_par t, int32_t b[IT2N_DIM])
{
    /* every value is in [0, 2^30]: unsigned products, no sign handling */
    uint32_t t30 = (uint32_t)((t + 2) >> 2), s30 = (uint32_t)Q30_ONE - t30;
    uint32_t v[IT2N_DIM];
    uint32_t sum = 0u;
    unsigned k, i, big = 0u;
    v[0] = (uint32_t)Q30_ONE;
    for (k = 1; k <= deg; k++) {
        /* b_k^k = t b_{k-1}^{k-1}; b_i^k = s b_i^{k-1} + t b_{i-1}^{k-1} */
        v[k] = (uint32_t)((q30mul(t30, v[k - 1u]) + (1u << 29)) >> 30);
        for (i = k - 1u; i >= 1u; i--) {
            uint64_t acc = q30mul(s30, v[i]) + q30mul(t30, v[i - 1u]);
            v[i] = (uint32_t)((acc + (1u << 29)) >> 30);
        }
        v[0] = (uint32_t)((q30mul(s30, v[0]) + (1u << 29)) >> 30);
    }
    /* Exact partition of unity: the largest value takes the rounding
     * residue (a few LSB), so sum_i b[i] = 2^30 exactly. Constant data give
     * constant surfaces, and a stage-1 sum never leaves the net's range. */
    for (i = 0; i <= deg; i++) {
        sum += v[i];
        big = v[i] > v[big] ? i : big;
    }
    v[big] += (uint32_t)Q30_ONE - sum;
    for (i = 0; i <= deg; i++) {
        b[i] = (int32_t)v[i];
    }
}

#if !IT2N_MUL_HALVES && defined(__x86_64__)
/* x86-64 hosts: one unrolled copy per degree (two per FC 23 query of
 * it2nd); the same arithmetic, the same values. */
#define IT2N_BASIS30_K(k) \
    case k:               \
        basis30(k, t, b); \
        break
#endif

void it2n__basis30(unsigned deg, it2n_par t, int32_t b[IT2N_DIM])
{
#ifdef IT2N_BASIS30_K
    /* Only the degrees this build holds (IT2N_MAX_DEGREE): a constant
     * beyond them would index past the arrays. */
    /* clang-format off */
    switch (deg) {
    IT2N_BASIS30_K(1);
#if IT2N_MAX_DEGREE >= 2
    IT2N_BASIS30_K(2);
#endif
#if IT2N_MAX_DEGREE >= 3
    IT2N_BASIS30_K(3);
#endif
#if IT2N_MAX_DEGREE >= 4
    IT2N_BASIS30_K(4);
#endif
#if IT2N_MAX_DEGREE >= 5
    IT2N_BASIS30_K(5);
#endif
#if IT2N_MAX_DEGREE >= 6
    IT2N_BASIS30_K(6);
#endif
#if IT2N_MAX_DEGREE >= 7
    IT2N_BASIS30_K(7);
#endif
    default:
        basis30(deg, t, b);
        break;
    }
    /* clang-format on */
#else
    basis30(deg, t, b);
#endif
}

/* Derivative basis in Q26: d/dt sum_i c_i B_i^deg(t) = sum_i c_i db[i], with
 * db[i] = deg (B_{i-1}^{deg-1}(t) - B_i^{deg-1}(t)), |db[i]| <= deg < 2^4. */
static void dbasis26(unsigned deg, it2n_par t, int32_t db[IT2N_DIM])
{
    int32_t b[IT2N_DIM];
    unsigned i;
    it2n__basis30(deg - 1u, t, b);
    for (i = 0; i <= deg; i++) {
        int32_t lo = i >= 1u ? b[i - 1u] : 0;
        int32_t hi = i < deg ? b[i] : 0;
        db[i] = (int32_t)((it2n_smul32(lo - hi, (int32_t)deg) + 8) >> 4);
    }
}

/*
 * One surface value: sum_j cw[j] sum_i cu[i] net[i (m+1) + j]. cu, cw are
 * Q30 basis values or Q26 derivative weights (|cu| sums to at most 2^30
 * times 2 deg). Stage 1 rounds to the mantissa scale (a convex combination:
 * the basis sums to 2^30 exactly, so it stays within the net's int32 range),
 * or half of it for derivative weights (up to 2 deg times the net), stage 2
 * to Q24. False if the result does not fit Q39.24 (derivatives of nets near
 * 2^39 only).
 */
/* The two stages with stage-1 shift s1. Wide cores inline it at each call
 * with a constant shift; ARMv6-M keeps one copy for both shifts (flash; a
 * run-time shift costs a few instructions per column). One accumulator at
 * a time: no spills on ARMv6-M's 8 low registers. */
#if IT2N_MUL_HALVES
#define TWO_STAGES_LINKAGE __attribute__((noinline)) static
#else
#define TWO_STAGES_LINKAGE IT2N_INLINE
#endif
/* x86-64 unrolls the inner sum where the degree is a constant
 * (two_stages_host below); MCU builds keep the loop (flash). */
#if !IT2N_MUL_HALVES && defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define TWO_STAGES_UNROLL _Pragma("GCC unroll 8")
#else
#define TWO_STAGES_UNROLL
#endif
TWO_STAGES_LINKAGE int64_t two_stages(const int32_t *net, unsigned n1, unsigned m1, const int32_t *cu,
                                      const int32_t *cw, const int s1)
{
    int64_t acc = 0;
    unsigned i, j;
    for (j = 0; j < m1; j++) {
        const int32_t *p = net + j;
        int64_t q = 0;
        TWO_STAGES_UNROLL
        for (i = 0; i < n1; i++, p += m1) {
            q += it2n_smul32(cu[i], *p);
        }
        q = (q + ((int64_t)1 << (s1 - 1))) >> s1;
        acc += it2n_smul32(cw[j], (int32_t)q);
    }
    return acc;
}

#if !IT2N_MUL_HALVES && defined(__x86_64__)
/* x86-64 hosts (the daemon, the CLI): two_stages inlined once per degree,
 * so the inner sum has a constant trip count and unrolls. The same
 * products summed in the same order: results identical (core vectors),
 * about 28 % fewer instructions per it2n_eval at degree 3 (an FC 23 query
 * of it2nd is mostly this). MCU targets keep the single loop (flash). */
#define IT2N_TWO_STAGES_K(k) \
    case k: return s1 == 30 ? two_stages(net, k, m1, cu, cw, 30) : two_stages(net, k, m1, cu, cw, 31)

static int64_t two_stages_host(const int32_t *net, unsigned n1, unsigned m1, const int32_t *cu, const int32_t *cw,
                               int s1)
{
    /* clang-format off */
    switch (n1) {
    IT2N_TWO_STAGES_K(2);
    IT2N_TWO_STAGES_K(3);
    IT2N_TWO_STAGES_K(4);
    IT2N_TWO_STAGES_K(5);
    IT2N_TWO_STAGES_K(6);
    IT2N_TWO_STAGES_K(7);
    IT2N_TWO_STAGES_K(8);
    default:
        return s1 == 30 ? two_stages(net, n1, m1, cu, cw, 30)
                        : two_stages(net, n1, m1, cu, cw, 31);
    }
    /* clang-format on */
}
#define IT2N_TWO_STAGES_HOST 1
#endif

static bool surface(const int32_t *net, int frac, unsigned n1, unsigned m1, const int32_t *cu, int ufrac,
                    const int32_t *cw, int wfrac, it2n_val *out)
{
    int64_t acc;
    int s, s1 = ufrac < 30 ? 31 : 30;
#ifdef IT2N_TWO_STAGES_HOST
    acc = two_stages_host(net, n1, m1, cu, cw, s1);
#else
    acc = s1 == 30 ? two_stages(net, n1, m1, cu, cw, 30) : two_stages(net, n1, m1, cu, cw, 31);
#endif
    s = ufrac - s1 + wfrac + frac - IT2N_VAL_FRAC;
    if (s < 0) {
        /* Only nets near 2^39 get here: check the left shift. */
        int64_t lim = INT64_MAX >> (unsigned)-s;
        if (acc > lim || acc < -lim) {
            return false;
        }
    }
    *out = it2n__shift_round(acc, s);
    return true;
}

/* Hosted builds only: <emmintrin.h> includes <stdlib.h>. IT2N_NO_SIMD
 * keeps the scalar path (the same values). */
#if !IT2N_MUL_HALVES && defined(__x86_64__) && defined(__SSE2__) && defined(__GNUC__) && __STDC_HOSTED__ && \
    !defined(IT2N_NO_SIMD)
/*
 * x86-64 hosts (it2nd answers every FC 23 query with this): the values of
 * every net at once with SSE2's PMULUDQ, two 32 x 32 -> 64 products per
 * instruction, unsigned. The basis values are unsigned and sum to 2^30
 * exactly (it2n__basis30), so a net biased by 2^31 (its sign bit flipped:
 * P + 2^31, unsigned) gives
 *   sum_i B_i (P_ij + 2^31) = sum_i B_i P_ij + 2^61,
 * and rounding that to the mantissa scale (2^61 is a multiple of 2^30)
 * gives q_j + 2^31, the biased stage-1 value, below 2^32 because q_j is a
 * convex combination of the net. Stage 2 the same way: the total is the
 * exact signed sum plus 2^61, every partial sum below 2^62. The same
 * integers as two_stages, so the results are bit-identical (core vectors);
 * the derivative weights are signed and keep the scalar path.
 */
#include <emmintrin.h>
#define IT2N_VALUES_SSE2 1

/* Columns j.. of one row (cols of them, 1..3), biased; the missing ones
 * read as 0 (their weight is 0 below). */
IT2N_INLINE __m128i load_tail(const int32_t *p, unsigned cols)
{
    __m128i x;
    if (cols == 3u) {
        x = _mm_unpacklo_epi64(_mm_loadl_epi64((const __m128i *)(const void *)p), _mm_cvtsi32_si128(p[2]));
    } else if (cols == 2u) {
        x = _mm_loadl_epi64((const __m128i *)(const void *)p);
    } else {
        x = _mm_cvtsi32_si128(p[0]);
    }
    return _mm_xor_si128(x, _mm_set1_epi32(INT32_MIN));
}

/* The odd 32-bit elements of x into the even ones (PMULUDQ's operands). */
#define ODD(x) _mm_shuffle_epi32((x), 0xF5)

/* Stage 2 of one block of columns: ev / od hold the stage-1 sums of its
 * even / odd columns (biased), bwe / bwo their weights. */
IT2N_INLINE __m128i stage2(__m128i acc, __m128i ev, __m128i od, __m128i bwe, __m128i bwo)
{
    const __m128i half = _mm_set1_epi64x((int64_t)1 << 29);
    ev = _mm_srli_epi64(_mm_add_epi64(ev, half), 30);
    od = _mm_srli_epi64(_mm_add_epi64(od, half), 30);
    acc = _mm_add_epi64(acc, _mm_mul_epu32(ev, bwe));
    return _mm_add_epi64(acc, _mm_mul_epu32(od, bwo));
}

/* The values of every net in fpmask into out[fp][ch], n1 rows (a constant
 * at each call: the row loop unrolls), m1 columns. bu[i] is B_i(u) in both
 * 64-bit lanes, bwe[b] / bwo[b] B_j(w) of the even / odd columns of the
 * 4-column block b (0 where a column is missing). */
IT2N_INLINE void values_sse2(const it2n_model *mdl, unsigned fpmask, const unsigned n1, const unsigned m1,
                             const __m128i *bu, const __m128i *bwe, const __m128i *bwo, it2n_val *out)
{
    const __m128i bias = _mm_set1_epi32(INT32_MIN);
    unsigned fp, ch, i, j, b;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            const int32_t *net = mdl->net[fp][ch];
            it2n_val *o = &out[fp * IT2N_CH_COUNT + ch];
            __m128i acc = _mm_setzero_si128(), ev, od;
            int64_t v;
            *o = 0;
            if (!(fpmask & (1u << fp)) || !it2n__ch_used(mdl->flags, ch)) {
                continue;
            }
            for (j = 0, b = 0; j + 4u <= m1; j += 4u, b++) {
                ev = od = _mm_setzero_si128();
                TWO_STAGES_UNROLL
                for (i = 0; i < n1; i++) {
                    __m128i x = _mm_xor_si128(_mm_loadu_si128((const __m128i *)(const void *)(net + i * m1 + j)), bias);
                    od = _mm_add_epi64(od, _mm_mul_epu32(ODD(x), bu[i]));
                    ev = _mm_add_epi64(ev, _mm_mul_epu32(x, bu[i]));
                }
                acc = stage2(acc, ev, od, bwe[b], bwo[b]);
            }
            if (j < m1) {
                ev = od = _mm_setzero_si128();
                for (i = 0; i < n1; i++) {
                    __m128i x = load_tail(net + i * m1 + j, m1 - j);
                    od = _mm_add_epi64(od, _mm_mul_epu32(ODD(x), bu[i]));
                    ev = _mm_add_epi64(ev, _mm_mul_epu32(x, bu[i]));
                }
                acc = stage2(acc, ev, od, bwe[b], bwo[b]);
            }
            acc = _mm_add_epi64(acc, _mm_unpackhi_epi64(acc, acc));
            v = (int64_t)((uint64_t)_mm_cvtsi128_si64(acc) - ((uint64_t)1 << 61));
            /* convex weights: the value is within the net, so it fits
             * Q39.24 (a left shift for frac < -6 cannot overflow, as in
             * it2n_sample) */
            *o = it2n__shift_round(v, 30 + mdl->frac[fp][ch] - IT2N_VAL_FRAC);
        }
    }
}

/* Constant row counts (and the 4 columns of degree 3, the common bicubic
 * surface): the loops unroll. */
#define IT2N_VALUES_SSE2_K(k)                                 \
    case k:                                                   \
        if (m1 == 4u) {                                       \
            values_sse2(mdl, fpmask, k, 4u, vu, we, wo, out); \
        } else {                                              \
            values_sse2(mdl, fpmask, k, m1, vu, we, wo, out); \
        }                                                     \
        break

#if defined(__GNUC__) && !defined(IT2N_NO_AVX2)
/*
 * x86-64 hosts with AVX2 (chosen at run time, __builtin_cpu_supports):
 * the same biased sums four columns per instruction. A 4-column block of
 * row i, biased, is widened to four 64-bit lanes (VPMOVZXDQ) and
 * multiplied by B_i(u) in every lane: the lanes hold the stage-1 sums of
 * the block's columns, the very integers values_sse2 holds in its even and
 * odd lanes; stage 2 multiplies each by its B_j(w) (0 for a missing tail
 * column) and the lanes are added. Every partial sum is below 2^62, so the
 * order of the additions does not matter: bit-identical to values_sse2 and
 * two_stages (tests/core/test_eval_exact.c runs both SIMD paths).
 */
#include <immintrin.h>
#define IT2N_VALUES_AVX2 1
#define IT2N_AVX2_FN __attribute__((target("avx2")))

IT2N_AVX2_FN IT2N_INLINE void values_avx2(const it2n_model *mdl, unsigned fpmask, const unsigned n1, const unsigned m1,
                                          const int32_t *cu, const int32_t *cw, it2n_val *out)
{
    /* The weights as vectors (registers where n1 is a constant: no
     * 32-byte-aligned arrays on the stack). bw[b]: B_j(w) of the columns
     * of block b, 0 for a missing tail column. */
    __m256i bu[IT2N_DIM], bw[(IT2N_DIM + 3) / 4];
    const __m128i bias = _mm_set1_epi32(INT32_MIN);
    const __m256i half = _mm256_set1_epi64x((int64_t)1 << 29);
    const unsigned flags = mdl->flags;
    unsigned fp, ch, i, j, b;
    for (i = 0; i < n1; i++) {
        bu[i] = _mm256_set1_epi64x(cu[i]);
    }
    for (b = 0; b * 4u < m1; b++) {
        int32_t c[4];
        for (i = 0; i < 4u; i++) {
            c[i] = b * 4u + i < m1 ? cw[b * 4u + i] : 0;
        }
        bw[b] = _mm256_set_epi64x(c[3], c[2], c[1], c[0]);
    }
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (!(fpmask & (1u << fp))) {
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                out[fp * IT2N_CH_COUNT + ch] = 0;
            }
            continue;
        }
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            const int32_t *net = mdl->net[fp][ch];
            it2n_val *o = &out[fp * IT2N_CH_COUNT + ch];
            __m256i acc = _mm256_setzero_si256();
            __m128i t;
            int64_t v;
            if (!it2n__ch_used(flags, ch)) {
                *o = 0;
                continue;
            }
            for (j = 0, b = 0; j < m1; j += 4u, b++) {
                __m256i q = _mm256_setzero_si256();
                TWO_STAGES_UNROLL
                for (i = 0; i < n1; i++) {
                    const int32_t *p = net + i * m1 + j;
                    __m128i x = m1 - j >= 4u ? _mm_xor_si128(_mm_loadu_si128((const __m128i *)(const void *)p), bias)
                                             : load_tail(p, m1 - j);
                    q = _mm256_add_epi64(q, _mm256_mul_epu32(_mm256_cvtepu32_epi64(x), bu[i]));
                }
                q = _mm256_srli_epi64(_mm256_add_epi64(q, half), 30);
                acc = _mm256_add_epi64(acc, _mm256_mul_epu32(q, bw[b]));
            }
            t = _mm_add_epi64(_mm256_castsi256_si128(acc), _mm256_extracti128_si256(acc, 1));
            t = _mm_add_epi64(t, _mm_unpackhi_epi64(t, t));
            v = (int64_t)((uint64_t)_mm_cvtsi128_si64(t) - ((uint64_t)1 << 61));
            *o = it2n__shift_round(v, 30 + mdl->frac[fp][ch] - IT2N_VAL_FRAC);
        }
    }
}

/*
 * Four columns (m1 == 4: cubic in w, the common bicubic surface): four
 * nets at a time, one per group of four consecutive flat [fp][ch]
 * indices (frac and net are flat arrays in that order). Stage 1 of a net
 * multiplies each row, sign-extended, by B_i(u) (VPMULDQ: signed, exact),
 * its lanes the four columns, starting from 2^61 + 2^29: the sum
 * S_j + 2^61 + 2^29 is non-negative (|S_j| <= 2^30 2^31), so a logical
 * shift by 30 gives the rounded stage-1 value q_j plus 2^31, the biased
 * value values_avx2 computes. Stage 2 as there. The four nets' lanes are
 * added in one transpose (the values biased by 2^61), and the rounding to
 * Q24 is one variable shift per lane: for 1 <= s <= 61,
 *   (v + 2^61 + 2^(s-1)) >> s  ==  ((v + 2^(s-1)) >> s) + 2^(61-s)
 * (2^61 is a multiple of 2^s), which is it2n__shift_round(v, s) once
 * 2^(61-s) is subtracted; a group with another shift on a net in use
 * goes through it2n__shift_round. Nets of unused channels are computed
 * and zeroed. The same integers as values_avx2 and two_stages.
 */
IT2N_AVX2_FN IT2N_INLINE __m256i net_m4(const int32_t *net, const unsigned n1, const __m256i *bu, __m256i bw)
{
    __m256i q = _mm256_set1_epi64x(((int64_t)1 << 61) + ((int64_t)1 << 29));
    unsigned i;
    TWO_STAGES_UNROLL
    for (i = 0; i < n1; i++) {
        __m256i x = _mm256_cvtepi32_epi64(_mm_loadu_si128((const __m128i *)(const void *)(net + 4u * i)));
        q = _mm256_add_epi64(q, _mm256_mul_epi32(x, bu[i]));
    }
    return _mm256_mul_epu32(_mm256_srli_epi64(q, 30), bw);
}

#define IT2N_NETS (IT2N_FP_COUNT * IT2N_CH_COUNT)

/* The nets k, k + l1, k + l2, k + l3 (the first cnt of them distinct: a
 * partial group repeats its last net, read, never stored) into out[k..],
 * their lanes of `used` (bit k: a net in use) zero where unused. */
IT2N_AVX2_FN IT2N_INLINE void group_m4(const it2n_model *mdl, const unsigned n1, const __m256i *bu, __m256i bw,
                                       uint64_t used, unsigned k, const unsigned l1, const unsigned l2,
                                       const unsigned l3, const unsigned cnt, it2n_val *out)
{
    const int32_t *net0 = &mdl->net[0][0][0];
    const int8_t *frac = &mdl->frac[0][0];
    const __m256i one = _mm256_set1_epi64x(1), lanebit = _mm256_set_epi64x(8, 4, 2, 1);
    __m256i a0 = net_m4(net0 + (size_t)k * IT2N_DIM * IT2N_DIM, n1, bu, bw);
    __m256i a1 = net_m4(net0 + (size_t)(k + l1) * IT2N_DIM * IT2N_DIM, n1, bu, bw);
    __m256i a2 = net_m4(net0 + (size_t)(k + l2) * IT2N_DIM * IT2N_DIM, n1, bu, bw);
    __m256i a3 = net_m4(net0 + (size_t)(k + l3) * IT2N_DIM * IT2N_DIM, n1, bu, bw);
    /* the lanes of a0..a3 summed: v + 2^61 of net l in lane l */
    __m256i s01 = _mm256_add_epi64(_mm256_unpacklo_epi64(a0, a1), _mm256_unpackhi_epi64(a0, a1));
    __m256i s23 = _mm256_add_epi64(_mm256_unpacklo_epi64(a2, a3), _mm256_unpackhi_epi64(a2, a3));
    __m256i v = _mm256_add_epi64(_mm256_permute2x128_si256(s01, s23, 0x20), _mm256_permute2x128_si256(s01, s23, 0x31));
    __m256i live = _mm256_set1_epi64x((int64_t)((used >> k) & 15u));
    __m256i s, r, ok;
    int64_t t[4];
    unsigned i;
    if (cnt == 4u) {
        int32_t f4;
        memcpy(&f4, frac + k, sizeof f4); /* frac[k..k+3], sign-extended */
        s = _mm256_cvtepi8_epi64(_mm_cvtsi32_si128(f4));
    } else {
        s = _mm256_set_epi64x(frac[k + l3], frac[k + l2], frac[k + l1], frac[k]);
    }
    live = _mm256_cmpeq_epi64(_mm256_and_si256(live, lanebit), lanebit);
    s = _mm256_add_epi64(s, _mm256_set1_epi64x(30 - IT2N_VAL_FRAC));
    ok = _mm256_and_si256(_mm256_cmpgt_epi64(s, _mm256_setzero_si256()), _mm256_cmpgt_epi64(_mm256_set1_epi64x(62), s));
    if (_mm256_testz_si256(_mm256_andnot_si256(ok, live), live)) {
        r = _mm256_add_epi64(v, _mm256_sllv_epi64(one, _mm256_sub_epi64(s, one)));
        r = _mm256_sub_epi64(_mm256_srlv_epi64(r, s),
                             _mm256_sllv_epi64(one, _mm256_sub_epi64(_mm256_set1_epi64x(61), s)));
        r = _mm256_and_si256(r, live);
    } else {
        /* a shift of 0 or less (a left shift) or of 62 or more */
        _mm256_storeu_si256((__m256i *)(void *)t, v);
        for (i = 0; i < cnt; i++) {
            t[i] = (used >> (k + i)) & 1u ? it2n__shift_round((int64_t)((uint64_t)t[i] - ((uint64_t)1 << 61)),
                                                              30 + frac[k + i] - IT2N_VAL_FRAC)
                                          : 0;
        }
        r = _mm256_loadu_si256((const __m256i *)(const void *)t);
    }
    if (cnt == 4u) {
        _mm256_storeu_si256((__m256i *)(void *)(out + k), r);
    } else {
        _mm256_storeu_si256((__m256i *)(void *)t, r);
        for (i = 0; i < cnt; i++) {
            out[k + i] = t[i];
        }
    }
}

IT2N_AVX2_FN IT2N_INLINE void values_avx2_m4(const it2n_model *mdl, unsigned fpmask, const unsigned n1,
                                             const int32_t *cu, const int32_t *cw, it2n_val *out)
{
    __m256i bu[IT2N_DIM];
    const __m256i bw = _mm256_set_epi64x(cw[3], cw[2], cw[1], cw[0]);
    uint64_t used = 0u;
    unsigned i, k, k0 = IT2N_NETS, k1 = 0u, fp, chbits = 0u;
    for (i = 0; i < n1; i++) {
        bu[i] = _mm256_set1_epi64x(cu[i]);
    }
    /* every channel but z without IT2N_F_Z (it2n__ch_used) */
    chbits = ((1u << IT2N_CH_COUNT) - 1u) & ~((mdl->flags & IT2N_F_Z) ? 0u : 1u << IT2N_CH_Z);
    if (fpmask == (1u << IT2N_FP_COUNT) - 1u) { /* type-2: chbits in every footprint's six bits */
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            used |= (uint64_t)chbits << (fp * IT2N_CH_COUNT);
        }
        k0 = 0u;
        k1 = IT2N_NETS;
    } else {
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            if (fpmask & (1u << fp)) {
                used |= (uint64_t)chbits << (fp * IT2N_CH_COUNT);
                k0 = k0 < fp * IT2N_CH_COUNT ? k0 : fp * IT2N_CH_COUNT;
                k1 = (fp + 1u) * IT2N_CH_COUNT;
            }
        }
        /* the footprints before the first and after the last one in fpmask */
        for (k = 0; k < k0; k++) {
            out[k] = 0;
        }
        for (k = k1; k < IT2N_NETS; k++) {
            out[k] = 0;
        }
    }
    for (k = k0; k + 4u <= k1; k += 4u) {
        group_m4(mdl, n1, bu, bw, used, k, 1u, 2u, 3u, 4u, out);
    }
    if (k1 - k == 3u) {
        group_m4(mdl, n1, bu, bw, used, k, 1u, 2u, 2u, 3u, out);
    } else if (k1 - k == 2u) {
        group_m4(mdl, n1, bu, bw, used, k, 1u, 1u, 1u, 2u, out);
    } else if (k1 - k == 1u) {
        group_m4(mdl, n1, bu, bw, used, k, 0u, 0u, 0u, 1u, out);
    }
}

#define IT2N_VALUES_AVX2_K(k)                             \
    case k:                                               \
        if (m1 == 4u) {                                   \
            values_avx2_m4(mdl, fpmask, k, bu, bw, out);  \
        } else {                                          \
            values_avx2(mdl, fpmask, k, m1, bu, bw, out); \
        }                                                 \
        break

/* apply_values with AVX2 (the caller checked the CPU has it). */
IT2N_AVX2_FN static void apply_values_avx2(const it2n_model *mdl, unsigned fpmask, const int32_t *bu, const int32_t *bw,
                                           it2n_val *out)
{
    unsigned n1 = mdl->n + 1u, m1 = mdl->m + 1u;
    switch (n1) {
        IT2N_VALUES_AVX2_K(2);
#if IT2N_MAX_DEGREE >= 2
        IT2N_VALUES_AVX2_K(3);
#endif
#if IT2N_MAX_DEGREE >= 3
        IT2N_VALUES_AVX2_K(4);
#endif
#if IT2N_MAX_DEGREE >= 4
        IT2N_VALUES_AVX2_K(5);
#endif
#if IT2N_MAX_DEGREE >= 5
        IT2N_VALUES_AVX2_K(6);
#endif
#if IT2N_MAX_DEGREE >= 6
        IT2N_VALUES_AVX2_K(7);
#endif
#if IT2N_MAX_DEGREE >= 7
        IT2N_VALUES_AVX2_K(8);
#endif
    default: values_avx2(mdl, fpmask, n1, m1, bu, bw, out); break;
    }
}
#endif

/*
 * The bases of u and w together when their degrees are equal (the
 * bicubic surface): basis30's recurrence in the two 64-bit lanes of SSE2
 * (PMULUDQ: the same 32 x 32 -> 64 unsigned products, the same sums and
 * roundings), then each lane's partition-of-unity correction as there.
 * The same values as two calls of it2n__basis30 (test_eval_exact checks
 * them against its own basis).
 */
IT2N_INLINE void basis30_pair(const unsigned deg, it2n_par u, it2n_par w, int32_t bu[IT2N_DIM], int32_t bw[IT2N_DIM])
{
    const __m128i half = _mm_set1_epi64x((int64_t)1 << 29);
    uint32_t tu = (uint32_t)((u + 2) >> 2), tw = (uint32_t)((w + 2) >> 2);
    __m128i t = _mm_set_epi64x(tw, tu);
    __m128i sv = _mm_sub_epi64(_mm_set1_epi64x(Q30_ONE), t);
    __m128i v[IT2N_DIM];
    unsigned k, i;
    v[0] = _mm_set1_epi64x(Q30_ONE);
    TWO_STAGES_UNROLL
    for (k = 1; k <= deg; k++) {
        v[k] = _mm_srli_epi64(_mm_add_epi64(_mm_mul_epu32(t, v[k - 1u]), half), 30);
        TWO_STAGES_UNROLL
        for (i = k - 1u; i >= 1u; i--) {
            __m128i acc = _mm_add_epi64(_mm_mul_epu32(sv, v[i]), _mm_mul_epu32(t, v[i - 1u]));
            v[i] = _mm_srli_epi64(_mm_add_epi64(acc, half), 30);
        }
        v[0] = _mm_srli_epi64(_mm_add_epi64(_mm_mul_epu32(sv, v[0]), half), 30);
    }
    /* Each lane's correction: the first largest value takes 2^30 - sum.
     * Values are at most 2^30: the low 32 bits of a lane compare signed. */
    {
        __m128i sum = v[0], mx = v[0], big = _mm_setzero_si128(), res;
        TWO_STAGES_UNROLL
        for (i = 1; i <= deg; i++) {
            __m128i gt = _mm_cmpgt_epi32(v[i], mx);
            sum = _mm_add_epi64(sum, v[i]);
            mx = _mm_or_si128(_mm_and_si128(gt, v[i]), _mm_andnot_si128(gt, mx));
        }
        TWO_STAGES_UNROLL
        for (i = deg + 1u; i-- > 0u;) { /* down: the first index of the largest is left */
            __m128i eq = _mm_cmpeq_epi32(v[i], mx);
            big = _mm_or_si128(_mm_and_si128(eq, _mm_set1_epi32((int)i)), _mm_andnot_si128(eq, big));
        }
        res = _mm_sub_epi32(_mm_set1_epi32(Q30_ONE), sum);
        TWO_STAGES_UNROLL
        for (i = 0; i <= deg; i++) {
            __m128i at = _mm_cmpeq_epi32(big, _mm_set1_epi32((int)i));
            __m128i x = _mm_add_epi32(v[i], _mm_and_si128(at, res));
            bu[i] = _mm_cvtsi128_si32(x);
            bw[i] = _mm_cvtsi128_si32(_mm_srli_si128(x, 8));
        }
    }
}

/* Constant degrees (the loops unroll), as it2n__basis30. */
#define IT2N_BASIS30_PAIR_K(k) \
    case k: basis30_pair(k, u, w, bu, bw); break

static void bases30(const it2n_model *mdl, it2n_par u, it2n_par w, int32_t bu[IT2N_DIM], int32_t bw[IT2N_DIM])
{
    if (mdl->n != mdl->m) {
        it2n__basis30(mdl->n, u, bu);
        it2n__basis30(mdl->m, w, bw);
        return;
    }
    /* clang-format off */
    switch (mdl->n) {
    IT2N_BASIS30_PAIR_K(1);
#if IT2N_MAX_DEGREE >= 2
    IT2N_BASIS30_PAIR_K(2);
#endif
#if IT2N_MAX_DEGREE >= 3
    IT2N_BASIS30_PAIR_K(3);
#endif
#if IT2N_MAX_DEGREE >= 4
    IT2N_BASIS30_PAIR_K(4);
#endif
#if IT2N_MAX_DEGREE >= 5
    IT2N_BASIS30_PAIR_K(5);
#endif
#if IT2N_MAX_DEGREE >= 6
    IT2N_BASIS30_PAIR_K(6);
#endif
#if IT2N_MAX_DEGREE >= 7
    IT2N_BASIS30_PAIR_K(7);
#endif
    default:
        it2n__basis30(mdl->n, u, bu);
        it2n__basis30(mdl->m, w, bw);
        break;
    }
    /* clang-format on */
}

/* apply_values with SSE2. */
static void apply_values_sse2(const it2n_model *mdl, unsigned fpmask, const int32_t *bu, const int32_t *bw,
                              it2n_val *out)
{
    __m128i vu[IT2N_DIM], we[(IT2N_DIM + 3) / 4], wo[(IT2N_DIM + 3) / 4];
    unsigned n1 = mdl->n + 1u, m1 = mdl->m + 1u, i, b;
    for (i = 0; i < n1; i++) {
        vu[i] = _mm_set1_epi64x(bu[i]);
    }
    for (b = 0; b * 4u < m1; b++) {
        int32_t c[4];
        for (i = 0; i < 4u; i++) {
            c[i] = b * 4u + i < m1 ? bw[b * 4u + i] : 0;
        }
        we[b] = _mm_set_epi64x(c[2], c[0]);
        wo[b] = _mm_set_epi64x(c[3], c[1]);
    }
    /* Row counts this build holds only (IT2N_DIM), as it2n__basis30. */
    /* clang-format off */
    switch (n1) {
    IT2N_VALUES_SSE2_K(2);
#if IT2N_MAX_DEGREE >= 2
    IT2N_VALUES_SSE2_K(3);
#endif
#if IT2N_MAX_DEGREE >= 3
    IT2N_VALUES_SSE2_K(4);
#endif
#if IT2N_MAX_DEGREE >= 4
    IT2N_VALUES_SSE2_K(5);
#endif
#if IT2N_MAX_DEGREE >= 5
    IT2N_VALUES_SSE2_K(6);
#endif
#if IT2N_MAX_DEGREE >= 6
    IT2N_VALUES_SSE2_K(7);
#endif
#if IT2N_MAX_DEGREE >= 7
    IT2N_VALUES_SSE2_K(8);
#endif
    default:
        values_sse2(mdl, fpmask, n1, m1, vu, we, wo, out);
        break;
    }
    /* clang-format on */
}

/* The values of every net in fpmask (basis bu, bw: Q30, summing to 2^30)
 * into out[fp][ch], as apply() with ufrac = wfrac = 30 computes them:
 * AVX2 where the CPU has it, else SSE2 (a call of its own each, so neither
 * one's vectors are on the other's stack). */
static void apply_values(const it2n_model *mdl, unsigned fpmask, const int32_t *bu, const int32_t *bw, it2n_val *out)
{
#ifdef IT2N_VALUES_AVX2
    if (__builtin_cpu_supports("avx2")) {
        apply_values_avx2(mdl, fpmask, bu, bw, out);
        return;
    }
#endif
    apply_values_sse2(mdl, fpmask, bu, bw, out);
}
#endif

/*
 * One pair of weight vectors applied to every net in fpmask into
 * out[fp][ch]. Returns false (and names fp, ch in *bad) if a result does not
 * fit Q39.24.
 */
static bool apply(const it2n_model *mdl, unsigned fpmask, const int32_t *cu, int ufrac, const int32_t *cw, int wfrac,
                  it2n_val *out, unsigned *bad)
{
    unsigned n1 = mdl->n + 1u, m1 = mdl->m + 1u, fp, ch;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            it2n_val *o = &out[fp * IT2N_CH_COUNT + ch];
            *o = 0;
            if (!(fpmask & (1u << fp)) || !it2n__ch_used(mdl->flags, ch)) {
                continue;
            }
            if (!surface(mdl->net[fp][ch], mdl->frac[fp][ch], n1, m1, cu, ufrac, cw, wfrac, o)) {
                *bad = fp << 4 | ch; /* no division needed to split it */
                return false;
            }
        }
    }
    return true;
}

void it2n__summarise(const it2n_model *mdl, it2n_point *out)
{
    it2n__summarise_flags(mdl->flags, out);
}

#ifdef IT2N_VALUES_AVX2
/*
 * The type-2 summary with AVX2 (the caller checked the CPU): the
 * memberships T, I, F of a footprint are three consecutive values, one
 * vector each (a fourth lane read from the next field and never used):
 * minima and maxima by compare and blend, the out-of-range flags by one
 * unsigned compare per footprint (sign bits flipped). The same values and
 * bits as the scalar code below, which it replaces for it2nd's FC 23.
 */
IT2N_AVX2_FN static void summarise_avx2(it2n_point *out)
{
    const __m256i flip = _mm256_set1_epi64x(INT64_MIN), one = _mm256_set1_epi64x(IT2N_VAL_ONE ^ INT64_MIN);
    const __m256i three = _mm256_set_epi64x(0, -1, -1, -1);
#define IT2N_LOAD_TIF(fp) _mm256_loadu_si256((const __m256i *)(const void *)&out->v[(fp)][IT2N_CH_T])
#define IT2N_MIN(a, b) _mm256_blendv_epi8((a), (b), _mm256_cmpgt_epi64((a), (b)))
#define IT2N_MAX(a, b) _mm256_blendv_epi8((a), (b), _mm256_cmpgt_epi64((b), (a)))
    __m256i d = IT2N_LOAD_TIF(IT2N_FP_D), a0 = IT2N_LOAD_TIF(IT2N_FP_LL), a1 = IT2N_LOAD_TIF(IT2N_FP_RR);
    __m256i b0 = IT2N_LOAD_TIF(IT2N_FP_LR), b1 = IT2N_LOAD_TIF(IT2N_FP_RL);
    uint32_t oor = 0u;
    unsigned fp;
    _mm256_maskstore_epi64((long long *)(void *)out->sum.upper_min, three, IT2N_MIN(IT2N_MIN(d, a0), a1));
    _mm256_maskstore_epi64((long long *)(void *)out->sum.upper_max, three, IT2N_MAX(IT2N_MAX(d, a0), a1));
    _mm256_maskstore_epi64((long long *)(void *)out->sum.lower_min, three, IT2N_MIN(IT2N_MIN(d, b0), b1));
    _mm256_maskstore_epi64((long long *)(void *)out->sum.lower_max, three, IT2N_MAX(IT2N_MAX(d, b0), b1));
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        __m256i x = _mm256_xor_si256(IT2N_LOAD_TIF(fp), flip);
        oor |= ((uint32_t)_mm256_movemask_pd(_mm256_castsi256_pd(_mm256_cmpgt_epi64(x, one))) & 7u) << (fp * 3u);
    }
#undef IT2N_LOAD_TIF
#undef IT2N_MIN
#undef IT2N_MAX
    out->out_of_range = oor;
}
#endif

void it2n__summarise_flags(unsigned flags, it2n_point *out)
{
    unsigned k, fp;
    uint32_t oor = 0u;
#ifdef IT2N_VALUES_AVX2
    if ((flags & IT2N_F_TYPE1) == 0u && __builtin_cpu_supports("avx2")) {
        summarise_avx2(out);
        return;
    }
#endif
    if ((flags & IT2N_F_TYPE1) != 0u) {
        /* one footprint: every bound is its value */
        for (k = 0; k < 3u; k++) {
            it2n_val d = out->v[IT2N_FP_D][IT2N_CH_T + k];
            out->sum.upper_min[k] = out->sum.upper_max[k] = d;
            out->sum.lower_min[k] = out->sum.lower_max[k] = d;
            if ((uint64_t)d > (uint64_t)IT2N_VAL_ONE) {
                oor |= (uint32_t)1u << (IT2N_FP_D * 3u + k);
            }
        }
        out->out_of_range = oor;
        return;
    }
    for (k = 0; k < 3u; k++) {
        unsigned ch = IT2N_CH_T + k;
        it2n_val d = out->v[IT2N_FP_D][ch];
        it2n_val umin = d, umax = d, lmin = d, lmax = d;
        /* upper over LL, D, RR; lower over LR, D, RL */
        it2n_val a0 = out->v[IT2N_FP_LL][ch], a1 = out->v[IT2N_FP_RR][ch];
        it2n_val b0 = out->v[IT2N_FP_LR][ch], b1 = out->v[IT2N_FP_RL][ch];
        umin = a0 < umin ? a0 : umin;
        umin = a1 < umin ? a1 : umin;
        umax = a0 > umax ? a0 : umax;
        umax = a1 > umax ? a1 : umax;
        lmin = b0 < lmin ? b0 : lmin;
        lmin = b1 < lmin ? b1 : lmin;
        lmax = b0 > lmax ? b0 : lmax;
        lmax = b1 > lmax ? b1 : lmax;
        out->sum.upper_min[k] = umin;
        out->sum.upper_max[k] = umax;
        out->sum.lower_min[k] = lmin;
        out->sum.lower_max[k] = lmax;
    }
    /* Bits fp*3 + k: v < 0 or v > 1 is one unsigned compare. */
    TWO_STAGES_UNROLL
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        const it2n_val *v = &out->v[fp][IT2N_CH_T];
        uint32_t g = (uint32_t)((uint64_t)v[0] > (uint64_t)IT2N_VAL_ONE) |
                     (uint32_t)((uint64_t)v[1] > (uint64_t)IT2N_VAL_ONE) << 1 |
                     (uint32_t)((uint64_t)v[2] > (uint64_t)IT2N_VAL_ONE) << 2;
        oor |= g << (fp * 3u);
    }
    out->out_of_range = oor;
}

/* Common argument checks of the evaluation entry points. */
static int check_args(const it2n_model *mdl, it2n_par u, it2n_par w, it2n_errinfo *err)
{
    if (!mdl->solved) {
        return it2n__fail(err, IT2N_ERR_STATE, -1, -1, -1, -1, 0, 0, 0);
    }
    return it2n__check_uw(u, w, err);
}

/* Values of every footprint at (u, w) into v (no summary). */
static void eval_values(const it2n_model *mdl, it2n_par u, it2n_par w, it2n_val *v)
{
    int32_t bu[IT2N_DIM], bw[IT2N_DIM];
    unsigned bad;
#ifdef IT2N_VALUES_SSE2
    (void)bad;
    bases30(mdl, u, w, bu, bw);
    apply_values(mdl, it2n__fp_mask(mdl->flags), bu, bw, v);
#else
    it2n__basis30(mdl->n, u, bu);
    it2n__basis30(mdl->m, w, bw);
    if (!apply(mdl, it2n__fp_mask(mdl->flags), bu, 30, bw, 30, v, &bad)) {
        IT2N_ASSERT(false); /* convex weights: values are within the net */
    }
#endif
}

int it2n_eval(const it2n_model *mdl, it2n_par u, it2n_par w, it2n_point *out, it2n_errinfo *err)
{
    int rc;
    if (mdl == NULL || out == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = check_args(mdl, u, w, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    eval_values(mdl, u, w, &out->v[0][0]);
    it2n__summarise(mdl, out);
    return IT2N_OK;
}

int it2n__eval_full(const it2n_model *mdl, unsigned fpmask, it2n_par u, it2n_par w, it2n_val *v, it2n_val *du,
                    it2n_val *dw, it2n_errinfo *err)
{
    int32_t bu[IT2N_DIM], bw[IT2N_DIM], d[IT2N_DIM];
    unsigned bad = 0u;
    it2n__basis30(mdl->n, u, bu);
    it2n__basis30(mdl->m, w, bw);
    if (v != NULL) {
#ifdef IT2N_VALUES_SSE2
        apply_values(mdl, fpmask, bu, bw, v);
#else
        (void)apply(mdl, fpmask, bu, 30, bw, 30, v, &bad);
#endif
    }
    if (du != NULL) {
        dbasis26(mdl->n, u, d);
        if (!apply(mdl, fpmask, d, 26, bw, 30, du, &bad)) {
            goto overflow;
        }
    }
    if (dw != NULL) {
        dbasis26(mdl->m, w, d);
        if (!apply(mdl, fpmask, bu, 30, d, 26, dw, &bad)) {
            goto overflow;
        }
    }
    return IT2N_OK;
overflow:
    return it2n__fail(err, IT2N_ERR_OVERFLOW, -1, -1, (int)(bad >> 4), (int)(bad & 15u), 0, 0, 0);
}

int it2n_deriv(const it2n_model *mdl, it2n_par u, it2n_par w, it2n_point *du, it2n_point *dw, it2n_errinfo *err)
{
    int rc;
    if (mdl == NULL || du == NULL || dw == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = check_args(mdl, u, w, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    memset(du, 0, sizeof(*du));
    memset(dw, 0, sizeof(*dw));
    return it2n__eval_full(mdl, it2n__fp_mask(mdl->flags), u, w, NULL, &du->v[0][0], &dw->v[0][0], err);
}

/* Grid parameter k / (count - 1) in Q32. */
static it2n_par grid_par(unsigned k, unsigned count)
{
    uint64_t d = count - 1u;
    return (it2n_par)it2n__udiv64_32(((uint64_t)k << IT2N_PAR_FRAC) + d / 2u, (uint32_t)d);
}

int it2n__check_grid(unsigned rows, unsigned cols, it2n_errinfo *err)
{
    if (rows < 2u || rows > 65535u) {
        return it2n__fail(err, IT2N_ERR_RANGE, (int)(rows > 32767u ? 32767u : rows), -1, -1, -1, (it2n_val)rows, 2,
                          65535);
    }
    if (cols < 2u || cols > 65535u) {
        return it2n__fail(err, IT2N_ERR_RANGE, -1, (int)(cols > 32767u ? 32767u : cols), -1, -1, (it2n_val)cols, 2,
                          65535);
    }
    return IT2N_OK;
}

int it2n_sample(const it2n_model *mdl, unsigned rows, unsigned cols, it2n_sample_cb cb, void *ctx, it2n_errinfo *err)
{
    it2n_point pt;
    int32_t bu[IT2N_DIM], bw[IT2N_DIM];
    int32_t q[IT2N_FP_COUNT][IT2N_CH_COUNT][IT2N_DIM];
    unsigned r, c, mask, n1, m1;
    if (mdl == NULL || cb == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (!mdl->solved) {
        return it2n__fail(err, IT2N_ERR_STATE, -1, -1, -1, -1, 0, 0, 0);
    }
    if (it2n__check_grid(rows, cols, err) != IT2N_OK) {
        return IT2N_ERR_RANGE;
    }
    n1 = mdl->n + 1u;
    m1 = mdl->m + 1u;
    mask = it2n__fp_mask(mdl->flags);
    for (r = 0; r < rows; r++) {
        it2n_par u = grid_par(r, rows);
        unsigned fp, ch, i, j;
        /* Stage 1 depends on u only: once per row for every net, exactly as
         * it2n_eval computes it, so every node stays bit-identical. */
        it2n__basis30(n1 - 1u, u, bu);
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                const int32_t *net = mdl->net[fp][ch];
                for (j = 0; j < m1; j++) {
                    int64_t acc = 0;
                    for (i = 0; i < n1; i++) {
                        acc += it2n_smul32(bu[i], net[i * m1 + j]);
                    }
                    q[fp][ch][j] = (int32_t)((acc + ((int64_t)1 << 29)) >> 30);
                }
            }
        }
        for (c = 0; c < cols; c++) {
            it2n_par w = grid_par(c, cols);
            int stop;
            it2n__basis30(m1 - 1u, w, bw);
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    int64_t acc = 0;
                    if (!(mask & (1u << fp)) || !it2n__ch_used(mdl->flags, ch)) {
                        pt.v[fp][ch] = 0;
                        continue;
                    }
                    for (j = 0; j < m1; j++) {
                        acc += it2n_smul32(bw[j], q[fp][ch][j]);
                    }
                    /* a convex combination of the net: fits Q39.24 */
                    pt.v[fp][ch] = it2n__shift_round(acc, 30 + mdl->frac[fp][ch] - IT2N_VAL_FRAC);
                }
            }
            it2n__summarise(mdl, &pt);
            stop = cb(ctx, r, c, u, w, &pt);
            if (stop != 0) {
                return stop;
            }
        }
    }
    return IT2N_OK;
}
