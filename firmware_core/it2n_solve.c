/*
 * Solving the control nets: P = (M^T)^-1 F N^-1 for every footprint and
 * channel, and the incremental update of one data point.
 *
 * The data satisfy F = M P N^T (M[k][i] = B_i^n(u_k), N[l][j] = B_j^m(w_l)),
 * so with C_n = M^-1 and C_m = N^-1 (fixed point, rows summing below 2^55:
 * exact tables for uniform parameters, it2n__invert for chord-length ones):
 *   stage 1  G[k][j] = sum_l F[k][l] C_m[j][l]      ((n+1)(m+1)^2 products)
 *   stage 2  P[i][j] = sum_k C_n[i][k] G[k][j]      ((n+1)^2(m+1) products)
 * Every product is split into 32 x 32 -> 64 multiplies of the operands'
 * halves (C = hi 2^24 + lo, G = hi 2^31 + lo, large data likewise), summed
 * in int64 accumulators and recombined with constant shifts: one rounding
 * per G and per P (to 2^-58 of its bound), no 64 x 64 product and no
 * run-time shift. The net is then stored as int32 mantissas with
 * one exponent chosen so that its largest point uses the full width.
 * A net depends only on its own channel's data and the two inverses, so the
 * update re-solves just the nets that changed and stays bit-identical to a
 * full solve.
 */
#include <string.h>

#include "it2n_internal.h"

/* Control points must stay below 2^39 so that every surface value, a
 * convex combination of them, fits Q39.24. */
#define NET_LIMIT_BITS 39

/* Pivots below 2^-24 mean the parameters (nearly) coincide. */
#define PIVOT_MIN ((int64_t)1 << (IT2N_PAR_FRAC - 24))

/* The inverse of one direction (see it2n__uinv), cs_bits the bit length
 * of its largest row absolute sum. */
typedef struct dir_inv {
    const int32_t *hi, *lo;
    int frac;
    unsigned cs_bits;
    const int32_t *w; /* one-word table (short path) or NULL */
    int wfrac;
} dir_inv;

void it2n_model_init(it2n_model *mdl)
{
    memset(mdl, 0, sizeof(*mdl));
}

static void params_uniform(unsigned deg, it2n_par t[IT2N_DIM])
{
    unsigned k;
    for (k = 0; k <= deg; k++) {
        t[k] = (it2n_par)it2n__udiv_round(k, deg);
    }
}

#if IT2N_CHORD
/* Distance between two D footprints, Q24. */
static int64_t chord(const it2n_dataset *ds, unsigned i0, unsigned j0, unsigned i1, unsigned j1)
{
    it2n_i128 sq = it2n__i128_zero();
    unsigned ch;
    for (ch = 0; ch < it2n__ncoord(ds->flags); ch++) {
        /* |difference| < 2^49 raw, square < 2^98: exact in 128 bits. */
        int64_t d =
            it2n_dataset_value_fine(ds, i1, j1, IT2N_FP_D, ch) - it2n_dataset_value_fine(ds, i0, j0, IT2N_FP_D, ch);
        sq = it2n_mac(sq, d, d);
    }
    return (int64_t)it2n__i128_isqrt(sq);
}

/*
 * Chord-length parameters averaged over rows (The NURBS Book, 9.2.5), from
 * the mean footprint D. dir 0: u along i for every j; dir 1: w along j.
 */
static int params_chord(const it2n_dataset *ds, unsigned dir, it2n_par t[IT2N_DIM], it2n_errinfo *err)
{
    unsigned deg = dir ? ds->m : ds->n, lines = dir ? ds->n : ds->m;
    unsigned line, k, used = 0u;
    uint64_t acc[IT2N_DIM];
    memset(acc, 0, sizeof(acc));
    for (line = 0; line <= lines; line++) {
        int64_t d[IT2N_DIM], total = 0, cum = 0;
        for (k = 1; k <= deg; k++) {
            d[k] = dir ? chord(ds, line, k - 1u, line, k) : chord(ds, k - 1u, line, k, line);
            total += d[k]; /* <= 15 * 2^50: no overflow */
        }
        if (total == 0) {
            continue; /* every point of this line coincides: skip it */
        }
        used++;
        for (k = 1; k < deg; k++) {
            int64_t r;
            cum += d[k]; /* cum <= total < 2^54 */
            r = (int64_t)it2n__div_round((uint64_t)cum, (uint64_t)total, IT2N_PAR_FRAC);
            acc[k] += (uint64_t)r;
        }
    }
    if (used == 0u) {
        return it2n__fail(err, IT2N_ERR_DEGENERATE, -1, -1, IT2N_FP_D, -1, (it2n_val)dir, 0, 0);
    }
    t[0] = 0;
    t[deg] = IT2N_PAR_ONE;
    for (k = 1; k < deg; k++) {
        t[k] = (it2n_par)it2n__udiv64_32(acc[k] + used / 2u, used);
    }
    for (k = 1; k <= deg; k++) {
        if (t[k] - t[k - 1u] < PIVOT_MIN) {
            /* Two parameters coincide: the collocation matrix is singular.
             * Report which (dir, k) via i/j. */
            return it2n__fail(err, IT2N_ERR_DEGENERATE, dir ? -1 : (int)k, dir ? (int)k : -1, IT2N_FP_D, -1,
                              (it2n_val)(t[k] >> 8), (it2n_val)(t[k - 1u] >> 8), 0);
        }
    }
    return IT2N_OK;
}

#endif /* IT2N_CHORD */

int it2n_params(const it2n_dataset *ds, it2n_par u[IT2N_DIM], it2n_par w[IT2N_DIM], it2n_errinfo *err)
{
    int rc;
    if (ds == NULL || u == NULL || w == NULL || ds->n < 1u || ds->n > IT2N_MAX_DEGREE || ds->m < 1u ||
        ds->m > IT2N_MAX_DEGREE) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    memset(u, 0, sizeof(it2n_par) * IT2N_DIM);
    memset(w, 0, sizeof(it2n_par) * IT2N_DIM);
    if (!(ds->flags & IT2N_F_CHORD)) {
        params_uniform(ds->n, u);
        params_uniform(ds->m, w);
        return IT2N_OK;
    }
#if IT2N_CHORD
    rc = params_chord(ds, 0u, u, err);
    return rc != IT2N_OK ? rc : params_chord(ds, 1u, w, err);
#else
    (void)rc;
    return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, (it2n_val)ds->flags, 0, IT2N_F_ALL);
#endif
}

/* Bit length of the largest row absolute sum (< 2^55 by construction). */
static unsigned rowsum_bits(const int32_t *hi, const int32_t *lo, unsigned deg)
{
    unsigned n = deg + 1u, r, k;
    uint64_t best = 0u;
    for (r = 0; r < n; r++) {
        uint64_t s = 0u;
        for (k = 0; k < n; k++) {
            int64_t v = (int64_t)(((uint64_t)(int64_t)hi[r * n + k] << 24) + (uint32_t)lo[r * n + k]);
            s += (uint64_t)(v < 0 ? -v : v);
        }
        best = s > best ? s : best;
    }
    return it2n__bitlen64(best);
}

static void dir_uniform(unsigned deg, dir_inv *d)
{
    d->hi = it2n__uniform_inv[deg - 1u].hi;
    d->lo = it2n__uniform_inv[deg - 1u].lo;
    d->frac = it2n__uniform_inv[deg - 1u].frac;
    d->w = it2n__uniform_inv[deg - 1u].w;
    d->wfrac = it2n__uniform_inv[deg - 1u].wfrac;
    d->cs_bits = rowsum_bits(d->hi, d->lo, deg);
}

/* Largest |F| of one channel (raw: Q24 coordinates, Q30 memberships) and
 * its bit length. */
static unsigned data_bits(const it2n_dataset *ds, unsigned fp, unsigned ch)
{
    uint64_t big = 0u;
    unsigned k, l;
    for (k = 0; k <= ds->n; k++) {
        for (l = 0; l <= ds->m; l++) {
            int64_t v = it2n_dataset_value_fine(ds, k, l, fp, ch);
            uint64_t a = (uint64_t)(v < 0 ? -v : v);
            big = a > big ? a : big;
        }
    }
    return it2n__bitlen64(big);
}

/*
 * Control points are below max|F| * rowsum(C_n) * rowsum(C_m); require that
 * bound (in bits) to stay under 2^NET_LIMIT_BITS for every net of the
 * footprints in fpmask. Returns IT2N_OK or IT2N_ERR_OVERFLOW naming fp, ch.
 */
static int check_bound(const it2n_dataset *ds, unsigned fpmask, const dir_inv *du, const dir_inv *dw, it2n_errinfo *err)
{
    unsigned fp, ch;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT && (fpmask & (1u << fp)); ch++) {
            unsigned eb;
            int bits;
            if (!it2n__ch_used(ds->flags, ch)) {
                continue;
            }
            eb = data_bits(ds, fp, ch);
            bits = (int)(eb + du->cs_bits + dw->cs_bits) - it2n__ch_frac(ch) - du->frac - dw->frac;
            if (eb != 0u && bits > NET_LIMIT_BITS) {
                return it2n__fail(err, IT2N_ERR_OVERFLOW, -1, -1, (int)fp, (int)ch, (it2n_val)bits, 0, NET_LIMIT_BITS);
            }
        }
    }
    return IT2N_OK;
}

/* Data at or above 2^30 (coordinates of magnitude 64 and more) take the
 * wide stage-1 path; memberships (Q30, at most 2^30: 31 bits, within the
 * small path's bounds) never do. */
#define SMALL_DATA_BITS 30

/* Dot products of n int32 pairs, exact in int64 (every caller's bounds keep
 * the partial sums below 2^62, so the order of the terms does not matter):
 * sum a[k] b[k], and sum a[k] b[k] with b[k] in [0, 2^31). ARMv6-M keeps one
 * out-of-line copy of each (flash: the solve's dozen product sites cost
 * about 0.6 KB inline, a call about a tenth of an 8-term sum); wider cores
 * inline them, one accumulator per loop as before. */
#if IT2N_MUL_HALVES
#define DOT_LINKAGE __attribute__((noinline)) static
#else
#define DOT_LINKAGE IT2N_INLINE
#endif
DOT_LINKAGE int64_t dot_ss(const int32_t *a, const int32_t *b, unsigned n)
{
    int64_t s = 0;
    unsigned k;
    for (k = 0; k < n; k++) {
        s += it2n_smul32(a[k], b[k]);
    }
    return s;
}

DOT_LINKAGE int64_t dot_su(const int32_t *a, const int32_t *b, unsigned n)
{
    int64_t s = 0;
    unsigned k;
    for (k = 0; k < n; k++) {
        s += it2n_mul32su(a[k], (uint32_t)b[k]);
    }
    return s;
}

/*
 * Stage 1 for column j: g[k] = sum_l F[k][l] C_m[j][l], rounded. Small data
 * (|F| <= 2^30): F * (hi 2^24 + lo), g = S / 2^24 (frac of C_m plus the
 * data's beyond 24). Wide data (|F| < 2^47): exact 128-bit S, g = S / 2^42
 * (frac of C_m - 18). Bounds (row sums of C below 2^55, so sum |hi| <
 * 2^31 + 16, lo < 2^24): every int64 partial sum stays below 2^62 and
 * |g| < 2^62.
 */
static void stage1(unsigned n1, unsigned m1, const int32_t *fa, const int32_t *fb, const dir_inv *dw, unsigned j,
                   bool wide, int64_t *g)
{
    unsigned k;
    const int32_t *hi = &dw->hi[j * m1], *lo = &dw->lo[j * m1];
    for (k = 0; k < n1; k++, fa += m1, fb += m1) {
        if (!wide) {
            g[k] = dot_ss(fa, hi, m1) + ((dot_su(fa, lo, m1) + ((int64_t)1 << 23)) >> 24);
            continue;
        }
        {
            /* coordinates of 64 and more: F = fh 2^24 + fl (fl in [0, 2^24),
             * |fh| < 2^23), C = hi 2^24 + lo, so S = F C = A 2^48 + B 2^24
             * + D with A = sum fh hi (< 2^55), B = sum fh lo + fl hi (<
             * 2^56), D = sum fl lo (< 2^51, >= 0), each an exact int64 sum
             * of 32 x 32 products. round(S / 2^42) (ties up, as
             * it2n__i128_round) is then A 2^6 + (B + (D >> 24) + 2^17) >>
             * 18 exactly: the same value as one 128-bit sum, without it. */
            int64_t a = dot_ss(fa, hi, m1);
            int64_t e = dot_su(fa, lo, m1) + dot_su(hi, fb, m1) + (dot_su(fb, lo, m1) >> 24);
            g[k] = (int64_t)((uint64_t)a << 6) + ((e + ((int64_t)1 << 17)) >> 18);
        }
    }
}

/*
 * Stage 2 for column j: p[i] = sum_k C_n[i][k] g[k] / 2^55 with C_n = hi
 * 2^24 + lo and g = gh 2^31 + gl: three int64 partial sums below 2^62. The
 * fourth, sum lo gl < 2^59, is below 16 units of p and dropped (p is kept to
 * 2^-58 of its bound and rounded to 31 bits afterwards).
 */
static void stage2(const dir_inv *du, unsigned n1, const int64_t *g, int64_t *p, unsigned stride)
{
    int32_t gh[IT2N_DIM], gl[IT2N_DIM];
    unsigned i, k;
    for (k = 0; k < n1; k++) {
        gh[k] = (int32_t)(g[k] >> 31);
        gl[k] = (int32_t)(g[k] & 0x7FFFFFFF);
    }
    for (i = 0; i < n1; i++) {
        const int32_t *hi = &du->hi[i * n1], *lo = &du->lo[i * n1];
        /* S = a 2^55 + b 2^31 + c 2^24 (c = sum hi gl, folded into b as
         * c >> 7); p = S / 2^55 (floor inside, one rounding at the end) */
        int64_t a = dot_ss(hi, gh, n1), b = dot_su(gh, lo, n1) + (dot_su(hi, gl, n1) >> 7);
        p[i * stride] = a + ((b + ((int64_t)1 << 23)) >> 24);
    }
}

/*
 * The short path, for uniform degrees up to 3 and data below 2^30: one-word
 * tables W (row sums below 2^31, entries rounded to 2^-28 or better).
 * Stage 1 is exact, g[k] = sum_l F[k][l] W_m[j][l] < 2^61; stage 2 sums
 * W_n g = (W gh) 2^31 + W gl exactly and rounds once, p = S / 2^30 < 2^62.
 * Three products per multiply-add instead of five. The table rounding
 * moves a control point by at most 1.7e-7 of max|F| <= max|P| (the data
 * are convex combinations of the net), within the 1e-6 max|P| goal.
 */
static void short_column(unsigned n1, unsigned m1, const int32_t *fa, const dir_inv *du, const dir_inv *dw, unsigned j,
                         int64_t *p, unsigned stride)
{
    unsigned i, k;
    const int32_t *wm = &dw->w[j * m1];
    int32_t gh[IT2N_DIM], gl[IT2N_DIM];
    for (k = 0; k < n1; k++, fa += m1) {
        int64_t g = dot_ss(fa, wm, m1);
        gh[k] = (int32_t)(g >> 31);
        gl[k] = (int32_t)(g & 0x7FFFFFFF);
    }
    for (i = 0; i < n1; i++) {
        const int32_t *wn = &du->w[i * n1];
        int64_t a = dot_ss(wn, gh, n1), b = dot_su(wn, gl, n1);
        p[i * stride] = a + a + ((b + ((int64_t)1 << 29)) >> 30);
    }
}

/*
 * Solve one net (fp, ch) of ds into net[] (int32 mantissas, compact
 * (n+1)(m+1)) and *frac. Cannot fail once check_bound passed.
 */
/*
 * The data of net (fp, ch), read once per net instead of once per column
 * of stage 1 (on ARMv6-M each read is a call with index arithmetic): small
 * data as int32 in fa; wide data split F = fh 2^24 + fl, fh in fa and fl
 * (in [0, 2^24)) in fb. Row k at k (m+1).
 */
static void load_net(const it2n_dataset *ds, unsigned fp, unsigned ch, bool wide, int32_t *fa, int32_t *fb)
{
    unsigned n1 = ds->n + 1u, m1 = ds->m + 1u, k, l;
    for (k = 0; k < n1; k++) {
        for (l = 0; l < m1; l++, fa++, fb++) {
            if (!wide) {
                *fa = (int32_t)it2n_dataset_value_fine(ds, k, l, fp, ch);
                continue;
            }
            {
                it2n_val f = it2n_dataset_value(ds, k, l, fp, ch);
                *fa = (int32_t)(f >> 24);
                *fb = (int32_t)(f & 0xFFFFFF);
            }
        }
    }
}

static void solve_net(const it2n_dataset *ds, unsigned fp, unsigned ch, const dir_inv *du, const dir_inv *dw,
                      int32_t *net, int8_t *frac)
{
    int64_t p64[IT2N_DIM * IT2N_DIM], g[IT2N_DIM];
    int32_t fa[IT2N_DIM * IT2N_DIM];
    int32_t fb[IT2N_DIM * IT2N_DIM];
    unsigned n1 = ds->n + 1u, m1 = ds->m + 1u, j, k, count = n1 * m1;
    unsigned eb = data_bits(ds, fp, ch), eh;
    bool wide = eb > SMALL_DATA_BITS + (ch >= IT2N_CH_T ? 1u : 0u);
    bool shortp = !wide && du->w != NULL && dw->w != NULL;
    uint64_t big = 0u;
    int s, f;
    if (eb == 0u) {
        memset(net, 0, count * sizeof(*net));
        *frac = 0;
        return;
    }
    load_net(ds, fp, ch, wide, fa, fb);
    for (j = 0; j < m1; j++) {
        if (shortp) {
            short_column(n1, m1, fa, du, dw, j, &p64[j], m1);
            continue;
        }
        stage1(n1, m1, fa, fb, dw, j, wide, g);
        stage2(du, n1, g, &p64[j], m1);
    }
    for (k = 0; k < count; k++) {
        int64_t v = p64[k] < 0 ? -p64[k] : p64[k];
        big = (uint64_t)v > big ? (uint64_t)v : big;
    }
    /* Normalise: the largest mantissa in [2^30, 2^31). */
    eh = it2n__bitlen64(big);
    s = (int)eh - 31;
    if (s > 0 && it2n__shift_round((int64_t)big, s) > INT32_MAX) {
        s++;
    }
    /* g has frac_m + (data frac - 24) fractional bits (wide: 18 fewer),
     * p64 frac_n + frac_g - 55, the mantissas s fewer. */
    f = shortp ? it2n__ch_frac(ch) + du->wfrac + dw->wfrac - 30 - s
               : du->frac + dw->frac - 55 - (wide ? 18 : 0) - s + (it2n__ch_frac(ch) - IT2N_VAL_FRAC);
    if (f > 127) { /* a net of values below 2^-96: keep the exponent */
        s += f - 127;
        f = 127;
    }
    for (k = 0; k < count; k++) {
        net[k] = (int32_t)it2n__shift_round(p64[k], s);
    }
    *frac = (int8_t)f;
}

/* Solve the nets of the footprints in fpmask into mdl (after the checks). */
static void solve_nets(it2n_model *mdl, const it2n_dataset *ds, unsigned fpmask, const dir_inv *du, const dir_inv *dw)
{
    unsigned fp, ch;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (!(fpmask & (1u << fp))) {
            continue;
        }
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            if (it2n__ch_used(ds->flags, ch)) {
                solve_net(ds, fp, ch, du, dw, mdl->net[fp][ch], &mdl->frac[fp][ch]);
            }
        }
    }
}

/*
 * Inverses, bound check, then (commit point) the nets of fpmask. With
 * fpmask = every footprint the whole model is rewritten.
 */
static int solve_core(it2n_model *mdl, const it2n_dataset *ds, unsigned fpmask, bool full, it2n_errinfo *err);

/* Commit point: clear what a full solve does not write (unused footprints
 * and channels, entries beyond the degrees) so the model bytes are a
 * function of the data alone, then solve. */
static void commit(it2n_model *mdl, const it2n_dataset *ds, unsigned fpmask, bool full, const dir_inv *du,
                   const dir_inv *dw)
{
    if (full) {
        memset(mdl->net, 0, sizeof(mdl->net));
        memset(mdl->frac, 0, sizeof(mdl->frac));
    }
    solve_nets(mdl, ds, fpmask, du, dw);
}

#if IT2N_CHORD
/* Chord-length inverses need buffers; uniform ones are tables. Separate
 * frames keep the uniform solve's stack small. */
static int solve_chord(it2n_model *mdl, const it2n_dataset *ds, unsigned fpmask, bool full, it2n_errinfo *err)
{
    int32_t uh[IT2N_DIM * IT2N_DIM], ul[IT2N_DIM * IT2N_DIM];
    int32_t wh[IT2N_DIM * IT2N_DIM], wl[IT2N_DIM * IT2N_DIM];
    it2n_par u[IT2N_DIM], w[IT2N_DIM];
    dir_inv du, dw;
    int rc = it2n_params(ds, u, w, err);
    if (rc == IT2N_OK) {
        rc = it2n__invert(ds->n, u, uh, ul, &du.frac, err);
    }
    if (rc == IT2N_OK) {
        rc = it2n__invert(ds->m, w, wh, wl, &dw.frac, err);
    }
    if (rc != IT2N_OK) {
        return rc;
    }
    du.hi = uh;
    du.lo = ul;
    dw.hi = wh;
    dw.lo = wl;
    du.w = dw.w = NULL;
    du.wfrac = dw.wfrac = 0;
    du.cs_bits = rowsum_bits(uh, ul, ds->n);
    dw.cs_bits = rowsum_bits(wh, wl, ds->m);
    rc = check_bound(ds, fpmask, &du, &dw, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    commit(mdl, ds, fpmask, full, &du, &dw);
    return IT2N_OK;
}

#endif /* IT2N_CHORD */

static int solve_core(it2n_model *mdl, const it2n_dataset *ds, unsigned fpmask, bool full, it2n_errinfo *err)
{
    dir_inv du, dw;
    int rc;
#if IT2N_CHORD
    if (ds->flags & IT2N_F_CHORD) {
        return solve_chord(mdl, ds, fpmask, full, err);
    }
#endif
    dir_uniform(ds->n, &du);
    dir_uniform(ds->m, &dw);
    rc = check_bound(ds, fpmask, &du, &dw, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    commit(mdl, ds, fpmask, full, &du, &dw);
    return IT2N_OK;
}

/* Everything a full solve writes besides the nets. */
static void model_header(it2n_model *mdl, const it2n_dataset *ds)
{
    mdl->n = ds->n;
    mdl->m = ds->m;
    mdl->flags = ds->flags;
    mdl->solved = 1u;
    mdl->generation++;
}

int it2n_model_solve(it2n_model *mdl, const it2n_dataset *ds, it2n_errinfo *err)
{
    int rc;
    if (mdl == NULL || ds == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = it2n_dataset_check(ds, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    rc = solve_core(mdl, ds, it2n__fp_mask(ds->flags), true, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    model_header(mdl, ds);
    return IT2N_OK;
}

/* it2n_model_update for memberships of mfrac fraction bits. */
static int model_update(it2n_model *mdl, it2n_dataset *ds, unsigned i, unsigned j, unsigned fp,
                        const it2n_val vals[IT2N_CH_COUNT], int mfrac, it2n_errinfo *err)
{
    it2n_val nv[IT2N_CH_COUNT], old[IT2N_CH_COUNT];
    unsigned ch, flags, mask;
    int rc;
    if (mdl == NULL || ds == NULL || vals == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (!mdl->solved || mdl->n != ds->n || mdl->m != ds->m || mdl->flags != ds->flags) {
        /* not solved, or not solved from this data set */
        return it2n__fail(err, IT2N_ERR_STATE, (int)i, (int)j, (int)fp, -1, 0, 0, 0);
    }
    flags = ds->flags;
    if (i > ds->n || j > ds->m) {
        return it2n__fail(err, IT2N_ERR_INVAL, (int)i, (int)j, -1, -1, (it2n_val)(i > ds->n ? i : j), 0,
                          (it2n_val)(i > ds->n ? ds->n : ds->m));
    }
    if (fp >= IT2N_FP_COUNT || ((1u << fp) & it2n__fp_mask(flags)) == 0u) {
        return it2n__fail(err, IT2N_ERR_INVAL, (int)i, (int)j, (int)fp, -1, (it2n_val)fp, 0, IT2N_FP_COUNT - 1);
    }
    rc = it2n__check_vals(flags, i, j, fp, vals, mfrac, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
        /* memberships in Q30, as stored (checked: the shift is exact) */
        nv[ch] = !it2n__ch_used(flags, ch) ? 0
                 : ch < IT2N_CH_T          ? vals[ch]
                                           : vals[ch] * ((it2n_val)1 << (IT2N_MEMB_FRAC - mfrac));
    }
    rc = it2n__check_nesting_point(ds, i, j, fp, nv, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    /* Chord-length parameters follow footprint D: every net moves. */
    mask = ((flags & IT2N_F_CHORD) && fp == IT2N_FP_D) ? it2n__fp_mask(flags) : 1u << fp;
    it2n_dataset_get_fine(ds, i, j, fp, old);
    it2n__dataset_store(ds, i, j, fp, nv, 0u);
    rc = solve_core(mdl, ds, mask, false, err);
    if (rc != IT2N_OK) {
        it2n__dataset_store(ds, i, j, fp, old, 0u);
        return rc;
    }
    ds->present[i][j] = (uint8_t)(ds->present[i][j] | (1u << fp));
    mdl->generation++;
    return IT2N_OK;
}

int it2n_model_update(it2n_model *mdl, it2n_dataset *ds, unsigned i, unsigned j, unsigned fp,
                      const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err)
{
    return model_update(mdl, ds, i, j, fp, vals, IT2N_VAL_FRAC, err);
}

int it2n_model_update_fine(it2n_model *mdl, it2n_dataset *ds, unsigned i, unsigned j, unsigned fp,
                           const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err)
{
    return model_update(mdl, ds, i, j, fp, vals, IT2N_MEMB_FRAC, err);
}

it2n_val it2n_model_ctrl(const it2n_model *mdl, unsigned i, unsigned j, unsigned fp, unsigned ch)
{
    if (mdl == NULL || !mdl->solved || i > mdl->n || j > mdl->m || fp >= IT2N_FP_COUNT || ch >= IT2N_CH_COUNT ||
        !it2n_model_has_fp(mdl, fp)) {
        return 0;
    }
    /* frac >= -8 (nets below 2^39): the left shift cannot overflow */
    return it2n__shift_round(mdl->net[fp][ch][i * (mdl->m + 1u) + j], mdl->frac[fp][ch] - IT2N_VAL_FRAC);
}
