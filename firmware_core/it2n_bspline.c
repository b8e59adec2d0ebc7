/*
 * B-spline kind: data set in caller storage and the not-a-knot solve.
 *
 * One net (footprint, channel) is solved in two passes of line solves:
 * every data row (fixed i, along w) into an intermediate row of m+3
 * B-spline coefficients, then every intermediate column (along u) into n+3
 * coefficients. A line solve is exact algebra on the uniform B-spline
 * equations (c_{k-1} + 4 c_k + c_{k+1}) / 6 = y_k plus the not-a-knot
 * conditions (the fourth difference of c vanishes at knots 1 and N-1):
 *   6 c_1 = 8 y_1 - y_0 - y_2 (spans 0 and 1 are one cubic, so its second
 *   difference gives S''(u_1) directly), likewise 6 c_{N-1};
 *   c_2..c_{N-2} from the tridiagonal (1, 4, 1) system between them;
 *   6 c_0 = 4 (y_0 + y_1 + y_2) - 6 c_2, 6 c_{-1} = 36 y_0 - 24 c_0 - 6 c_1
 *   (the interpolation equations at u_1 and u_0), likewise at the far end.
 * The tridiagonal system has constant coefficients, so its pivots are fixed
 * rationals (a table below): no division at run time. Lines of 2 and 3
 * points are the line and the parabola through them (see it2n.h).
 *
 * Precision: values are int64 with at most 2^55 in, every intermediate
 * below 2^62 (|6 c| <= 93.5 max|y| over every line length, measured in
 * exact rationals; intermediates <= 123 max|y|); each product is one
 * rounding of an int64 by a 32-bit constant (two 32 x 32 -> 64 products).
 * The intermediate rows are stored as int32 mantissas with one exponent per
 * row, the result columns with one per column, then shifted to one exponent
 * per net (the net's largest mantissa in [2^30, 2^31)).
 */
#include <string.h>

#include "it2n_internal.h"

#define COORD_MAX ((it2n_val)IT2N_COORD_LIMIT << IT2N_VAL_FRAC)
#define LINE_MAX (IT2N_BSPLINE_MAX_N + 3)

/* ---- Data set ------------------------------------------------------------ */

static unsigned nfp_of(unsigned flags)
{
    return IT2N_BSPLINE_NFP(flags);
}

/* Record of footprint fp at (i, j); fp must be stored by this data set. */
static it2n_bspline_rec *rec_at(const it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp)
{
    unsigned nfp = nfp_of(ds->flags);
    size_t k = ((size_t)i * (ds->m + 1u) + j) * nfp + (nfp == 1u ? 0u : fp);
    return &ds->rec[k];
}

/* Channel ch of a record as stored: Q24 coordinate, Q30 membership. */
static it2n_val rec_value(const it2n_bspline_rec *r, unsigned ch)
{
    if (ch >= 3u) {
        return (it2n_val)r->memb[ch - 3u];
    }
    return (it2n_val)((uint64_t)(int64_t)r->hi[ch] * 4294967296u | r->lo[ch]);
}

static bool fp_stored(unsigned flags, unsigned fp)
{
    return fp < IT2N_FP_COUNT && ((1u << fp) & it2n__fp_mask(flags)) != 0u;
}

int it2n_bspline_data_init(it2n_bspline_data *ds, it2n_bspline_rec *rec, size_t cap, unsigned n, unsigned m,
                           unsigned flags, it2n_errinfo *err)
{
    const unsigned ok_flags = IT2N_F_Z | IT2N_F_TYPE1;
    size_t need, k;
    if (ds == NULL || rec == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (n < 1u || n > IT2N_BSPLINE_MAX_N) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, (it2n_val)n, 1, IT2N_BSPLINE_MAX_N);
    }
    if (m < 1u || m > IT2N_BSPLINE_MAX_N) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, (it2n_val)m, 1, IT2N_BSPLINE_MAX_N);
    }
    if ((flags & ~ok_flags) != 0u) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, (it2n_val)flags, 0, ok_flags);
    }
    need = IT2N_BSPLINE_DATA_RECS(n, m, flags);
    if (cap < need) {
        return it2n__fail(err, IT2N_ERR_RANGE, -1, -1, -1, -1, (it2n_val)cap, (it2n_val)need, (it2n_val)need);
    }
    for (k = 0; k < need; k++) {
        memset(&rec[k], 0, sizeof(rec[k]));
    }
    ds->rec = rec;
    ds->cap = cap;
    ds->n = (uint16_t)n;
    ds->m = (uint16_t)m;
    ds->flags = (uint8_t)flags;
    return IT2N_OK;
}

/* Store checked values into a record (memberships with IT2N_MEMB_FRAC -
 * shift fraction bits). */
static void rec_store(it2n_bspline_rec *r, unsigned flags, const it2n_val vals[IT2N_CH_COUNT], unsigned shift)
{
    unsigned ch;
    for (ch = 0; ch < 3u; ch++) {
        it2n_val v = it2n__ch_used(flags, ch) ? vals[ch] : 0;
        r->lo[ch] = (uint32_t)(uint64_t)v;
        r->hi[ch] = (int16_t)(v >> 32); /* |v| < 2^47 */
        r->memb[ch] = (uint32_t)vals[3u + ch] << shift;
    }
    r->present = 1u;
}

/* Index and footprint checks shared by put and update. */
static int check_where(const it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp, it2n_errinfo *err)
{
    if (i > ds->n || j > ds->m) {
        return it2n__fail(err, IT2N_ERR_INVAL, (int)i, (int)j, -1, -1, (it2n_val)(i > ds->n ? i : j), 0,
                          (it2n_val)(i > ds->n ? ds->n : ds->m));
    }
    if (!fp_stored(ds->flags, fp)) {
        return it2n__fail(err, IT2N_ERR_INVAL, (int)i, (int)j, (int)fp, -1, (it2n_val)fp, 0, IT2N_FP_COUNT - 1);
    }
    return IT2N_OK;
}

/* it2n_bspline_data_put for memberships of mfrac fraction bits. */
static int data_put(it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                    bool replace, int mfrac, it2n_errinfo *err)
{
    it2n_bspline_rec *r;
    int rc;
    if (ds == NULL || ds->rec == NULL || vals == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = check_where(ds, i, j, fp, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    rc = it2n__check_vals(ds->flags, i, j, fp, vals, mfrac, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    r = rec_at(ds, i, j, fp);
    if (!replace && r->present) {
        return it2n__fail(err, IT2N_ERR_DUPLICATE, (int)i, (int)j, (int)fp, -1, 0, 0, 0);
    }
    rec_store(r, ds->flags, vals, (unsigned)(IT2N_MEMB_FRAC - mfrac));
    return IT2N_OK;
}

int it2n_bspline_data_put(it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                          const it2n_val vals[IT2N_CH_COUNT], bool replace, it2n_errinfo *err)
{
    return data_put(ds, i, j, fp, vals, replace, IT2N_VAL_FRAC, err);
}

int it2n_bspline_data_put_fine(it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                               const it2n_val vals[IT2N_CH_COUNT], bool replace, it2n_errinfo *err)
{
    return data_put(ds, i, j, fp, vals, replace, IT2N_MEMB_FRAC, err);
}

void it2n_bspline_data_get(const it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                           it2n_val vals[IT2N_CH_COUNT])
{
    unsigned ch;
    it2n_bspline_data_get_fine(ds, i, j, fp, vals);
    for (ch = IT2N_CH_T; ch < IT2N_CH_COUNT; ch++) {
        /* in [0, 2^30]: Q24 rounded to nearest, ties up */
        vals[ch] =
            (vals[ch] + ((it2n_val)1 << (IT2N_MEMB_FRAC - IT2N_VAL_FRAC - 1))) >> (IT2N_MEMB_FRAC - IT2N_VAL_FRAC);
    }
}

void it2n_bspline_data_get_fine(const it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                                it2n_val vals[IT2N_CH_COUNT])
{
    const it2n_bspline_rec *r;
    unsigned ch;
    for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
        vals[ch] = 0;
    }
    if (ds == NULL || ds->rec == NULL || i > ds->n || j > ds->m || !fp_stored(ds->flags, fp)) {
        return;
    }
    r = rec_at(ds, i, j, fp);
    for (ch = 0; ch < IT2N_CH_COUNT && r->present; ch++) {
        vals[ch] = rec_value(r, ch);
    }
}

uint32_t it2n_bspline_data_missing(const it2n_bspline_data *ds)
{
    unsigned i, j, fp;
    uint32_t missing = 0u;
    for (i = 0; i <= ds->n; i++) {
        for (j = 0; j <= ds->m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (fp_stored(ds->flags, fp) && !rec_at(ds, i, j, fp)->present) {
                    missing++;
                }
            }
        }
    }
    return missing;
}

/* Nesting of footprint fp (values vals) with the stored fp - 1 and fp + 1
 * at (i, j), reported as a full check would. */
static int check_nesting(const it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                         const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err)
{
    unsigned ch;
    if (ds->flags & IT2N_F_TYPE1) {
        return IT2N_OK;
    }
    for (ch = 0; ch < it2n__ncoord(ds->flags) && fp > 0u; ch++) {
        it2n_val prev = rec_value(rec_at(ds, i, j, fp - 1u), ch);
        if (vals[ch] < prev) {
            return it2n__fail(err, IT2N_ERR_ORDER, (int)i, (int)j, (int)fp, (int)ch, vals[ch], prev, vals[ch]);
        }
    }
    for (ch = 0; ch < it2n__ncoord(ds->flags) && fp + 1u < IT2N_FP_COUNT; ch++) {
        it2n_val next = rec_value(rec_at(ds, i, j, fp + 1u), ch);
        if (next < vals[ch]) {
            return it2n__fail(err, IT2N_ERR_ORDER, (int)i, (int)j, (int)fp + 1, (int)ch, next, vals[ch], next);
        }
    }
    return IT2N_OK;
}

/* Sizes and flags a data set may have (the struct may be filled by hand). */
static bool data_shape_ok(const it2n_bspline_data *ds)
{
    return ds != NULL && ds->rec != NULL && ds->n >= 1u && ds->n <= IT2N_BSPLINE_MAX_N && ds->m >= 1u &&
           ds->m <= IT2N_BSPLINE_MAX_N && (ds->flags & ~(unsigned)(IT2N_F_Z | IT2N_F_TYPE1)) == 0u &&
           ds->cap >= IT2N_BSPLINE_DATA_RECS(ds->n, ds->m, ds->flags);
}

/* True when every record is present, in range and nested: one pass over
 * the records with no error bookkeeping (the solve's common case, about a
 * sixth of a 256x256 solve's instructions before); on false,
 * it2n_bspline_data_check's full loop finds and reports the first problem
 * exactly as before. Channels not used are skipped. */
static bool data_all_ok(const it2n_bspline_data *ds)
{
    const it2n_bspline_rec *r = ds->rec;
    size_t k, count = IT2N_BSPLINE_DATA_RECS(ds->n, ds->m, ds->flags);
    unsigned nfp = nfp_of(ds->flags), ncoord = it2n__ncoord(ds->flags), fp = 0;
    for (k = 0; k < count; k++, r++, fp = fp + 1u == nfp ? 0u : fp + 1u) {
        unsigned ch;
        if (!r->present) {
            return false;
        }
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            it2n_val v = rec_value(r, ch);
            bool coord = ch <= IT2N_CH_Z;
            if (!it2n__ch_used(ds->flags, ch)) {
                continue;
            }
            if (coord ? (v < -COORD_MAX || v > COORD_MAX) : (v < 0 || v > IT2N_VAL_ONE)) {
                return false;
            }
            /* nesting with footprint fp - 1 of the same point */
            if (coord && ch < ncoord && fp > 0u && v < rec_value(r - 1, ch)) {
                return false;
            }
        }
    }
    return true;
}

int it2n_bspline_data_check(const it2n_bspline_data *ds, it2n_errinfo *err)
{
    it2n_val vals[IT2N_CH_COUNT];
    unsigned i, j, fp;
    int rc;
    if (!data_shape_ok(ds)) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (data_all_ok(ds)) {
        return IT2N_OK;
    }
    for (i = 0; i <= ds->n; i++) {
        for (j = 0; j <= ds->m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (!fp_stored(ds->flags, fp)) {
                    continue;
                }
                if (!rec_at(ds, i, j, fp)->present) {
                    return it2n__fail(err, IT2N_ERR_MISSING, (int)i, (int)j, (int)fp, -1, 0, 0, 0);
                }
                it2n_bspline_data_get_fine(ds, i, j, fp, vals);
                rc = it2n__check_vals(ds->flags, i, j, fp, vals, IT2N_MEMB_FRAC, err);
                if (rc != IT2N_OK) {
                    return rc;
                }
                /* against fp - 1 only: each pair is checked once, in order */
                if (fp > 0u && !(ds->flags & IT2N_F_TYPE1)) {
                    unsigned ch;
                    for (ch = 0; ch < it2n__ncoord(ds->flags); ch++) {
                        it2n_val prev = rec_value(rec_at(ds, i, j, fp - 1u), ch);
                        if (vals[ch] < prev) {
                            return it2n__fail(err, IT2N_ERR_ORDER, (int)i, (int)j, (int)fp, (int)ch, vals[ch], prev,
                                              vals[ch]);
                        }
                    }
                }
            }
        }
    }
    return IT2N_OK;
}

/* ---- Line solve -------------------------------------------------------- */

/* round(a b / 2^32) for |a| < 2^62: a = hi 2^32 + lo, two 32 x 32 -> 64
 * products, exact rounding (ties toward +inf). */
static int64_t mulq32(int64_t a, uint32_t b)
{
    int32_t hi = (int32_t)(a >> 32);
    uint32_t lo = (uint32_t)(uint64_t)a;
    return it2n_mul32su(hi, b) + (int64_t)((it2n_umul32(lo, b) + 0x80000000u) >> 32);
}

/* Pivot reciprocals of the (1, 4, 1) elimination, round(2^32 / d_k) with
 * d_0 = 4, d_k = 4 - 1 / d_{k-1} (d_k = a_k / a_{k-1}, a_k = 4 a_{k-1} -
 * a_{k-2}, a_{-1} = 1, a_0 = 4); from k = 7 on they round to the limit
 * 2^32 (2 - sqrt 3). tests/core/test_bspline.c recomputes them. */
#define PIVOTS 8u
#define PIVOT_LIM 1150833018u /* the limit, from k = PIVOTS - 1 on */
static const uint32_t inv_pivot[PIVOTS] = {1073741824u, 1145324612u, 1150437669u, 1150804634u,
                                           1150830981u, 1150832872u, 1150833008u, PIVOT_LIM};

uint32_t it2n__bspline_pivot_inv(unsigned k)
{
    return inv_pivot[k < PIVOTS ? k : PIVOTS - 1u];
}

/* k x for small constants k as shifts and adds: no 64-bit multiply helper
 * on ARMv6-M (|k x| < 2^63 in every caller). */
static int64_t shl(int64_t x, unsigned s)
{
    return (int64_t)((uint64_t)x << s);
}
#define MUL4(x) shl((x), 2)
#define MUL6(x) (shl((x), 2) + shl((x), 1))
#define MUL8(x) shl((x), 3)
#define MUL3(x) (shl((x), 1) + (x))
#define MUL36(x) (shl((x), 5) + shl((x), 2))

/* The data a line solve keeps aside while it overwrites v. */
typedef struct line_ends {
    int64_t y0, y1, y2, ya, yb, yc, z1, zn1;
} line_ends;

/* Lines of 2 and 3 points: the line and the parabola through them. */
static void line_small(int64_t *v, unsigned N)
{
    int64_t y0 = v[1], y1 = v[2], y2;
    if (N == 1u) {
        v[0] = MUL6(2 * y0 - y1);
        v[1] = MUL6(y0);
        v[2] = MUL6(y1);
        v[3] = MUL6(2 * y1 - y0);
        return;
    }
    y2 = v[3];
    {
        /* the parabola p: 6 c_k = 6 p(u_k) - h^2 p'' */
        int64_t d = y0 - 2 * y1 + y2;
        v[0] = MUL6(MUL3(y0 - y1) + y2) - d;
        v[1] = MUL6(y0) - d;
        v[2] = MUL6(y1) - d;
        v[3] = MUL6(y2) - d;
        v[4] = MUL6(y0 + MUL3(y2 - y1)) - d;
    }
}

/* N >= 3: the ends' data and 6 c_1, 6 c_{N-1}. */
static void line_begin(const int64_t *v, unsigned N, line_ends *e)
{
    e->y0 = v[1];
    e->y1 = v[2];
    e->y2 = v[3];
    e->ya = v[N - 1u];
    e->yb = v[N];
    e->yc = v[N + 1u];
    e->z1 = MUL8(e->y1) - e->y0 - e->y2;
    e->zn1 = MUL8(e->yb) - e->ya - e->yc;
}

/* Forward elimination (1, 4, 1) for z_2..z_{N-2} (at v[3..N-1]),
 * right-hand sides 36 y_k with z_1 and z_{N-1} moved over, then back
 * substitution, in line_solve and line_solve2; pivot k's reciprocal is
 * inv_pivot[k], PIVOT_LIM from k = PIVOTS - 1 on. */

/* The ends from the interpolation equations at u_0, u_1 and u_{N-1}, u_N. */
static void line_finish(int64_t *v, unsigned N, const line_ends *e)
{
    int64_t z0, zn;
    v[2] = e->z1;
    v[N] = e->zn1;
    z0 = MUL4(e->y0 + e->y1 + e->y2) - v[3];
    v[1] = z0;
    v[0] = MUL36(e->y0) - MUL4(z0) - e->z1;
    zn = MUL4(e->yc + e->yb + e->ya) - v[N - 1u];
    v[N + 1u] = zn;
    v[N + 2u] = MUL36(e->yc) - MUL4(zn) - e->zn1;
}

/*
 * In: v[1..N+1] = y_0..y_N, |y| < 2^55, N in 1..IT2N_BSPLINE_MAX_N.
 * Out: v[0..N+2] = 6 c_{-1} .. 6 c_{N+1}, the not-a-knot coefficients (line
 * or parabola for N < 3), each below 93.5 max|y| < 2^62.
 */
static void line_solve(int64_t *v, unsigned N)
{
    line_ends e;
    unsigned k, M;
    if (N < 3u) {
        line_small(v, N);
        return;
    }
    line_begin(v, N, &e);
    M = N - 3u;
    if (M > 0u) {
        /* line_fwd and line_back with their first and last steps peeled
         * and the pivots' table part split off: the same values */
        unsigned kk = M < PIVOTS ? M : PIVOTS;
        v[3] = MUL36(v[3]) - e.z1;
        for (k = 1u; k < kk; k++) {
            v[k + 3u] = MUL36(v[k + 3u]) - mulq32(v[k + 2u], inv_pivot[k - 1u]);
        }
        for (; k < M; k++) {
            v[k + 3u] = MUL36(v[k + 3u]) - mulq32(v[k + 2u], PIVOT_LIM);
        }
        v[M + 2u] -= e.zn1;
        k = M - 1u;
        v[k + 3u] = mulq32(v[k + 3u], it2n__bspline_pivot_inv(k));
        while (k > PIVOTS - 1u) {
            k--;
            v[k + 3u] = mulq32(v[k + 3u] - v[k + 4u], PIVOT_LIM);
        }
        while (k > 0u) {
            k--;
            v[k + 3u] = mulq32(v[k + 3u] - v[k + 4u], inv_pivot[k]);
        }
    }
    line_finish(v, N, &e);
}

/* Hosts solve two lines at a time: their elimination chains interleaved
 * (each step waits for a multiply of the previous one), the same
 * arithmetic per line, so the same bits as one at a time. MCUs (in order,
 * no gain) keep one line and half the stack. */
#if !IT2N_MUL_HALVES && (defined(__x86_64__) || defined(__aarch64__))
#define LINE_PAIRS 1
static void line_solve2(int64_t *a, int64_t *b, unsigned N)
{
    line_ends ea, eb;
    unsigned k, M;
    if (N < 3u) {
        line_small(a, N);
        line_small(b, N);
        return;
    }
    line_begin(a, N, &ea);
    line_begin(b, N, &eb);
    M = N - 3u;
    if (M > 0u) {
        /* as line_solve, the two chains interleaved */
        unsigned kk = M < PIVOTS ? M : PIVOTS;
        uint32_t p;
        a[3] = MUL36(a[3]) - ea.z1;
        b[3] = MUL36(b[3]) - eb.z1;
        for (k = 1u; k < kk; k++) {
            p = inv_pivot[k - 1u];
            a[k + 3u] = MUL36(a[k + 3u]) - mulq32(a[k + 2u], p);
            b[k + 3u] = MUL36(b[k + 3u]) - mulq32(b[k + 2u], p);
        }
        for (; k < M; k++) {
            a[k + 3u] = MUL36(a[k + 3u]) - mulq32(a[k + 2u], PIVOT_LIM);
            b[k + 3u] = MUL36(b[k + 3u]) - mulq32(b[k + 2u], PIVOT_LIM);
        }
        a[M + 2u] -= ea.zn1;
        b[M + 2u] -= eb.zn1;
        k = M - 1u;
        p = it2n__bspline_pivot_inv(k);
        a[k + 3u] = mulq32(a[k + 3u], p);
        b[k + 3u] = mulq32(b[k + 3u], p);
        while (k > PIVOTS - 1u) {
            k--;
            a[k + 3u] = mulq32(a[k + 3u] - a[k + 4u], PIVOT_LIM);
            b[k + 3u] = mulq32(b[k + 3u] - b[k + 4u], PIVOT_LIM);
        }
        while (k > 0u) {
            k--;
            a[k + 3u] = mulq32(a[k + 3u] - a[k + 4u], inv_pivot[k]);
            b[k + 3u] = mulq32(b[k + 3u] - b[k + 4u], inv_pivot[k]);
        }
    }
    line_finish(a, N, &ea);
    line_finish(b, N, &eb);
}
#else
#define LINE_PAIRS 0
#endif

/* Shift s with round(max / 2^s) in [2^30, 2^31) for max > 0 (s may be
 * negative: an exact left shift). */
static int norm_shift(uint64_t max)
{
    int s = (int)it2n__bitlen64(max) - 31;
    if (s > 0 && (((max + ((uint64_t)1 << (s - 1))) >> s) >> 31) != 0u) {
        s++;
    }
    return s;
}

static uint64_t uabs(int64_t v)
{
    return v < 0 ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
}

/* v * 2^-s rounded (s > 0) or exact (s <= 0, the caller knows it fits). */
static int64_t scale(int64_t v, int s)
{
    if (s >= 63) {
        return 0;
    }
    return it2n__shift_round(v, s);
}

/* out[k * stride] = v[k] * 2^-s rounded, k < count, exactly as scale()
 * does it element by element (the shift's case decided once). */
static void store_line(int32_t *out, size_t stride, const int64_t *v, unsigned count, int s)
{
    unsigned k;
    if (s >= 63) {
        for (k = 0; k < count; k++) {
            out[k * stride] = 0;
        }
    } else if (s >= 1) {
        int64_t half = (int64_t)1 << (s - 1);
        for (k = 0; k < count; k++) {
            out[k * stride] = (int32_t)((v[k] + half) >> s);
        }
    } else {
        for (k = 0; k < count; k++) {
            out[k * stride] = (int32_t)(uint32_t)((uint64_t)v[k] << (unsigned)-s);
        }
    }
}

/* 2^36 / 36 rounded: the two passes' factor 6 each. */
#define INV36 1908874354u

/* Pass-1 state of the nets of one footprint: per channel the input shift
 * (or -1: all data zero), the exponent of every intermediate row and the
 * largest of them. */
typedef struct solve_fp_state {
    int f1[IT2N_CH_COUNT], tmax[IT2N_CH_COUNT];
    int8_t rsh[IT2N_CH_COUNT][IT2N_BSPLINE_MAX_N + 1];
} solve_fp_state;

/*
 * Pass 1 of every net of footprint fp: the data rows (|f| < 2^47, scaled to
 * below 2^55) into intermediate rows, row i at net row i + 1, 31-bit
 * mantissas with one exponent per row. All channels together, so the data
 * set is read twice per footprint (its largest value, then the rows), not
 * twice per net.
 */
/* Data row starting at record row (records nfp apart), channel ch, scaled
 * by 2^f1, into v[1..m+1]. */
static void gather_row(int64_t *v, const it2n_bspline_rec *row, unsigned flags, unsigned m, unsigned ch, int f1)
{
    size_t nfp = IT2N_BSPLINE_NFP(flags);
    const it2n_bspline_rec *r = row;
    unsigned j;
    if (ch < 3u) {
        for (j = 0; j <= m; j++, r += nfp) {
            int64_t x = (int64_t)((uint64_t)(int64_t)r->hi[ch] * 4294967296u | r->lo[ch]);
            v[j + 1u] = (int64_t)((uint64_t)x << f1);
        }
    } else {
        for (j = 0; j <= m; j++, r += nfp) {
            v[j + 1u] = (int64_t)((uint64_t)r->memb[ch - 3u] << f1);
        }
    }
}

/* A solved data row i of channel ch into net row i + 1, with its own
 * exponent. */
static void store_row(const it2n_bspline_model *mdl, unsigned fp, unsigned ch, unsigned i, const int64_t *v,
                      solve_fp_state *st)
{
    unsigned w = mdl->m + 3u, j;
    uint64_t mx = 0u;
    int s;
    for (j = 0; j < w; j++) {
        uint64_t a = uabs(v[j]);
        mx = a > mx ? a : mx;
    }
    s = mx == 0u ? -31 : norm_shift(mx);
    st->rsh[ch][i] = (int8_t)s;
    st->tmax[ch] = s > st->tmax[ch] ? s : st->tmax[ch];
    store_line(it2n__bspline_net(mdl, fp, ch) + (i + 1u) * w, 1u, v, w, s);
}

static void solve_rows(const it2n_bspline_model *mdl, const it2n_bspline_data *ds, unsigned fp,
                       const uint64_t amax[IT2N_CH_COUNT], solve_fp_state *st)
{
    int64_t v[LINE_MAX];
#if LINE_PAIRS
    int64_t v2[LINE_MAX];
#endif
    unsigned n = ds->n, m = ds->m, i, ch;
    for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
        st->f1[ch] = amax[ch] == 0u || !it2n__ch_used(ds->flags, ch) ? -1 : 55 - (int)it2n__bitlen64(amax[ch]);
        st->tmax[ch] = -64;
    }
    for (i = 0; i <= n; i++) {
        const it2n_bspline_rec *row = rec_at(ds, i, 0, fp);
        unsigned act[IT2N_CH_COUNT], na = 0, k;
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            if (st->f1[ch] >= 0) {
                act[na++] = ch;
            }
        }
        for (k = 0; k < na; k++) {
#if LINE_PAIRS
            if (k + 1u < na) {
                gather_row(v, row, ds->flags, m, act[k], st->f1[act[k]]);
                gather_row(v2, row, ds->flags, m, act[k + 1u], st->f1[act[k + 1u]]);
                line_solve2(v, v2, m);
                store_row(mdl, fp, act[k], i, v, st);
                store_row(mdl, fp, act[k + 1u], i, v2, st);
                k++;
                continue;
            }
#endif
            gather_row(v, row, ds->flags, m, act[k], st->f1[act[k]]);
            line_solve(v, m);
            store_row(mdl, fp, act[k], i, v, st);
        }
    }
}

/*
 * Pass 2 of one net: the intermediate columns, rows brought to the largest
 * row's exponent (each below 2^55), results times 16/36, one exponent per
 * column, then one per net. Returns the net's exponent (frac). Always
 * succeeds: see the bounds above.
 */
/* Intermediate column j (net rows 1..n+1), rows brought to the largest
 * row's exponent tmax (each below 2^55), into v[1..n+1]. */
static void gather_col(int64_t *v, const int32_t *net, unsigned w, unsigned n, unsigned j, const int8_t *rsh, int tmax)
{
    unsigned i;
    for (i = 0; i <= n; i++) {
        int64_t g = net[(i + 1u) * w + j];
        int sh = rsh[i] - tmax + 24;
        v[i + 1u] = sh >= 0 ? (int64_t)((uint64_t)g << sh) : scale(g, -sh);
    }
}

/* A solved column: times 16/36, into net column j with its own exponent
 * (csh[j]; *cmax the largest so far). */
static void store_col(int32_t *net, unsigned w, unsigned n, unsigned j, int64_t *v, int8_t *csh, int *cmax)
{
    uint64_t mx = 0u;
    unsigned i;
    int s;
    for (i = 0; i < n + 3u; i++) {
        uint64_t a;
        v[i] = mulq32(v[i], INV36);
        a = uabs(v[i]);
        mx = a > mx ? a : mx;
    }
    s = mx == 0u ? -31 : norm_shift(mx);
    csh[j] = (int8_t)s;
    *cmax = s > *cmax ? s : *cmax;
    store_line(net + j, w, v, n + 3u, s);
}

static int solve_cols(const it2n_bspline_model *mdl, unsigned fp, unsigned ch, const solve_fp_state *st)
{
    int64_t v[LINE_MAX];
#if LINE_PAIRS
    int64_t v2[LINE_MAX];
#endif
    int8_t csh[LINE_MAX];
    unsigned n = mdl->n, w = mdl->m + 3u, i, j;
    int32_t *net = it2n__bspline_net(mdl, fp, ch);
    int f1 = st->f1[ch], tmax = st->tmax[ch], cmax = -64, frac;
    if (f1 < 0) {
        for (i = 0; i < (n + 3u) * w; i++) {
            net[i] = 0;
        }
        return 0;
    }
    for (j = 0; j < w; j++) {
#if LINE_PAIRS
        if (j + 1u < w) {
            gather_col(v, net, w, n, j, st->rsh[ch], tmax);
            gather_col(v2, net, w, n, j + 1u, st->rsh[ch], tmax);
            line_solve2(v, v2, n);
            store_col(net, w, n, j, v, csh, &cmax);
            store_col(net, w, n, j + 1u, v2, csh, &cmax);
            j++;
            continue;
        }
#endif
        gather_col(v, net, w, n, j, st->rsh[ch], tmax);
        line_solve(v, n);
        store_col(net, w, n, j, v, csh, &cmax);
    }
    /* one exponent per net: columns shifted to the largest one's (row by
     * row, the same roundings as column by column) */
    for (i = 0; i < n + 3u; i++) {
        int32_t *p = net + i * w;
        for (j = 0; j < w; j++) {
            int d = cmax - csh[j];
            if (d > 0) {
                p[j] = (int32_t)scale(p[j], d);
            }
        }
    }
    /* value (Q24) = y 2^-f1; 6 g = row result; g = G 2^(rsh - f1) / 6;
     * column input 2^(tmax - 24 - f1) / 6 per unit; result 16 c / 36 ...:
     * c (Q24) = mantissa 2^(cmax + tmax - 28 - f1); frac counts real units */
    frac = f1 + 28 - cmax - tmax + it2n__ch_frac(ch); /* Q30 memberships */
    IT2N_ASSERT(frac >= -1 && frac <= 127);
    return frac;
}

/* ---- Model --------------------------------------------------------------- */

void it2n_bspline_model_init(it2n_bspline_model *mdl, int32_t *coef, size_t cap)
{
    if (mdl == NULL) {
        return;
    }
    memset(mdl, 0, sizeof(*mdl));
    mdl->coef = coef;
    mdl->cap = coef != NULL ? cap : 0u;
}

/* Solve every net of the footprints in fpmask (checks done). */
static void solve_fps(it2n_bspline_model *mdl, const it2n_bspline_data *ds, unsigned fpmask)
{
    solve_fp_state st;
    uint64_t amax[IT2N_FP_COUNT][IT2N_CH_COUNT];
    unsigned fp, ch;
    {
        /* every footprint's largest |value| per channel in one pass over
         * the records in storage order (footprints interleave: a pass per
         * footprint reads the whole data set each time); memberships are
         * never negative */
        const it2n_bspline_rec *r = ds->rec;
        size_t nfp = IT2N_BSPLINE_NFP(ds->flags), k;
        size_t count = (size_t)(ds->n + 1u) * (ds->m + 1u);
        memset(amax, 0, sizeof(amax));
        for (k = 0; k < count; k++) {
            unsigned slot;
            for (slot = 0; slot < nfp; slot++, r++) {
                uint64_t *am = amax[nfp == 1u ? IT2N_FP_D : slot];
                for (ch = 0; ch < 3u; ch++) {
                    uint64_t a = uabs(rec_value(r, ch));
                    uint64_t b = r->memb[ch];
                    am[ch] = a > am[ch] ? a : am[ch];
                    am[ch + 3u] = b > am[ch + 3u] ? b : am[ch + 3u];
                }
            }
        }
    }
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (!(fpmask & (1u << fp))) {
            continue;
        }
        solve_rows(mdl, ds, fp, amax[fp], &st);
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            if (it2n__ch_used(ds->flags, ch)) {
                mdl->frac[fp][ch] = (int8_t)solve_cols(mdl, fp, ch, &st);
            }
        }
    }
    mdl->generation++;
}

int it2n_bspline_solve(it2n_bspline_model *mdl, const it2n_bspline_data *ds, it2n_errinfo *err)
{
    size_t need;
    int rc;
    if (mdl == NULL || ds == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = it2n_bspline_data_check(ds, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    need = IT2N_BSPLINE_MODEL_WORDS(ds->n, ds->m, ds->flags);
    if (mdl->coef == NULL || mdl->cap < need) {
        return it2n__fail(err, IT2N_ERR_RANGE, -1, -1, -1, -1, (it2n_val)mdl->cap, (it2n_val)need, (it2n_val)need);
    }
    /* nothing below can fail */
    mdl->n = ds->n;
    mdl->m = ds->m;
    mdl->flags = ds->flags;
    memset(mdl->frac, 0, sizeof(mdl->frac));
    solve_fps(mdl, ds, it2n__fp_mask(ds->flags));
    mdl->solved = 1u;
    return IT2N_OK;
}

/* it2n_bspline_update for memberships of mfrac fraction bits. */
static int bs_update(it2n_bspline_model *mdl, it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                     const it2n_val vals[IT2N_CH_COUNT], int mfrac, it2n_errinfo *err)
{
    int rc;
    if (mdl == NULL || vals == NULL || !data_shape_ok(ds)) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (!mdl->solved || mdl->n != ds->n || mdl->m != ds->m || mdl->flags != ds->flags || mdl->coef == NULL ||
        mdl->cap < IT2N_BSPLINE_MODEL_WORDS(ds->n, ds->m, ds->flags)) {
        return it2n__fail(err, IT2N_ERR_STATE, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = check_where(ds, i, j, fp, err);
    if (rc == IT2N_OK) {
        rc = it2n__check_vals(ds->flags, i, j, fp, vals, mfrac, err);
    }
    if (rc == IT2N_OK) {
        rc = check_nesting(ds, i, j, fp, vals, err);
    }
    if (rc != IT2N_OK) {
        return rc;
    }
    rec_store(rec_at(ds, i, j, fp), ds->flags, vals, (unsigned)(IT2N_MEMB_FRAC - mfrac));
    solve_fps(mdl, ds, 1u << fp);
    return IT2N_OK;
}

int it2n_bspline_update(it2n_bspline_model *mdl, it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                        const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err)
{
    return bs_update(mdl, ds, i, j, fp, vals, IT2N_VAL_FRAC, err);
}

int it2n_bspline_update_fine(it2n_bspline_model *mdl, it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                             const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err)
{
    return bs_update(mdl, ds, i, j, fp, vals, IT2N_MEMB_FRAC, err);
}

it2n_val it2n_bspline_coef(const it2n_bspline_model *mdl, unsigned r, unsigned s, unsigned fp, unsigned ch)
{
    const int32_t *net;
    if (mdl == NULL || !mdl->solved || r > mdl->n + 2u || s > mdl->m + 2u || !fp_stored(mdl->flags, fp) ||
        ch >= IT2N_CH_COUNT || !it2n__ch_used(mdl->flags, ch)) {
        return 0;
    }
    net = it2n__bspline_net(mdl, fp, ch);
    /* frac >= -1: below 2^56 in Q24, no overflow */
    return it2n__shift_round(net[r * (mdl->m + 3u) + s], mdl->frac[fp][ch] - IT2N_VAL_FRAC);
}
