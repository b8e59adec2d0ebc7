/*
 * A tiny soft floating point for the few places that need range more than
 * speed: the chord-length inverse and locate's Newton step. Integer-only and
 * bit-reproducible on every target; see it2n_xf.h.
 */
#include "it2n_internal.h"
#include "it2n_xf.h"


#define XF_TOP ((int64_t)1 << 62)
#define XF_LOW ((int64_t)1 << 61)

xf xf_norm(int64_t m, int32_t e)
{
    xf r;
    unsigned k;
    if (m == 0) {
        r.m = 0;
        r.e = 0;
        return r;
    }
    /* |m| < 2^63: at most two rounding right shifts, 61 left shifts */
    for (k = 0; k < 2u && (m >= XF_TOP || m <= -XF_TOP); k++) {
        m = (m >> 1) + (m & 1); /* round half up */
        e++;
    }
    for (k = 0; k < 62u && m < XF_LOW && m > -XF_LOW; k++) {
        m *= 2;
        e--;
    }
    r.m = m;
    r.e = e;
    return r;
}

xf xf_mul(xf a, xf b)
{
    int64_t p;
    if (a.m == 0 || b.m == 0) {
        return xf_norm(0, 0);
    }
    /* |a.m * b.m| < 2^124: / 2^62 fits */
    if (!it2n_i128_round(it2n_mul64(a.m, b.m), 62u, &p)) {
        IT2N_ASSERT(false);
    }
    return xf_norm(p, a.e + b.e + 62);
}

xf xf_add(xf a, xf b)
{
    int32_t d;
    if (b.m == 0) {
        return a;
    }
    if (a.m == 0) {
        return b;
    }
    if (a.e < b.e) {
        xf t = a;
        a = b;
        b = t;
    }
    d = a.e - b.e;
    if (d > 63) {
        return a; /* b below a's last bit */
    }
    return xf_norm(a.m + it2n__shift_round(b.m, (int)d), a.e);
}

xf xf_neg(xf a)
{
    a.m = -a.m;
    return a;
}

/* a / b, b != 0 */
xf xf_div(xf a, xf b)
{
    int64_t q;
    if (a.m == 0) {
        return a;
    }
    /* |a.m| 2^62 / |b.m| lies in (2^61, 2^63) */
    if (!it2n_i128_div(it2n_i128_shl(a.m, 62u), it2n_i128_from(b.m), &q)) {
        IT2N_ASSERT(false);
    }
    return xf_norm(q, a.e - b.e - 62);
}

/* |a| < |b| */
bool xf_abs_lt(xf a, xf b)
{
    int64_t am = a.m < 0 ? -a.m : a.m, bm = b.m < 0 ? -b.m : b.m;
    if (am == 0 || bm == 0) {
        return am < bm;
    }
    return a.e != b.e ? a.e < b.e : am < bm;
}

xf xf_abs(xf a)
{
    a.m = a.m < 0 ? -a.m : a.m;
    return a;
}

/* a as Q32 fixed point, clamped to +-2^62 (callers clamp further). */
int64_t xf_to_q32(xf a)
{
    int s = -(a.e + IT2N_PAR_FRAC);
    if (a.m == 0) {
        return 0;
    }
    if (s < 0) {
        /* |a| >= 2^30: beyond any parameter step a caller accepts */
        return a.m < 0 ? -((int64_t)1 << 62) : ((int64_t)1 << 62);
    }
    return it2n__shift_round(a.m, s);
}
