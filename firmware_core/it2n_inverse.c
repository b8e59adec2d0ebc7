/*
 * Run-time inverse of a collocation matrix (chord-length parameters; the
 * uniform ones are exact tables, it2n_uniform_inv.c).
 *
 * The inverse can amplify by 10^5 and more, and control nets must be right
 * to 10^-6 of their range, so the elimination runs in a tiny soft floating
 * point: a 62-bit mantissa and a binary exponent (unit roundoff 2^-62). It
 * is integer-only and exactly reproducible on every target. Used O(n^3)
 * times per solve, never per evaluation.
 */
#include "it2n_internal.h"

/* value = m * 2^e, |m| in [2^61, 2^62) or m == 0. */
typedef struct xf {
    int64_t m;
    int32_t e;
} xf;

#define XF_TOP ((int64_t)1 << 62)
#define XF_LOW ((int64_t)1 << 61)

static xf xf_norm(int64_t m, int32_t e)
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

static xf xf_mul(xf a, xf b)
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

static xf xf_add(xf a, xf b)
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

static xf xf_neg(xf a)
{
    a.m = -a.m;
    return a;
}

/* a / b, b != 0 */
static xf xf_div(xf a, xf b)
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
static bool xf_abs_lt(xf a, xf b)
{
    int64_t am = a.m < 0 ? -a.m : a.m, bm = b.m < 0 ? -b.m : b.m;
    if (am == 0 || bm == 0) {
        return am < bm;
    }
    return a.e != b.e ? a.e < b.e : am < bm;
}

static xf xf_abs(xf a)
{
    a.m = a.m < 0 ? -a.m : a.m;
    return a;
}

/* Bernstein basis of degree deg at Q32 parameter t, by de Casteljau. */
static void basis_xf(unsigned deg, it2n_par t, xf b[IT2N_DIM])
{
    xf tx = xf_norm(t, -IT2N_PAR_FRAC);
    xf sx = xf_norm(IT2N_PAR_ONE - t, -IT2N_PAR_FRAC);
    unsigned k, i;
    b[0] = xf_norm(1, 0);
    for (k = 1; k <= deg; k++) {
        b[k] = xf_mul(tx, b[k - 1u]);
        for (i = k - 1u; i >= 1u; i--) {
            b[i] = xf_add(xf_mul(sx, b[i]), xf_mul(tx, b[i - 1u]));
        }
        b[0] = xf_mul(sx, b[0]);
    }
}

int it2n__invert(unsigned deg, const it2n_par t[IT2N_DIM],
                 int32_t hi[IT2N_DIM * IT2N_DIM],
                 int32_t lo[IT2N_DIM * IT2N_DIM], int *frac,
                 it2n_errinfo *err)
{
    xf a[IT2N_DIM][IT2N_DIM], rowmax;
    unsigned char perm[IT2N_DIM];
    unsigned n = deg + 1u, r, c, k;
    /* Pivots below 2^-24: the parameters (nearly) coincide. */
    const xf tiny = xf_norm(1, -24);
    for (r = 0; r < n; r++) {
        basis_xf(deg, t[r], a[r]);
    }
    /* In-place Gauss-Jordan with partial pivoting (row swaps recorded and
     * undone on the columns at the end). */
    for (k = 0; k < n; k++) {
        unsigned piv = k;
        xf p;
        for (r = k + 1u; r < n; r++) {
            if (xf_abs_lt(a[piv][k], a[r][k])) {
                piv = r;
            }
        }
        perm[k] = (unsigned char)piv;
        if (xf_abs_lt(a[piv][k], tiny)) {
            return it2n__fail(err, IT2N_ERR_SINGULAR, -1, -1, -1, -1, 0, 0, 0);
        }
        if (piv != k) {
            for (c = 0; c < n; c++) {
                xf tmp = a[k][c];
                a[k][c] = a[piv][c];
                a[piv][c] = tmp;
            }
        }
        p = a[k][k];
        a[k][k] = xf_norm(1, 0);
        for (c = 0; c < n; c++) {
            a[k][c] = xf_div(a[k][c], p);
        }
        for (r = 0; r < n; r++) {
            xf f = a[r][k];
            if (r == k || f.m == 0) {
                continue;
            }
            a[r][k] = xf_norm(0, 0);
            for (c = 0; c < n; c++) {
                a[r][c] = xf_add(a[r][c], xf_neg(xf_mul(f, a[k][c])));
            }
        }
    }
    for (k = n; k-- > 0u;) {
        if (perm[k] != k) {
            for (r = 0; r < n; r++) {
                xf tmp = a[r][k];
                a[r][k] = a[r][perm[k]];
                a[r][perm[k]] = tmp;
            }
        }
    }
    /* Scale: largest row absolute sum < 2^(62 + e), so 2^(-8 - e) keeps
     * every rounded row sum below 2^55. */
    rowmax = xf_norm(0, 0);
    for (r = 0; r < n; r++) {
        xf s = xf_norm(0, 0);
        for (c = 0; c < n; c++) {
            s = xf_add(s, xf_abs(a[r][c]));
        }
        if (xf_abs_lt(rowmax, s)) {
            rowmax = s;
        }
    }
    *frac = -8 - rowmax.e;
    if (*frac < 0 || *frac > 61) {
        return it2n__fail(err, IT2N_ERR_OVERFLOW, -1, -1, -1, -1, 0, 0, 0);
    }
    for (r = 0; r < n; r++) {
        for (c = 0; c < n; c++) {
            /* an entry's exponent is at most rowmax.e, so this is a right
             * shift by 8 or more */
            int64_t q = it2n__shift_round(a[r][c].m, -(a[r][c].e + *frac));
            hi[r * n + c] = (int32_t)(q >> 24);
            lo[r * n + c] = (int32_t)(q & 0xFFFFFF);
        }
    }
    return IT2N_OK;
}
