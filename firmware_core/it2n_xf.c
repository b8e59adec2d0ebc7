/*
 * A tiny soft floating point for the few places that need range more than
 * speed: the chord-length inverse and locate's Newton step. Integer-only and
 * bit-reproducible on every target; see it2n_xf.h.
 */
#include "it2n_internal.h"
#include "it2n_xf.h"

#define XF_TOP ((int64_t)1 << 62)
#define XF_LOW ((int64_t)1 << 61)

void it2n__xf_set(it2n__xf *r, int64_t m, int32_t e)
{
    unsigned k;
    if (m == 0) {
        r->m = 0;
        r->e = 0;
        return;
    }
    /* |m| < 2^63: at most two rounding right shifts, 61 left shifts */
    for (k = 0; k < 2u && (m >= XF_TOP || m <= -XF_TOP); k++) {
        m = (m >> 1) + (m & 1); /* round half up */
        e++;
    }
    for (k = 0; k < 62u && m < XF_LOW && m > -XF_LOW; k++) {
        m = (int64_t)((uint64_t)m << 1);
        e--;
    }
    r->m = m;
    r->e = e;
}

void it2n__xf_mul(it2n__xf *r, const it2n__xf *a, const it2n__xf *b)
{
    int64_t p = 0;
    /* |a.m * b.m| < 2^124: / 2^62 fits */
    if (!it2n__i128_round(it2n__mul64(a->m, b->m), 62u, &p)) {
        IT2N_ASSERT(false);
    }
    it2n__xf_set(r, p, a->e + b->e + 62);
}

/* a + s b for s = +1 or -1 */
static void add_signed(it2n__xf *r, const it2n__xf *a, const it2n__xf *b, int s)
{
    int64_t am = a->m, bm = s < 0 ? -b->m : b->m;
    int32_t ae = a->e, be = b->e, d;
    if (bm == 0 || am == 0) {
        it2n__xf_set(r, am == 0 ? bm : am, am == 0 ? be : ae);
        return;
    }
    if (ae < be) {
        int64_t tm = am;
        int32_t te = ae;
        am = bm;
        ae = be;
        bm = tm;
        be = te;
    }
    d = ae - be;
    /* b below a's last bit beyond 63 places */
    it2n__xf_set(r, am + (d > 63 ? 0 : it2n__shift_round(bm, (int)d)), ae);
}

void it2n__xf_add(it2n__xf *r, const it2n__xf *a, const it2n__xf *b)
{
    add_signed(r, a, b, 1);
}

void it2n__xf_sub(it2n__xf *r, const it2n__xf *a, const it2n__xf *b)
{
    add_signed(r, a, b, -1);
}

void it2n__xf_div(it2n__xf *r, const it2n__xf *a, const it2n__xf *b)
{
    int64_t q = 0;
    if (a->m != 0) {
        /* |a.m|, |b.m| in [2^61, 2^62): |a.m| 2^62 / |b.m| in (2^61, 2^63) */
        uint64_t am = (uint64_t)(a->m < 0 ? -a->m : a->m);
        uint64_t bm = (uint64_t)(b->m < 0 ? -b->m : b->m);
        q = (int64_t)it2n__div_round(am, bm, 62u);
        q = (a->m < 0) != (b->m < 0) ? -q : q;
    }
    it2n__xf_set(r, q, a->e - b->e - 62);
}

bool it2n__xf_abs_lt(const it2n__xf *a, const it2n__xf *b)
{
    int64_t am = a->m < 0 ? -a->m : a->m, bm = b->m < 0 ? -b->m : b->m;
    if (am == 0 || bm == 0) {
        return am < bm;
    }
    return a->e != b->e ? a->e < b->e : am < bm;
}

int64_t it2n__xf_to_q32(const it2n__xf *a)
{
    int s = -(a->e + IT2N_PAR_FRAC);
    if (a->m == 0) {
        return 0;
    }
    if (s < 0) {
        /* |a| >= 2^30: beyond any parameter step a caller accepts */
        return a->m < 0 ? -((int64_t)1 << 62) : ((int64_t)1 << 62);
    }
    return it2n__shift_round(a->m, s);
}
