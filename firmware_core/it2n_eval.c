/*
 * Evaluating the surfaces: Bernstein basis, tensor-product sums,
 * derivatives and grid sampling.
 *
 * At (u, w) the basis values B_i(u), B_j(w) (Q30) are shared by every
 * footprint and channel. Each surface value is two short stages over a
 * net's int32 mantissas, q_j = sum_i B_i(u) P_ij (rounded to the net's
 * mantissa scale) and sum_j B_j(w) q_j (rounded once to Q24), all 32 x 32 ->
 * 64 multiply-accumulates (SMLAL on ARMv7-M, four MULS on ARMv6-M) with a
 * few dozen bytes of stack. it2n_sample calls the same code per node, so a
 * sampled node is bit-identical to it2n_eval at the same (u, w).
 */
#include <string.h>

#include "it2n_internal.h"

#define Q30_ONE ((int32_t)1 << 30)
#define Q30_HALF ((int64_t)1 << 29)

/* The basis recurrence's product: one copy of the multiply on ARMv6-M (a
 * handful of calls per evaluation, flash matters more there). */
#if IT2N_MUL_HALVES
__attribute__((noinline))
#endif
static uint64_t q30mul(uint32_t a, uint32_t b)
{
    return it2n_umul32(a, b);
}

void it2n__basis30(unsigned deg, it2n_par t, int32_t b[IT2N_DIM])
{
    /* every value is in [0, 2^30]: unsigned products, no sign handling */
    uint32_t t30 = (uint32_t)((t + 2) >> 2), s30 = (uint32_t)Q30_ONE - t30;
    uint32_t v[IT2N_DIM];
    uint32_t sum = 0u;
    unsigned k, i, big = 0u;
    v[0] = (uint32_t)Q30_ONE;
    for (k = 1; k <= deg; k++) {
        /* b_k^k = t b_{k-1}^{k-1}; b_i^k = s b_i^{k-1} + t b_{i-1}^{k-1} */
        v[k] = (uint32_t)((q30mul(t30, v[k - 1u]) + (1u << 29)) >> 30);
        for (i = k - 1u; i >= 1u; i--) {
            uint64_t acc = q30mul(s30, v[i]) + q30mul(t30, v[i - 1u]);
            v[i] = (uint32_t)((acc + (1u << 29)) >> 30);
        }
        v[0] = (uint32_t)((q30mul(s30, v[0]) + (1u << 29)) >> 30);
    }
    /* Exact partition of unity: the largest value takes the rounding
     * residue (a few LSB), so sum_i b[i] = 2^30 exactly. Constant data give
     * constant surfaces, and a stage-1 sum never leaves the net's range. */
    for (i = 0; i <= deg; i++) {
        sum += v[i];
        big = v[i] > v[big] ? i : big;
    }
    v[big] += (uint32_t)Q30_ONE - sum;
    for (i = 0; i <= deg; i++) {
        b[i] = (int32_t)v[i];
    }
}

/* Derivative basis in Q26: d/dt sum_i c_i B_i^deg(t) = sum_i c_i db[i], with
 * db[i] = deg (B_{i-1}^{deg-1}(t) - B_i^{deg-1}(t)), |db[i]| <= deg < 2^4. */
static void dbasis26(unsigned deg, it2n_par t, int32_t db[IT2N_DIM])
{
    int32_t b[IT2N_DIM];
    unsigned i;
    it2n__basis30(deg - 1u, t, b);
    for (i = 0; i <= deg; i++) {
        int32_t lo = i >= 1u ? b[i - 1u] : 0;
        int32_t hi = i < deg ? b[i] : 0;
        db[i] = (int32_t)((it2n_smul32(lo - hi, (int32_t)deg) + 8) >> 4);
    }
}

/*
 * One surface value: sum_j cw[j] sum_i cu[i] net[i (m+1) + j]. cu, cw are
 * Q30 basis values or Q26 derivative weights (|cu| sums to at most 2^30
 * times 2 deg). Stage 1 rounds to the mantissa scale (a convex combination:
 * the basis sums to 2^30 exactly, so it stays within the net's int32 range),
 * or half of it for derivative weights (up to 2 deg times the net), stage 2
 * to Q24. False if the result does not fit Q39.24 (derivatives of nets near
 * 2^39 only).
 */
/* The two stages with stage-1 shift s1. Wide cores inline it at each call
 * with a constant shift; ARMv6-M keeps one copy for both shifts (flash; a
 * run-time shift costs a few instructions per column). One accumulator at
 * a time: no spills on ARMv6-M's 8 low registers. */
#if IT2N_MUL_HALVES
#define TWO_STAGES_LINKAGE __attribute__((noinline)) static
#else
#define TWO_STAGES_LINKAGE IT2N_INLINE
#endif
/* x86-64 unrolls the inner sum where the degree is a constant
 * (two_stages_host below); MCU builds keep the loop (flash). */
#if !IT2N_MUL_HALVES && defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define TWO_STAGES_UNROLL _Pragma("GCC unroll 8")
#else
#define TWO_STAGES_UNROLL
#endif
TWO_STAGES_LINKAGE int64_t two_stages(const int32_t *net, unsigned n1, unsigned m1,
                                      const int32_t *cu, const int32_t *cw,
                                      const int s1)
{
    int64_t acc = 0;
    unsigned i, j;
    for (j = 0; j < m1; j++) {
        const int32_t *p = net + j;
        int64_t q = 0;
        TWO_STAGES_UNROLL
        for (i = 0; i < n1; i++, p += m1) {
            q += it2n_smul32(cu[i], *p);
        }
        q = (q + ((int64_t)1 << (s1 - 1))) >> s1;
        acc += it2n_smul32(cw[j], (int32_t)q);
    }
    return acc;
}

#if !IT2N_MUL_HALVES && defined(__x86_64__)
/* x86-64 hosts (the daemon, the CLI): two_stages inlined once per degree,
 * so the inner sum has a constant trip count and unrolls. The same
 * products summed in the same order: results identical (core vectors),
 * about 28 % fewer instructions per it2n_eval at degree 3 (an FC 23 query
 * of it2nd is mostly this). MCU targets keep the single loop (flash). */
#define IT2N_TWO_STAGES_K(k)                                                 \
    case k:                                                                  \
        return s1 == 30 ? two_stages(net, k, m1, cu, cw, 30)                 \
                        : two_stages(net, k, m1, cu, cw, 31)

static int64_t two_stages_host(const int32_t *net, unsigned n1, unsigned m1,
                               const int32_t *cu, const int32_t *cw, int s1)
{
    switch (n1) {
    IT2N_TWO_STAGES_K(2);
    IT2N_TWO_STAGES_K(3);
    IT2N_TWO_STAGES_K(4);
    IT2N_TWO_STAGES_K(5);
    IT2N_TWO_STAGES_K(6);
    IT2N_TWO_STAGES_K(7);
    IT2N_TWO_STAGES_K(8);
    default:
        return s1 == 30 ? two_stages(net, n1, m1, cu, cw, 30)
                        : two_stages(net, n1, m1, cu, cw, 31);
    }
}
#define IT2N_TWO_STAGES_HOST 1
#endif

static bool surface(const int32_t *net, int frac, unsigned n1, unsigned m1,
                    const int32_t *cu, int ufrac, const int32_t *cw, int wfrac,
                    it2n_val *out)
{
    int64_t acc;
    int s, s1 = ufrac < 30 ? 31 : 30;
#ifdef IT2N_TWO_STAGES_HOST
    acc = two_stages_host(net, n1, m1, cu, cw, s1);
#else
    acc = s1 == 30 ? two_stages(net, n1, m1, cu, cw, 30)
                   : two_stages(net, n1, m1, cu, cw, 31);
#endif
    s = ufrac - s1 + wfrac + frac - IT2N_VAL_FRAC;
    if (s < 0) {
        /* Only nets near 2^39 get here: check the left shift. */
        int64_t lim = INT64_MAX >> (unsigned)-s;
        if (acc > lim || acc < -lim) {
            return false;
        }
    }
    *out = it2n__shift_round(acc, s);
    return true;
}

/*
 * One pair of weight vectors applied to every net in fpmask into
 * out[fp][ch]. Returns false (and names fp, ch in *bad) if a result does not
 * fit Q39.24.
 */
static bool apply(const it2n_model *mdl, unsigned fpmask, const int32_t *cu,
                  int ufrac, const int32_t *cw, int wfrac, it2n_val *out,
                  unsigned *bad)
{
    unsigned n1 = mdl->n + 1u, m1 = mdl->m + 1u, fp, ch;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            it2n_val *o = &out[fp * IT2N_CH_COUNT + ch];
            *o = 0;
            if (!(fpmask & (1u << fp)) || !it2n__ch_used(mdl->flags, ch)) {
                continue;
            }
            if (!surface(mdl->net[fp][ch], mdl->frac[fp][ch], n1, m1, cu,
                         ufrac, cw, wfrac, o)) {
                *bad = fp << 4 | ch; /* no division needed to split it */
                return false;
            }
        }
    }
    return true;
}

void it2n__summarise(const it2n_model *mdl, it2n_point *out)
{
    it2n__summarise_flags(mdl->flags, out);
}

void it2n__summarise_flags(unsigned flags, it2n_point *out)
{
    static const unsigned char upper[3] = {IT2N_FP_LL, IT2N_FP_D, IT2N_FP_RR};
    static const unsigned char lower[3] = {IT2N_FP_LR, IT2N_FP_D, IT2N_FP_RL};
    unsigned k, f, fp;
    bool type1 = (flags & IT2N_F_TYPE1) != 0u;
    uint32_t oor = 0u;
    if (type1) {
        /* one footprint: every bound is its value */
        for (k = 0; k < 3u; k++) {
            it2n_val d = out->v[IT2N_FP_D][IT2N_CH_T + k];
            out->sum.upper_min[k] = out->sum.upper_max[k] = d;
            out->sum.lower_min[k] = out->sum.lower_max[k] = d;
            if ((uint64_t)d > (uint64_t)IT2N_VAL_ONE) {
                oor |= (uint32_t)1u << (IT2N_FP_D * 3u + k);
            }
        }
        out->out_of_range = oor;
        return;
    }
    for (k = 0; k < 3u; k++) {
        unsigned ch = IT2N_CH_T + k;
        it2n_val d = out->v[IT2N_FP_D][ch];
        it2n_val umin = d, umax = d, lmin = d, lmax = d;
        for (f = 0; f < 3u; f++) {
            it2n_val a = out->v[upper[f]][ch], b = out->v[lower[f]][ch];
            umin = a < umin ? a : umin;
            umax = a > umax ? a : umax;
            lmin = b < lmin ? b : lmin;
            lmax = b > lmax ? b : lmax;
        }
        out->sum.upper_min[k] = umin;
        out->sum.upper_max[k] = umax;
        out->sum.lower_min[k] = lmin;
        out->sum.lower_max[k] = lmax;
        /* outside [0, 1]: one unsigned compare catches both sides */
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            if ((uint64_t)out->v[fp][ch] > (uint64_t)IT2N_VAL_ONE) {
                oor |= (uint32_t)1u << (fp * 3u + k);
            }
        }
    }
    out->out_of_range = oor;
}

/* Common argument checks of the evaluation entry points. */
static int check_args(const it2n_model *mdl, it2n_par u, it2n_par w,
                      it2n_errinfo *err)
{
    if (!mdl->solved) {
        return it2n__fail(err, IT2N_ERR_STATE, -1, -1, -1, -1, 0, 0, 0);
    }
    return it2n__check_uw(u, w, err);
}


/* Values of every footprint at (u, w) into v (no summary). */
static void eval_values(const it2n_model *mdl, it2n_par u, it2n_par w,
                        it2n_val *v)
{
    int32_t bu[IT2N_DIM], bw[IT2N_DIM];
    unsigned bad;
    it2n__basis30(mdl->n, u, bu);
    it2n__basis30(mdl->m, w, bw);
    if (!apply(mdl, it2n__fp_mask(mdl->flags), bu, 30, bw, 30, v, &bad)) {
        IT2N_ASSERT(false); /* convex weights: values are within the net */
    }
}

int it2n_eval(const it2n_model *mdl, it2n_par u, it2n_par w, it2n_point *out,
              it2n_errinfo *err)
{
    int rc;
    if (mdl == NULL || out == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = check_args(mdl, u, w, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    eval_values(mdl, u, w, &out->v[0][0]);
    it2n__summarise(mdl, out);
    return IT2N_OK;
}

int it2n__eval_full(const it2n_model *mdl, unsigned fpmask, it2n_par u,
                    it2n_par w, it2n_val *v, it2n_val *du, it2n_val *dw,
                    it2n_errinfo *err)
{
    int32_t bu[IT2N_DIM], bw[IT2N_DIM], d[IT2N_DIM];
    unsigned bad = 0u;
    it2n__basis30(mdl->n, u, bu);
    it2n__basis30(mdl->m, w, bw);
    if (v != NULL) {
        (void)apply(mdl, fpmask, bu, 30, bw, 30, v, &bad);
    }
    if (du != NULL) {
        dbasis26(mdl->n, u, d);
        if (!apply(mdl, fpmask, d, 26, bw, 30, du, &bad)) {
            goto overflow;
        }
    }
    if (dw != NULL) {
        dbasis26(mdl->m, w, d);
        if (!apply(mdl, fpmask, bu, 30, d, 26, dw, &bad)) {
            goto overflow;
        }
    }
    return IT2N_OK;
overflow:
    return it2n__fail(err, IT2N_ERR_OVERFLOW, -1, -1, (int)(bad >> 4),
                      (int)(bad & 15u), 0, 0, 0);
}

int it2n_deriv(const it2n_model *mdl, it2n_par u, it2n_par w, it2n_point *du,
               it2n_point *dw, it2n_errinfo *err)
{
    int rc;
    if (mdl == NULL || du == NULL || dw == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = check_args(mdl, u, w, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    memset(du, 0, sizeof(*du));
    memset(dw, 0, sizeof(*dw));
    return it2n__eval_full(mdl, it2n__fp_mask(mdl->flags), u, w, NULL,
                           &du->v[0][0], &dw->v[0][0], err);
}

/* Grid parameter k / (count - 1) in Q32. */
static it2n_par grid_par(unsigned k, unsigned count)
{
    uint64_t d = count - 1u;
    return (it2n_par)it2n__udiv64_32(((uint64_t)k << IT2N_PAR_FRAC) + d / 2u, (uint32_t)d);
}

int it2n_sample(const it2n_model *mdl, unsigned rows, unsigned cols,
                it2n_sample_cb cb, void *ctx, it2n_errinfo *err)
{
    it2n_point pt;
    int32_t bu[IT2N_DIM], bw[IT2N_DIM];
    int32_t q[IT2N_FP_COUNT][IT2N_CH_COUNT][IT2N_DIM];
    unsigned r, c, mask, n1, m1;
    if (mdl == NULL || cb == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (!mdl->solved) {
        return it2n__fail(err, IT2N_ERR_STATE, -1, -1, -1, -1, 0, 0, 0);
    }
    if (rows < 2u || rows > 65535u) {
        return it2n__fail(err, IT2N_ERR_RANGE, (int)(rows > 32767u ? 32767u : rows),
                          -1, -1, -1, (it2n_val)rows, 2, 65535);
    }
    if (cols < 2u || cols > 65535u) {
        return it2n__fail(err, IT2N_ERR_RANGE, -1,
                          (int)(cols > 32767u ? 32767u : cols), -1, -1,
                          (it2n_val)cols, 2, 65535);
    }
    n1 = mdl->n + 1u;
    m1 = mdl->m + 1u;
    mask = it2n__fp_mask(mdl->flags);
    for (r = 0; r < rows; r++) {
        it2n_par u = grid_par(r, rows);
        unsigned fp, ch, i, j;
        /* Stage 1 depends on u only: once per row for every net, exactly as
         * it2n_eval computes it, so every node stays bit-identical. */
        it2n__basis30(n1 - 1u, u, bu);
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                const int32_t *net = mdl->net[fp][ch];
                for (j = 0; j < m1; j++) {
                    int64_t acc = 0;
                    for (i = 0; i < n1; i++) {
                        acc += it2n_smul32(bu[i], net[i * m1 + j]);
                    }
                    q[fp][ch][j] = (int32_t)((acc + ((int64_t)1 << 29)) >> 30);
                }
            }
        }
        for (c = 0; c < cols; c++) {
            it2n_par w = grid_par(c, cols);
            int stop;
            it2n__basis30(m1 - 1u, w, bw);
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    int64_t acc = 0;
                    if (!(mask & (1u << fp)) || !it2n__ch_used(mdl->flags, ch)) {
                        pt.v[fp][ch] = 0;
                        continue;
                    }
                    for (j = 0; j < m1; j++) {
                        acc += it2n_smul32(bw[j], q[fp][ch][j]);
                    }
                    /* a convex combination of the net: fits Q39.24 */
                    pt.v[fp][ch] = it2n__shift_round(acc, 30 + mdl->frac[fp][ch] - IT2N_VAL_FRAC);
                }
            }
            it2n__summarise(mdl, &pt);
            stop = cb(ctx, r, c, u, w, &pt);
            if (stop != 0) {
                return stop;
            }
        }
    }
    return IT2N_OK;
}
