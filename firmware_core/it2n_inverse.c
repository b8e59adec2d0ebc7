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
