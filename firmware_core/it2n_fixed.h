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
#else
#define IT2N_WUR
#endif

/* Two's complement 128-bit integer: value = hi * 2^64 + lo, hi signed. */
typedef struct it2n_i128 {
    uint64_t lo;
    uint64_t hi;
} it2n_i128;

/* C99 static assertion: a negative array size fails the build. */
#define IT2N_STATIC_ASSERT(cond, name) typedef char it2n_sa_##name[(cond) ? 1 : -1]

IT2N_STATIC_ASSERT(sizeof(it2n_i128) == 16, i128_is_two_words);
IT2N_STATIC_ASSERT(sizeof(int64_t) == 8 && (int64_t)-1 == ~(int64_t)0,
                   twos_complement_int64);

/* Zero. */
static inline it2n_i128 it2n_i128_zero(void)
{
    it2n_i128 r = {0u, 0u};
    return r;
}

/* Sign-extend an int64. */
static inline it2n_i128 it2n_i128_from(int64_t v)
{
    it2n_i128 r;
    r.lo = (uint64_t)v;
    r.hi = v < 0 ? UINT64_MAX : 0u;
    return r;
}

/* a + b (wraps only beyond 2^127, which no caller can reach). */
static inline it2n_i128 it2n_i128_add(it2n_i128 a, it2n_i128 b)
{
    it2n_i128 r;
    r.lo = a.lo + b.lo;
    r.hi = a.hi + b.hi + (r.lo < a.lo ? 1u : 0u);
    return r;
}

/* -a */
static inline it2n_i128 it2n_i128_neg(it2n_i128 a)
{
    it2n_i128 r;
    r.lo = ~a.lo + 1u;
    r.hi = ~a.hi + (r.lo == 0u ? 1u : 0u);
    return r;
}

/* a - b */
static inline it2n_i128 it2n_i128_sub(it2n_i128 a, it2n_i128 b)
{
    return it2n_i128_add(a, it2n_i128_neg(b));
}

/* True when a < 0. */
static inline bool it2n_i128_neg_p(it2n_i128 a)
{
    return (a.hi >> 63) != 0u;
}

/* Exact signed product a * b. */
it2n_i128 it2n_mul64(int64_t a, int64_t b);

/* acc + a * b */
static inline it2n_i128 it2n_mac(it2n_i128 acc, int64_t a, int64_t b)
{
    return it2n_i128_add(acc, it2n_mul64(a, b));
}

/*
 * round(a / 2^shift) to nearest (ties toward +inf), 1 <= shift <= 126.
 * Stores it in *out and returns true when it fits in int64; false otherwise
 * (*out untouched).
 */
bool it2n_i128_round(it2n_i128 a, unsigned shift, int64_t *out) IT2N_WUR;

/*
 * round(num / den) to nearest, den != 0. Returns false (and leaves *out) when
 * the quotient does not fit in int64 or den == 0.
 */
bool it2n_i128_div(it2n_i128 num, it2n_i128 den, int64_t *out) IT2N_WUR;

/* num * 2^shift as 128-bit (shift <= 62, |num| < 2^63). */
it2n_i128 it2n_i128_shl(int64_t num, unsigned shift);

/* Compare |a| <= |b|. */
bool it2n_i128_abs_le(it2n_i128 a, it2n_i128 b);

/* floor(sqrt(a)) for a >= 0 (fits in 64 bits). */
uint64_t it2n_i128_isqrt(it2n_i128 a);

/* round(a / 2^shift) where the caller has proved the result fits
 * (convex combinations, basis values); saturates rather than wraps if not. */
int64_t it2n_i128_round_fit(it2n_i128 a, unsigned shift);

/* round(a * b / 2^shift), a and b int64; false on overflow. */
static inline bool IT2N_WUR it2n_mul_shift(int64_t a, int64_t b,
                                           unsigned shift, int64_t *out)
{
    return it2n_i128_round(it2n_mul64(a, b), shift, out);
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
