/*
 * 128-bit integer arithmetic for the fixed-point core (see it2n_fixed.h).
 */
#include "it2n_fixed.h"

#include "it2n.h"

/* the one out-of-line copy of it2n__shift_round (ARMv6-M) */
#define IT2N__SHIFT_ROUND_HERE
#include "it2n_internal.h"

/* Unsigned 64 x 64 -> 128 from four 32 x 32 -> 64 products. */
static it2n_i128 umul64(uint64_t a, uint64_t b)
{
    const uint64_t m32 = 0xFFFFFFFFu;
    uint32_t a0 = (uint32_t)a, a1 = (uint32_t)(a >> 32);
    uint32_t b0 = (uint32_t)b, b1 = (uint32_t)(b >> 32);
    uint64_t p00 = it2n_umul32(a0, b0), p01 = it2n_umul32(a0, b1);
    uint64_t p10 = it2n_umul32(a1, b0), p11 = it2n_umul32(a1, b1);
    uint64_t mid = (p00 >> 32) + (p01 & m32) + (p10 & m32);
    it2n_i128 r;
    r.lo = (mid << 32) | (p00 & m32);
    r.hi = p11 + (p01 >> 32) + (p10 >> 32) + (mid >> 32);
    return r;
}

/* |v| as unsigned, valid for INT64_MIN too. */
static uint64_t uabs64(int64_t v)
{
    return v < 0 ? (uint64_t)(-(v + 1)) + 1u : (uint64_t)v;
}

uint64_t it2n__udiv64_32(uint64_t n, uint32_t d)
{
    uint64_t q = 0u, r = 0u;
    unsigned k;
    for (k = 64u; k-- > 0u;) {
        r = (r << 1) | ((n >> k) & 1u);
        q <<= 1;
        if (r >= d) {
            r -= d;
            q |= 1u;
        }
    }
    return q;
}

uint64_t it2n__div_round(uint64_t num, uint64_t den, unsigned bits)
{
    uint64_t q = 0u, r = num;
    unsigned k;
    if (r >= den) { /* num < 2 den: one integer bit */
        r -= den;
        q = 1u;
    }
    for (k = 0; k < bits; k++) { /* r < den < 2^62: 2r fits */
        r <<= 1;
        q <<= 1;
        if (r >= den) {
            r -= den;
            q |= 1u;
        }
    }
    return q + (r << 1 >= den ? 1u : 0u); /* half away from zero */
}

unsigned it2n__bitlen64(uint64_t v)
{
    unsigned k = 0;
    if (v >> 32) {
        v >>= 32;
        k = 32u;
    }
    while (v != 0u) { /* at most 32 steps */
        v >>= 1;
        k++;
    }
    return k;
}

it2n_i128 it2n__mul64(int64_t a, int64_t b)
{
    it2n_i128 r;
#if IT2N_HAVE_INT128
    it2n__u128 p = (it2n__u128)((it2n__s128)a * b);
    r.lo = (uint64_t)p;
    r.hi = (uint64_t)(p >> 64);
#else
    uint64_t ua = (uint64_t)a, ub = (uint64_t)b;
    r = umul64(ua, ub);
    /* unsigned product -> signed: subtract the other operand where one is
     * negative (mod 2^128, only the high word changes) */
    r.hi -= a < 0 ? ub : 0u;
    r.hi -= b < 0 ? ua : 0u;
#endif
    return r;
}

/* Logical right shift of a 128-bit pattern, 0 < s < 128. */
static it2n_i128 ushr(it2n_i128 a, unsigned s)
{
    it2n_i128 r;
    if (s >= 64u) {
        r.lo = a.hi >> (s - 64u);
        r.hi = 0u;
    } else {
        r.lo = (a.lo >> s) | (a.hi << (64u - s));
        r.hi = a.hi >> s;
    }
    return r;
}

/* Arithmetic right shift, 0 < s < 128: floor(a / 2^s). */
static it2n_i128 ashr(it2n_i128 a, unsigned s)
{
    it2n_i128 r = ushr(a, s);
    if (it2n__i128_neg_p(a)) {
        if (s >= 64u) {
            r.hi = UINT64_MAX;
            r.lo |= s > 64u ? UINT64_MAX << (128u - s) : 0u;
        } else {
            r.hi |= UINT64_MAX << (64u - s);
        }
    }
    return r;
}

/* The 128-bit value as int64 when it fits. */
static bool fits64(it2n_i128 a, int64_t *out)
{
    const uint64_t top = (uint64_t)1u << 63;
    if (a.hi == 0u && a.lo < top) {
        *out = (int64_t)a.lo;
        return true;
    }
    if (a.hi == UINT64_MAX && a.lo >= top) {
        *out = -(int64_t)(~a.lo) - 1; /* portable two's complement */
        return true;
    }
    return false;
}

bool it2n__i128_round(it2n_i128 a, unsigned shift, int64_t *out)
{
    it2n_i128 half = {0u, 0u};
    if (shift == 0u || shift > 126u) {
        return false;
    }
    if (shift > 64u) {
        half.hi = (uint64_t)1u << (shift - 65u);
    } else {
        half.lo = (uint64_t)1u << (shift - 1u);
    }
    return fits64(ashr(it2n__i128_add(a, half), shift), out);
}

int64_t it2n__i128_round_fit(it2n_i128 a, unsigned shift)
{
    int64_t r;
    bool ok = it2n__i128_round(a, shift, &r);
    IT2N_ASSERT(ok); /* callers proved the result fits */
    if (!ok) {
        r = it2n__i128_neg_p(a) ? INT64_MIN : INT64_MAX;
    }
    return r;
}

it2n_i128 it2n__i128_shl(int64_t num, unsigned shift)
{
    uint64_t m = uabs64(num);
    it2n_i128 r;
    r.lo = m << shift;
    r.hi = shift ? m >> (64u - shift) : 0u;
    return num < 0 ? it2n__i128_neg(r) : r;
}

static int ucmp(it2n_i128 a, it2n_i128 b)
{
    if (a.hi != b.hi) {
        return a.hi < b.hi ? -1 : 1;
    }
    if (a.lo != b.lo) {
        return a.lo < b.lo ? -1 : 1;
    }
    return 0;
}

static it2n_i128 uabs128(it2n_i128 a)
{
    return it2n__i128_neg_p(a) ? it2n__i128_neg(a) : a;
}

bool it2n__i128_abs_le(it2n_i128 a, it2n_i128 b)
{
    return ucmp(uabs128(a), uabs128(b)) <= 0;
}

bool it2n__i128_div(it2n_i128 num, it2n_i128 den, int64_t *out)
{
    /* Restoring binary long division on magnitudes: 128 fixed steps. */
    bool neg = it2n__i128_neg_p(num) != it2n__i128_neg_p(den);
    it2n_i128 n = uabs128(num), d = uabs128(den);
    it2n_i128 q = {0u, 0u}, r = {0u, 0u}, twice;
    unsigned k;
    if (d.lo == 0u && d.hi == 0u) {
        return false;
    }
    for (k = 128u; k-- > 0u;) {
        uint64_t bit = k >= 64u ? (n.hi >> (k - 64u)) & 1u : (n.lo >> k) & 1u;
        /* r fits in 127 bits because r < d <= 2^127 */
        r.hi = (r.hi << 1) | (r.lo >> 63);
        r.lo = (r.lo << 1) | bit;
        q.hi = (q.hi << 1) | (q.lo >> 63);
        q.lo <<= 1;
        if (ucmp(r, d) >= 0) {
            r = it2n__i128_sub(r, d);
            q.lo |= 1u;
        }
    }
    /* round half away from zero: 2r >= d */
    twice.hi = (r.hi << 1) | (r.lo >> 63);
    twice.lo = r.lo << 1;
    if ((r.hi >> 63) != 0u || ucmp(twice, d) >= 0) {
        q = it2n__i128_add(q, it2n__i128_from(1));
    }
    if (neg) {
        q = it2n__i128_neg(q);
    }
    return fits64(q, out);
}

uint64_t it2n__i128_isqrt(it2n_i128 a)
{
    /* Bitwise square root: 64 fixed steps, result bit by bit from the top. */
    uint64_t res = 0u;
    unsigned k;
    if (it2n__i128_neg_p(a)) {
        return 0u;
    }
    for (k = 64u; k-- > 0u;) {
        uint64_t cand = res | ((uint64_t)1u << k);
        it2n_i128 sq = umul64(cand, cand);
        if (ucmp(sq, a) <= 0) {
            res = cand;
        }
    }
    return res;
}
