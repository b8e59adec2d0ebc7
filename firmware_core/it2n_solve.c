/*
 * Solving the control nets: P = (M^T)^-1 F N^-1 for every footprint and
 * channel, and the O(n*m) incremental update of one data point.
 *
 * With A[i][a] = B_a^n(u_i) and C[j][b] = B_b^m(w_j) the data satisfy
 * F = A P C^T, so P[a][b] = sum_ij Ainv[a][i] * Cinv[b][j] * F[i][j]. The
 * product Ainv[a][i] * Cinv[b][j] is rounded once to Q32 (the weight W), and
 * each control point is one exact 128-bit sum of W * F rounded once. The
 * update adds round(W * delta) for the changed point, so it differs from a
 * full re-solve by at most 1 LSB.
 */
#include <string.h>

#include "it2n_internal.h"

/* Pivots below 2^-24 mean the parameters (nearly) coincide. */
#define PIVOT_MIN ((int64_t)1 << (IT2N_PAR_FRAC - 24))

/* Inverse collocation matrix and parameters of one direction. */
typedef struct dir_solution {
    it2n_par t[IT2N_DIM];
    it2n_par inv[IT2N_DIM][IT2N_DIM];
} dir_solution;

void it2n_model_init(it2n_model *mdl)
{
    memset(mdl, 0, sizeof(*mdl));
}

static void params_uniform(unsigned deg, it2n_par t[IT2N_DIM])
{
    unsigned k;
    for (k = 0; k <= deg; k++) {
        uint64_t num = ((uint64_t)k << IT2N_PAR_FRAC) + deg / 2u;
        t[k] = (it2n_par)(num / deg);
    }
}

/* Distance between two D footprints, Q24. */
static int64_t chord(const it2n_dataset *ds, unsigned i0, unsigned j0,
                     unsigned i1, unsigned j1)
{
    it2n_i128 sq = it2n_i128_zero();
    unsigned ch;
    for (ch = 0; ch < it2n__ncoord(ds->flags); ch++) {
        /* |difference| < 2^49 raw, square < 2^98: exact in 128 bits. */
        int64_t d = ds->values[i1][j1][IT2N_FP_D][ch] -
                    ds->values[i0][j0][IT2N_FP_D][ch];
        sq = it2n_mac(sq, d, d);
    }
    return (int64_t)it2n_i128_isqrt(sq);
}

/*
 * Chord-length parameters averaged over rows (The NURBS Book, 9.2.5), from
 * the mean footprint D. dir 0: u along i for every j; dir 1: w along j.
 */
static int params_chord(const it2n_dataset *ds, unsigned dir,
                        it2n_par t[IT2N_DIM], it2n_errinfo *err)
{
    unsigned deg = dir ? ds->m : ds->n, lines = dir ? ds->n : ds->m;
    unsigned line, k, used = 0u;
    uint64_t acc[IT2N_DIM];
    memset(acc, 0, sizeof(acc));
    for (line = 0; line <= lines; line++) {
        int64_t d[IT2N_DIM], total = 0, cum = 0;
        for (k = 1; k <= deg; k++) {
            d[k] = dir ? chord(ds, line, k - 1u, line, k)
                       : chord(ds, k - 1u, line, k, line);
            total += d[k]; /* <= 15 * 2^50: no overflow */
        }
        if (total == 0) {
            continue; /* every point of this line coincides: skip it */
        }
        used++;
        for (k = 1; k < deg; k++) {
            int64_t r;
            cum += d[k];
            if (!it2n_i128_div(it2n_i128_shl(cum, IT2N_PAR_FRAC),
                               it2n_i128_from(total), &r)) {
                return it2n__fail(err, IT2N_ERR_OVERFLOW, -1, -1, IT2N_FP_D,
                                  -1, 0, 0, 0);
            }
            acc[k] += (uint64_t)r;
        }
    }
    if (used == 0u) {
        return it2n__fail(err, IT2N_ERR_DEGENERATE, -1, -1, IT2N_FP_D, -1,
                          (it2n_val)dir, 0, 0);
    }
    t[0] = 0;
    t[deg] = IT2N_PAR_ONE;
    for (k = 1; k < deg; k++) {
        t[k] = (it2n_par)((acc[k] + used / 2u) / used);
    }
    for (k = 1; k <= deg; k++) {
        if (t[k] - t[k - 1u] < PIVOT_MIN) {
            /* Two parameters coincide: the collocation matrix is singular.
             * Report which (dir, k) via i/j. */
            return it2n__fail(err, IT2N_ERR_DEGENERATE,
                              dir ? -1 : (int)k, dir ? (int)k : -1,
                              IT2N_FP_D, -1, (it2n_val)(t[k] >> 8),
                              (it2n_val)(t[k - 1u] >> 8), 0);
        }
    }
    return IT2N_OK;
}

/* x * y in Q32 with overflow check. */
static bool q32_mul(int64_t x, int64_t y, int64_t *out)
{
    return it2n_mul_shift(x, y, IT2N_PAR_FRAC, out);
}

/*
 * Invert the (deg+1)^2 collocation matrix A[r][c] = B_c(t_r) by Gauss-Jordan
 * with partial pivoting in Q32, then one Newton-Schulz refinement step
 * X += X (I - A X) with the residual held in Q64, which recovers the bits the
 * elimination rounded away.
 */
static int invert(unsigned deg, const it2n_par t[IT2N_DIM],
                  it2n_par inv[IT2N_DIM][IT2N_DIM], it2n_errinfo *err)
{
    int64_t a[IT2N_DIM][IT2N_DIM], w[IT2N_DIM][2 * IT2N_DIM];
    unsigned n = deg + 1u, r, c, k;
    for (r = 0; r < n; r++) {
        it2n__basis(deg, t[r], a[r]);
        for (c = 0; c < 2u * n; c++) {
            w[r][c] = c < n ? a[r][c] : (c - n == r ? IT2N_PAR_ONE : 0);
        }
    }
    for (c = 0; c < n; c++) {
        unsigned piv = c;
        int64_t p;
        for (r = c + 1u; r < n; r++) {
            int64_t x = w[r][c] < 0 ? -w[r][c] : w[r][c];
            int64_t y = w[piv][c] < 0 ? -w[piv][c] : w[piv][c];
            if (x > y) {
                piv = r;
            }
        }
        p = w[piv][c];
        if (p < PIVOT_MIN && p > -PIVOT_MIN) {
            return it2n__fail(err, IT2N_ERR_SINGULAR, -1, -1, -1, -1, p, 0, 0);
        }
        if (piv != c) {
            for (k = 0; k < 2u * n; k++) {
                int64_t tmp = w[c][k];
                w[c][k] = w[piv][k];
                w[piv][k] = tmp;
            }
        }
        for (k = 0; k < 2u * n; k++) {
            if (!it2n_i128_div(it2n_i128_shl(w[c][k], IT2N_PAR_FRAC),
                               it2n_i128_from(p), &w[c][k])) {
                return it2n__fail(err, IT2N_ERR_OVERFLOW, -1, -1, -1, -1, 0, 0,
                                  0);
            }
        }
        for (r = 0; r < n; r++) {
            int64_t f = w[r][c];
            if (r == c || f == 0) {
                continue;
            }
            for (k = 0; k < 2u * n; k++) {
                int64_t prod;
                if (!q32_mul(f, w[c][k], &prod) ||
                    !it2n_sub_ok(w[r][k], prod, &w[r][k])) {
                    return it2n__fail(err, IT2N_ERR_OVERFLOW, -1, -1, -1, -1,
                                      0, 0, 0);
                }
            }
        }
    }
    /* Refinement: R = I - A X in Q64, X' = X + X R. */
    {
        int64_t res[IT2N_DIM][IT2N_DIM];
        for (r = 0; r < n; r++) {
            for (c = 0; c < n; c++) {
                it2n_i128 s = it2n_i128_zero();
                for (k = 0; k < n; k++) {
                    s = it2n_mac(s, a[r][k], w[k][n + c]);
                }
                if (r == c) {
                    it2n_i128 one = {0u, 1u}; /* 2^64 */
                    s = it2n_i128_sub(one, s);
                } else {
                    s = it2n_i128_neg(s);
                }
                /* Residual is tiny; if it does not fit, keep X as is. */
                if (s.hi != 0u && s.hi != UINT64_MAX) {
                    goto done;
                }
                if (!it2n_i128_round(s, 1u, &res[r][c])) {
                    goto done; /* res in Q63 */
                }
            }
        }
        for (r = 0; r < n; r++) {
            int64_t row[IT2N_DIM];
            for (c = 0; c < n; c++) {
                it2n_i128 s = it2n_i128_zero();
                int64_t corr;
                for (k = 0; k < n; k++) {
                    s = it2n_mac(s, w[r][n + k], res[k][c]);
                }
                if (!it2n_i128_round(s, 63u, &corr) ||
                    !it2n_add_ok(w[r][n + c], corr, &row[c])) {
                    goto done;
                }
            }
            for (c = 0; c < n; c++) {
                w[r][n + c] = row[c];
            }
        }
    }
done:
    for (r = 0; r < n; r++) {
        for (c = 0; c < n; c++) {
            inv[r][c] = w[r][n + c];
        }
    }
    return IT2N_OK;
}

/*
 * Split an exact Q56 sum s into its Q24 rounding p = round(s / 2^32) and the
 * remainder r = s - p * 2^32 in [-2^31, 2^31). False if p does not fit.
 */
static bool split_sum(it2n_i128 s, int64_t *p, int32_t *r)
{
    int64_t q;
    it2n_i128 rem;
    if (!it2n_i128_round(s, IT2N_PAR_FRAC, &q)) {
        return false;
    }
    rem = it2n_i128_sub(s, it2n_i128_shl(q, IT2N_PAR_FRAC));
    *p = q;
    /* rem lies in [-2^31, 2^31): rebuild it from its low word portably. */
    *r = (int32_t)((rem.lo >> 63) ? -(int64_t)(~rem.lo) - 1
                                  : (int64_t)rem.lo);
    return true;
}

/* W = round(ainv[a][i] * binv[b][j]), Q32, for all data points (i, j). */
static bool weights(it2n_par ainv[IT2N_DIM][IT2N_DIM],
                    it2n_par binv[IT2N_DIM][IT2N_DIM], unsigned n,
                    unsigned m, unsigned a, unsigned b,
                    int64_t wt[IT2N_DIM][IT2N_DIM])
{
    unsigned i, j;
    for (i = 0; i <= n; i++) {
        for (j = 0; j <= m; j++) {
            if (!q32_mul(ainv[a][i], binv[b][j], &wt[i][j])) {
                return false;
            }
        }
    }
    return true;
}

static int solve_dir(const it2n_dataset *ds, unsigned dir, dir_solution *out,
                     it2n_errinfo *err)
{
    unsigned deg = dir ? ds->m : ds->n;
    int rc;
    if (ds->flags & IT2N_F_CHORD) {
        rc = params_chord(ds, dir, out->t, err);
        if (rc != IT2N_OK) {
            return rc;
        }
    } else {
        params_uniform(deg, out->t);
    }
    return invert(deg, out->t, out->inv, err);
}

/*
 * Solve every control net of ds into mdl. Every failure is detected before
 * mdl is written: the worst-case bound sum |W| * max|F| of each control
 * point is checked first, so the final accumulation cannot overflow.
 */
static int solve_core(it2n_model *mdl, const it2n_dataset *ds,
                      it2n_errinfo *err)
{
    dir_solution su, sw;
    int64_t wt[IT2N_DIM][IT2N_DIM];
    it2n_val maxabs[IT2N_CH_COUNT];
    unsigned a, b, i, j, fp, ch, n = ds->n, m = ds->m;
    unsigned mask = it2n__fp_mask(ds->flags);
    int rc;
    /* Entries beyond the degree stay zero: the model bytes are a function
     * of the data alone. */
    memset(&su, 0, sizeof(su));
    memset(&sw, 0, sizeof(sw));
    rc = solve_dir(ds, 0u, &su, err);
    if (rc == IT2N_OK) {
        rc = solve_dir(ds, 1u, &sw, err);
    }
    if (rc != IT2N_OK) {
        return rc;
    }
    for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
        maxabs[ch] = 0;
        for (i = 0; i <= n && it2n__ch_used(ds->flags, ch); i++) {
            for (j = 0; j <= m; j++) {
                for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                    it2n_val v = ds->values[i][j][fp][ch];
                    v = v < 0 ? -v : v;
                    if ((mask & (1u << fp)) && v > maxabs[ch]) {
                        maxabs[ch] = v;
                    }
                }
            }
        }
    }
    for (a = 0; a <= n; a++) {
        for (b = 0; b <= m; b++) {
            int64_t wsum = 0, bound;
            if (!weights(su.inv, sw.inv, n, m, a, b, wt)) {
                return it2n__fail(err, IT2N_ERR_OVERFLOW, (int)a, (int)b, -1,
                                  -1, 0, 0, 0);
            }
            for (i = 0; i <= n; i++) {
                for (j = 0; j <= m; j++) {
                    int64_t x = wt[i][j] < 0 ? -wt[i][j] : wt[i][j];
                    if (!it2n_add_ok(wsum, x, &wsum)) {
                        return it2n__fail(err, IT2N_ERR_OVERFLOW, (int)a,
                                          (int)b, -1, -1, 0, 0, 0);
                    }
                }
            }
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                if (!q32_mul(wsum, maxabs[ch], &bound)) {
                    return it2n__fail(err, IT2N_ERR_OVERFLOW, (int)a, (int)b,
                                      -1, (int)ch, maxabs[ch], 0, 0);
                }
            }
        }
    }
    /* Commit point: nothing below can fail. */
    if (&mdl->data != ds) {
        mdl->data = *ds;
    }
    memcpy(mdl->u, su.t, sizeof(mdl->u));
    memcpy(mdl->w, sw.t, sizeof(mdl->w));
    memcpy(mdl->ainv, su.inv, sizeof(mdl->ainv));
    memcpy(mdl->binv, sw.inv, sizeof(mdl->binv));
    memset(mdl->ctrl, 0, sizeof(mdl->ctrl));
    memset(mdl->ctrl_rem, 0, sizeof(mdl->ctrl_rem));
    for (a = 0; a <= n; a++) {
        for (b = 0; b <= m; b++) {
            if (!weights(su.inv, sw.inv, n, m, a, b, wt)) {
                IT2N_ASSERT(false); /* ruled out by the bound pass above */
                continue;
            }
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (!(mask & (1u << fp))) {
                    continue;
                }
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    it2n_i128 s = it2n_i128_zero();
                    if (!it2n__ch_used(ds->flags, ch)) {
                        continue; /* unused z: ignore whatever it holds */
                    }
                    for (i = 0; i <= n; i++) {
                        for (j = 0; j <= m; j++) {
                            s = it2n_mac(s, wt[i][j],
                                         ds->values[i][j][fp][ch]);
                        }
                    }
                    if (!split_sum(s, &mdl->ctrl[a][b][fp][ch],
                                   &mdl->ctrl_rem[a][b][fp][ch])) {
                        IT2N_ASSERT(false); /* the bound pass proved it fits */
                    }
                }
            }
        }
    }
    mdl->solved = 1u;
    mdl->generation++;
    return IT2N_OK;
}

int it2n_model_solve(it2n_model *mdl, const it2n_dataset *ds,
                     it2n_errinfo *err)
{
    int rc;
    if (mdl == NULL || ds == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = it2n_dataset_check(ds, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    return solve_core(mdl, ds, err);
}

/*
 * Apply (store) or dry-run the incremental change delta[ch] at (i, j, fp):
 * the exact sum behind each control point, ctrl * 2^32 + ctrl_rem, gains
 * W * delta with the same W the solve used, so the result is bit-identical
 * to a full re-solve.
 */
static bool update_pass(it2n_model *mdl, unsigned i, unsigned j, unsigned fp,
                        const int64_t delta[IT2N_CH_COUNT], bool store)
{
    unsigned a, b, ch, n = mdl->data.n, m = mdl->data.m;
    for (a = 0; a <= n; a++) {
        for (b = 0; b <= m; b++) {
            int64_t w;
            if (!q32_mul(mdl->ainv[a][i], mdl->binv[b][j], &w)) {
                return false;
            }
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                it2n_i128 s;
                int64_t p;
                int32_t r;
                if (delta[ch] == 0) {
                    continue;
                }
                s = it2n_i128_add(
                    it2n_i128_shl(mdl->ctrl[a][b][fp][ch], IT2N_PAR_FRAC),
                    it2n_i128_from(mdl->ctrl_rem[a][b][fp][ch]));
                s = it2n_mac(s, w, delta[ch]);
                if (!split_sum(s, &p, &r)) {
                    return false;
                }
                if (store) {
                    mdl->ctrl[a][b][fp][ch] = p;
                    mdl->ctrl_rem[a][b][fp][ch] = r;
                }
            }
        }
    }
    return true;
}

int it2n_model_update(it2n_model *mdl, unsigned i, unsigned j, unsigned fp,
                      const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err)
{
    it2n_val pt[IT2N_FP_COUNT][IT2N_CH_COUNT];
    int64_t delta[IT2N_CH_COUNT];
    unsigned ch, flags;
    int rc;
    if (mdl == NULL || vals == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (!mdl->solved) {
        return it2n__fail(err, IT2N_ERR_STATE, (int)i, (int)j, (int)fp, -1, 0,
                          0, 0);
    }
    flags = mdl->data.flags;
    if (i > mdl->data.n || j > mdl->data.m) {
        return it2n__fail(err, IT2N_ERR_INVAL, (int)i, (int)j, -1, -1,
                          (it2n_val)(i > mdl->data.n ? i : j), 0,
                          (it2n_val)(i > mdl->data.n ? mdl->data.n
                                                     : mdl->data.m));
    }
    if (fp >= IT2N_FP_COUNT || ((1u << fp) & it2n__fp_mask(flags)) == 0u) {
        return it2n__fail(err, IT2N_ERR_INVAL, (int)i, (int)j, (int)fp, -1,
                          (it2n_val)fp, 0, IT2N_FP_COUNT - 1);
    }
    rc = it2n__check_vals(flags, i, j, fp, vals, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    memcpy(pt, mdl->data.values[i][j], sizeof(pt));
    for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
        pt[fp][ch] = it2n__ch_used(flags, ch) ? vals[ch] : 0;
        delta[ch] = pt[fp][ch] - mdl->data.values[i][j][fp][ch];
    }
    rc = it2n__check_nesting(flags, i, j, &pt[0][0], err);
    if (rc != IT2N_OK) {
        return rc;
    }
    if (flags & IT2N_F_CHORD) {
        /* Parameters move with the data: full re-solve in place, restoring
         * the old point if it fails. */
        it2n_val old[IT2N_CH_COUNT];
        memcpy(old, mdl->data.values[i][j][fp], sizeof(old));
        memcpy(mdl->data.values[i][j][fp], pt[fp], sizeof(old));
        rc = solve_core(mdl, &mdl->data, err);
        if (rc != IT2N_OK) {
            memcpy(mdl->data.values[i][j][fp], old, sizeof(old));
        }
        return rc;
    }
    if (!update_pass(mdl, i, j, fp, delta, false)) {
        return it2n__fail(err, IT2N_ERR_OVERFLOW, (int)i, (int)j, (int)fp, -1,
                          0, 0, 0);
    }
    if (!update_pass(mdl, i, j, fp, delta, true)) {
        IT2N_ASSERT(false); /* same arithmetic as the dry run that passed */
    }
    memcpy(mdl->data.values[i][j][fp], pt[fp], sizeof(pt[fp]));
    mdl->generation++;
    return IT2N_OK;
}
