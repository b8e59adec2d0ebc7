/*
 * Internal: 128-bit integer helpers and fixed-point primitives.
 *
 * C99 has no 128-bit type and Cortex-M GCC has no __int128, so products of
 * two int64 values are kept in a two-word struct. Everything here is exact
 * or rounds to nearest once, and reports overflow instead of wrapping.
 */
#ifndef IT2N_FIXED_H
#define IT2N_FIXED_H

#include <stdbool.h>
#include <stdint.h>

#if defined(__GNUC__)
#define IT2N_WUR __attribute__((warn_unused_result))
#define IT2N_INLINE static inline __attribute__((always_inline))
#else
#define IT2N_WUR
#define IT2N_INLINE static inline
#endif

/* ARMv6-M (Cortex-M0/M0+) and ARMv8-M Baseline have only MULS (32x32->32):
 * a 64-bit product there is built inline from 16-bit halves instead of the
 * generic libgcc helper (__aeabi_lmul, ~10x slower). */
#if defined(__ARM_ARCH_6M__) || defined(__ARM_ARCH_8M_BASE__)
#define IT2N_MUL_HALVES 1
#else
#define IT2N_MUL_HALVES 0
#endif

/* Hosts with a native 128-bit type use it for the exact solve products. The
 * arithmetic is exact either way, so results are bit-identical. */
#if defined(__SIZEOF_INT128__) && !defined(IT2N_NO_INT128)
#define IT2N_HAVE_INT128 1
__extension__ typedef __int128 it2n__s128;
__extension__ typedef unsigned __int128 it2n__u128;
#else
#define IT2N_HAVE_INT128 0
#endif

/* Unsigned 32 x 32 -> 64. */
IT2N_INLINE uint64_t it2n_umul32(uint32_t a, uint32_t b)
{
#if IT2N_MUL_HALVES
    uint32_t al = a & 0xFFFFu, ah = a >> 16, bl = b & 0xFFFFu, bh = b >> 16;
    uint32_t ll = al * bl, lh = al * bh, hl = ah * bl, hh = ah * bh;
    uint32_t mid = lh + hl;
    uint32_t lo = ll + (mid << 16);
    uint32_t hi = hh + (mid >> 16) + (mid < lh ? 0x10000u : 0u) + (lo < ll ? 1u : 0u);
    return ((uint64_t)hi << 32) | lo;
#else
    return (uint64_t)a * b;
#endif
}

/* Signed 32 x unsigned 32 -> 64 (b < 2^31 in every caller). */
IT2N_INLINE int64_t it2n_mul32su(int32_t a, uint32_t b)
{
#if IT2N_MUL_HALVES
    uint64_t p = it2n_umul32((uint32_t)a, b);
    uint32_t hi = (uint32_t)(p >> 32) - (a < 0 ? b : 0u);
    return (int64_t)(((uint64_t)hi << 32) | (uint32_t)p);
#else
    return (int64_t)a * (int64_t)b;
#endif
}

/* Signed 32 x 32 -> 64 (one SMULL on ARMv7-M). */
IT2N_INLINE int64_t it2n_smul32(int32_t a, int32_t b)
{
#if IT2N_MUL_HALVES
    uint64_t p = it2n_umul32((uint32_t)a, (uint32_t)b);
    uint32_t hi = (uint32_t)(p >> 32);
    /* two's complement correction of the unsigned product's high word */
    hi -= a < 0 ? (uint32_t)b : 0u;
    hi -= b < 0 ? (uint32_t)a : 0u;
    return (int64_t)(((uint64_t)hi << 32) | (uint32_t)p);
#else
    return (int64_t)a * b;
#endif
}

/* Two's complement 128-bit integer: value = hi * 2^64 + lo, hi signed. */
typedef struct it2n_i128 {
    uint64_t lo;
    uint64_t hi;
} it2n_i128;

/* C99 static assertion: a negative array size fails the build. */
#define IT2N_STATIC_ASSERT(cond, name) typedef char it2n_sa_##name[(cond) ? 1 : -1]

IT2N_STATIC_ASSERT(sizeof(it2n_i128) == 16, i128_is_two_words);
IT2N_STATIC_ASSERT(sizeof(int64_t) == 8 && (int64_t)-1 == ~(int64_t)0, twos_complement_int64);
/* >> of a negative value is arithmetic (GCC, Clang, IAR, armcc all do so). */
IT2N_STATIC_ASSERT(((int64_t)-5 >> 1) == -3 && ((int32_t)-5 >> 1) == -3, arithmetic_right_shift);

/* Zero. */
static inline it2n_i128 it2n__i128_zero(void)
{
    it2n_i128 r = {0u, 0u};
    return r;
}

/* Sign-extend an int64. */
static inline it2n_i128 it2n__i128_from(int64_t v)
{
    it2n_i128 r;
    r.lo = (uint64_t)v;
    r.hi = v < 0 ? UINT64_MAX : 0u;
    return r;
}

/* a + b (wraps only beyond 2^127, which no caller can reach). */
static inline it2n_i128 it2n__i128_add(it2n_i128 a, it2n_i128 b)
{
    it2n_i128 r;
    r.lo = a.lo + b.lo;
    r.hi = a.hi + b.hi + (r.lo < a.lo ? 1u : 0u);
    return r;
}

/* -a */
static inline it2n_i128 it2n__i128_neg(it2n_i128 a)
{
    it2n_i128 r;
    r.lo = ~a.lo + 1u;
    r.hi = ~a.hi + (r.lo == 0u ? 1u : 0u);
    return r;
}

/* a - b */
static inline it2n_i128 it2n__i128_sub(it2n_i128 a, it2n_i128 b)
{
    return it2n__i128_add(a, it2n__i128_neg(b));
}

/* True when a < 0. */
static inline bool it2n__i128_neg_p(it2n_i128 a)
{
    return (a.hi >> 63) != 0u;
}

/* Exact signed product a * b, from four 32 x 32 -> 64 products (out of
 * line: used by locate, chord parameters and the soft float, never in the
 * per-point loops). */
it2n_i128 it2n__mul64(int64_t a, int64_t b);

/* acc + a * b */
IT2N_INLINE it2n_i128 it2n_mac(it2n_i128 acc, int64_t a, int64_t b)
{
    return it2n__i128_add(acc, it2n__mul64(a, b));
}

/* *acc += a * b in place (no struct return: cheaper at -Os). */
IT2N_INLINE void it2n_mac128(it2n_i128 *acc, int64_t a, int64_t b)
{
    it2n_i128 p = it2n__mul64(a, b);
    uint64_t lo = acc->lo + p.lo;
    acc->hi += p.hi + (lo < p.lo ? 1u : 0u);
    acc->lo = lo;
}

/* floor(n / d) for d != 0, by 64 shift-subtract steps: no 64-bit division
 * helper from libgcc on parts without a divider (used outside hot loops). */
uint64_t it2n__udiv64_32(uint64_t n, uint32_t d);

/* round(num 2^bits / den) for den < 2^62 and num < 2 den: bits + 1
 * shift-subtract steps in 64-bit words (the soft float's division and the
 * chord parameters; no 128-bit division). */
uint64_t it2n__div_round(uint64_t num, uint64_t den, unsigned bits);

/* round(k 2^32 / d), k <= d (uniform parameters). */
static inline uint64_t it2n__udiv_round(unsigned k, unsigned d)
{
    return it2n__udiv64_32(((uint64_t)k << 32) + d / 2u, d);
}

/* Number of significant bits of v (0 for 0). */
unsigned it2n__bitlen64(uint64_t v);

/*
 * round(a / 2^shift) to nearest (ties toward +inf), 1 <= shift <= 126.
 * Stores it in *out and returns true when it fits in int64; false otherwise
 * (*out untouched).
 */
bool it2n__i128_round(it2n_i128 a, unsigned shift, int64_t *out) IT2N_WUR;

/*
 * round(num / den) to nearest, den != 0. Returns false (and leaves *out) when
 * the quotient does not fit in int64 or den == 0.
 */
bool it2n__i128_div(it2n_i128 num, it2n_i128 den, int64_t *out) IT2N_WUR;

/* num * 2^shift as 128-bit (shift <= 62, |num| < 2^63). */
it2n_i128 it2n__i128_shl(int64_t num, unsigned shift);

/* Compare |a| <= |b|. */
bool it2n__i128_abs_le(it2n_i128 a, it2n_i128 b);

/* floor(sqrt(a)) for a >= 0 (fits in 64 bits). */
uint64_t it2n__i128_isqrt(it2n_i128 a);

/* round(a / 2^shift) where the caller has proved the result fits
 * (convex combinations, basis values); saturates rather than wraps if not. */
int64_t it2n__i128_round_fit(it2n_i128 a, unsigned shift);

/* round(a * b / 2^shift), a and b int64; false on overflow. */
static inline bool IT2N_WUR it2n_mul_shift(int64_t a, int64_t b, unsigned shift, int64_t *out)
{
    return it2n__i128_round(it2n__mul64(a, b), shift, out);
}

/* a + b without wrap; false on overflow. */
static inline bool IT2N_WUR it2n_add_ok(int64_t a, int64_t b, int64_t *out)
{
    if ((b > 0 && a > INT64_MAX - b) || (b < 0 && a < INT64_MIN - b)) {
        return false;
    }
    *out = a + b;
    return true;
}

/* a - b without wrap; false on overflow. */
static inline bool IT2N_WUR it2n_sub_ok(int64_t a, int64_t b, int64_t *out)
{
    if ((b < 0 && a > INT64_MAX + b) || (b > 0 && a < INT64_MIN + b)) {
        return false;
    }
    *out = a - b;
    return true;
}

#endif /* IT2N_FIXED_H */
