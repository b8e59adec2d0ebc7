/*
 * Run-time inverse of a collocation matrix (chord-length parameters; the
 * uniform ones are exact tables, it2n_uniform_inv.c).
 *
 * The inverse can amplify by 10^5 and more, and control nets must be right
 * to 10^-6 of their range, so the elimination runs in the core's tiny soft
 * floating point (it2n_xf.c: 62-bit mantissa, unit roundoff 2^-62), which is
 * integer-only and exactly reproducible on every target. O(n^3) per solve,
 * never per evaluation.
 */
#include "it2n_internal.h"
#include "it2n_xf.h"

#if IT2N_CHORD

/* Bernstein basis of degree deg at Q32 parameter t, by de Casteljau. */
static void basis_xf(unsigned deg, it2n_par t, it2n__xf b[IT2N_DIM])
{
    it2n__xf tx, sx, p, q;
    unsigned k, i;
    it2n__xf_set(&tx, t, -IT2N_PAR_FRAC);
    it2n__xf_set(&sx, IT2N_PAR_ONE - t, -IT2N_PAR_FRAC);
    it2n__xf_set(&b[0], 1, 0);
    for (k = 1; k <= deg; k++) {
        it2n__xf_mul(&b[k], &tx, &b[k - 1u]);
        for (i = k - 1u; i >= 1u; i--) {
            it2n__xf_mul(&p, &sx, &b[i]);
            it2n__xf_mul(&q, &tx, &b[i - 1u]);
            it2n__xf_add(&b[i], &p, &q);
        }
        it2n__xf_mul(&b[0], &sx, &b[0]);
    }
}

static void swap_xf(it2n__xf *a, it2n__xf *b)
{
    it2n__xf t = *a;
    *a = *b;
    *b = t;
}

int it2n__invert(unsigned deg, const it2n_par t[IT2N_DIM], int32_t hi[IT2N_DIM * IT2N_DIM],
                 int32_t lo[IT2N_DIM * IT2N_DIM], int *frac, it2n_errinfo *err)
{
    it2n__xf a[IT2N_DIM][IT2N_DIM], rowmax, tiny, p, f, s;
    unsigned char perm[IT2N_DIM];
    unsigned n = deg + 1u, r, c, k;
    /* Pivots below 2^-24: the parameters (nearly) coincide. */
    it2n__xf_set(&tiny, 1, -24);
    for (r = 0; r < n; r++) {
        basis_xf(deg, t[r], a[r]);
    }
    /* In-place Gauss-Jordan with partial pivoting (row swaps recorded and
     * undone on the columns at the end). */
    for (k = 0; k < n; k++) {
        unsigned piv = k;
        for (r = k + 1u; r < n; r++) {
            if (it2n__xf_abs_lt(&a[piv][k], &a[r][k])) {
                piv = r;
            }
        }
        perm[k] = (unsigned char)piv;
        if (it2n__xf_abs_lt(&a[piv][k], &tiny)) {
            return it2n__fail(err, IT2N_ERR_SINGULAR, -1, -1, -1, -1, 0, 0, 0);
        }
        for (c = 0; c < n && piv != k; c++) {
            swap_xf(&a[k][c], &a[piv][c]);
        }
        p = a[k][k];
        it2n__xf_set(&a[k][k], 1, 0);
        for (c = 0; c < n; c++) {
            it2n__xf_div(&a[k][c], &a[k][c], &p);
        }
        for (r = 0; r < n; r++) {
            f = a[r][k];
            if (r == k || f.m == 0) {
                continue;
            }
            it2n__xf_set(&a[r][k], 0, 0);
            for (c = 0; c < n; c++) {
                it2n__xf_mul(&s, &f, &a[k][c]);
                it2n__xf_sub(&a[r][c], &a[r][c], &s);
            }
        }
    }
    for (k = n; k-- > 0u;) {
        for (r = 0; r < n && perm[k] != k; r++) {
            swap_xf(&a[r][k], &a[r][perm[k]]);
        }
    }
    /* Scale: largest row absolute sum < 2^(62 + e), so 2^(-8 - e) keeps
     * every rounded row sum below 2^55. */
    it2n__xf_set(&rowmax, 0, 0);
    for (r = 0; r < n; r++) {
        it2n__xf_set(&s, 0, 0);
        for (c = 0; c < n; c++) {
            it2n__xf e = a[r][c];
            e.m = e.m < 0 ? -e.m : e.m;
            it2n__xf_add(&s, &s, &e);
        }
        if (it2n__xf_abs_lt(&rowmax, &s)) {
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
#else
/* ISO C wants at least one declaration in a translation unit. */
typedef int it2n__no_chord_inverse;
#endif /* IT2N_CHORD */
