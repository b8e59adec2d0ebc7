/*
 * Evaluating the surfaces: Bernstein basis, tensor-product evaluation in two
 * stages (along u, then along w), derivatives and grid sampling.
 *
 * it2n_eval and it2n_sample share the same two stages, so a sampled node is
 * bit-identical to an evaluation at the same (u, w).
 */
#include <string.h>

#include "it2n_internal.h"

void it2n__basis(unsigned deg, it2n_par t, it2n_par b[IT2N_DIM])
{
    it2n_par s = IT2N_PAR_ONE - t;
    unsigned k, i;
    b[0] = IT2N_PAR_ONE;
    for (k = 1; k <= deg; k++) {
        /* b_k^k = t * b_{k-1}^{k-1}; b_i^k = s b_i^{k-1} + t b_{i-1}^{k-1} */
        b[k] = it2n_i128_round_fit(it2n_mul64(t, b[k - 1u]), IT2N_PAR_FRAC);
        for (i = k - 1u; i >= 1u; i--) {
            it2n_i128 acc = it2n_mac(it2n_mul64(s, b[i]), t, b[i - 1u]);
            b[i] = it2n_i128_round_fit(acc, IT2N_PAR_FRAC);
        }
        b[0] = it2n_i128_round_fit(it2n_mul64(s, b[0]), IT2N_PAR_FRAC);
    }
}

/* Derivative weights: d/dt sum_i c_i B_i^deg(t) = sum_i c_i db[i], with
 * db[i] = deg (B_{i-1}^{deg-1}(t) - B_i^{deg-1}(t)). |db[i]| <= deg. */
static void dbasis(unsigned deg, it2n_par t, it2n_par db[IT2N_DIM])
{
    it2n_par b[IT2N_DIM];
    unsigned i;
    it2n__basis(deg - 1u, t, b);
    for (i = 0; i <= deg; i++) {
        it2n_par lo = i >= 1u ? b[i - 1u] : 0;
        it2n_par hi = i < deg ? b[i] : 0;
        db[i] = (lo - hi) * (int64_t)deg;
    }
}

/* Stage along u with arbitrary (signed) weights; false on overflow. */
static bool stage_u_checked(const it2n_val *net, unsigned nb,
                            const it2n_par bu[IT2N_DIM], unsigned cols,
                            unsigned fpmask, it2n_val *q)
{
    unsigned i, j, fp, ch;
    for (j = 0; j < cols; j++) {
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            it2n_val *qo = &q[IT2N_Q_AT(j, fp, 0u)];
            if (!(fpmask & (1u << fp))) {
                memset(qo, 0, IT2N_CH_COUNT * sizeof(*qo));
                continue;
            }
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                it2n_i128 s = it2n_i128_zero();
                for (i = 0; i <= nb; i++) {
                    s = it2n_mac(s, bu[i], net[IT2N_NET_AT(i, j, fp, ch)]);
                }
                if (!it2n_i128_round(s, IT2N_PAR_FRAC, &qo[ch])) {
                    return false;
                }
            }
        }
    }
    return true;
}

void it2n__stage_u(const it2n_val *net, unsigned nb,
                   const it2n_par bu[IT2N_DIM], unsigned cols, unsigned fpmask,
                   it2n_val *q)
{
    /* Convex weights: the result lies within the inputs' range. */
    (void)stage_u_checked(net, nb, bu, cols, fpmask, q);
}

static bool stage_w_checked(const it2n_val *q, unsigned mb,
                            const it2n_par bw[IT2N_DIM], unsigned fpmask,
                            it2n_val *out)
{
    unsigned j, fp, ch;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        it2n_val *o = &out[fp * IT2N_CH_COUNT];
        if (!(fpmask & (1u << fp))) {
            memset(o, 0, IT2N_CH_COUNT * sizeof(*o));
            continue;
        }
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            it2n_i128 s = it2n_i128_zero();
            for (j = 0; j <= mb; j++) {
                s = it2n_mac(s, bw[j], q[IT2N_Q_AT(j, fp, ch)]);
            }
            if (!it2n_i128_round(s, IT2N_PAR_FRAC, &o[ch])) {
                return false;
            }
        }
    }
    return true;
}

void it2n__stage_w(const it2n_val *q, unsigned mb,
                   const it2n_par bw[IT2N_DIM], unsigned fpmask, it2n_val *out)
{
    (void)stage_w_checked(q, mb, bw, fpmask, out);
}

void it2n__summarise(const it2n_model *mdl, it2n_point *out)
{
    static const unsigned char upper[3] = {IT2N_FP_LL, IT2N_FP_D, IT2N_FP_RR};
    static const unsigned char lower[3] = {IT2N_FP_LR, IT2N_FP_D, IT2N_FP_RL};
    unsigned k, f, fp;
    bool type1 = (mdl->data.flags & IT2N_F_TYPE1) != 0u;
    out->out_of_range = 0u;
    for (k = 0; k < 3u; k++) {
        unsigned ch = IT2N_CH_T + k;
        it2n_val d = out->v[IT2N_FP_D][ch];
        out->sum.upper_min[k] = out->sum.upper_max[k] = d;
        out->sum.lower_min[k] = out->sum.lower_max[k] = d;
        for (f = 0; f < 3u && !type1; f++) {
            it2n_val a = out->v[upper[f]][ch], b = out->v[lower[f]][ch];
            if (a < out->sum.upper_min[k]) out->sum.upper_min[k] = a;
            if (a > out->sum.upper_max[k]) out->sum.upper_max[k] = a;
            if (b < out->sum.lower_min[k]) out->sum.lower_min[k] = b;
            if (b > out->sum.lower_max[k]) out->sum.lower_max[k] = b;
        }
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            it2n_val v = out->v[fp][ch];
            if (it2n_model_has_fp(mdl, fp) && (v < 0 || v > IT2N_VAL_ONE)) {
                out->out_of_range |= (uint32_t)1u << (fp * 3u + k);
            }
        }
    }
}

static bool par_ok(it2n_par t)
{
    return t >= 0 && t <= IT2N_PAR_ONE;
}

int it2n_eval(const it2n_model *mdl, it2n_par u, it2n_par w, it2n_point *out)
{
    it2n_par bu[IT2N_DIM], bw[IT2N_DIM];
    it2n_val q[IT2N_Q_SIZE];
    unsigned mask;
    if (mdl == NULL || out == NULL) {
        return IT2N_ERR_INVAL;
    }
    if (!mdl->solved) {
        return IT2N_ERR_STATE;
    }
    if (!par_ok(u) || !par_ok(w)) {
        return IT2N_ERR_RANGE;
    }
    mask = it2n__fp_mask(mdl->data.flags);
    it2n__basis(mdl->data.n, u, bu);
    it2n__basis(mdl->data.m, w, bw);
    it2n__stage_u(&mdl->ctrl[0][0][0][0], mdl->data.n, bu, mdl->data.m + 1u, mask, q);
    it2n__stage_w(q, mdl->data.m, bw, mask, &out->v[0][0]);
    it2n__summarise(mdl, out);
    return IT2N_OK;
}

int it2n__eval_full(const it2n_model *mdl, unsigned fpmask, it2n_par u,
                    it2n_par w, it2n_val *v, it2n_val *du, it2n_val *dw)
{
    it2n_par bu[IT2N_DIM], bw[IT2N_DIM], dbu[IT2N_DIM], dbw[IT2N_DIM];
    it2n_val q[IT2N_Q_SIZE];
    unsigned n = mdl->data.n, m = mdl->data.m;
    const it2n_val *net = &mdl->ctrl[0][0][0][0];
    it2n__basis(n, u, bu);
    it2n__basis(m, w, bw);
    dbasis(n, u, dbu);
    dbasis(m, w, dbw);
    it2n__stage_u(net, n, bu, m + 1u, fpmask, q);
    if (v != NULL) {
        it2n__stage_w(q, m, bw, fpmask, v);
    }
    if (!stage_w_checked(q, m, dbw, fpmask, dw) ||
        !stage_u_checked(net, n, dbu, m + 1u, fpmask, q) ||
        !stage_w_checked(q, m, bw, fpmask, du)) {
        return IT2N_ERR_OVERFLOW;
    }
    return IT2N_OK;
}

int it2n_deriv(const it2n_model *mdl, it2n_par u, it2n_par w, it2n_point *du,
               it2n_point *dw)
{
    if (mdl == NULL || du == NULL || dw == NULL) {
        return IT2N_ERR_INVAL;
    }
    if (!mdl->solved) {
        return IT2N_ERR_STATE;
    }
    if (!par_ok(u) || !par_ok(w)) {
        return IT2N_ERR_RANGE;
    }
    memset(du, 0, sizeof(*du));
    memset(dw, 0, sizeof(*dw));
    return it2n__eval_full(mdl, it2n__fp_mask(mdl->data.flags), u, w, NULL,
                           &du->v[0][0], &dw->v[0][0]);
}

/* Grid parameter k / (count - 1) in Q32. */
static it2n_par grid_par(unsigned k, unsigned count)
{
    uint64_t d = count - 1u;
    return (it2n_par)((((uint64_t)k << IT2N_PAR_FRAC) + d / 2u) / d);
}

int it2n_sample(const it2n_model *mdl, unsigned rows, unsigned cols,
                it2n_sample_cb cb, void *ctx)
{
    it2n_par bu[IT2N_DIM], bw[IT2N_DIM];
    it2n_val q[IT2N_Q_SIZE];
    it2n_point pt;
    unsigned r, c, mask;
    if (mdl == NULL || cb == NULL) {
        return IT2N_ERR_INVAL;
    }
    if (!mdl->solved) {
        return IT2N_ERR_STATE;
    }
    if (rows < 2u || cols < 2u || rows > 65535u || cols > 65535u) {
        return IT2N_ERR_RANGE;
    }
    mask = it2n__fp_mask(mdl->data.flags);
    for (r = 0; r < rows; r++) {
        it2n_par u = grid_par(r, rows);
        /* The u stage is done once per row and reused for every column. */
        it2n__basis(mdl->data.n, u, bu);
        it2n__stage_u(&mdl->ctrl[0][0][0][0], mdl->data.n, bu, mdl->data.m + 1u, mask, q);
        for (c = 0; c < cols; c++) {
            it2n_par w = grid_par(c, cols);
            int stop;
            it2n__basis(mdl->data.m, w, bw);
            it2n__stage_w(q, mdl->data.m, bw, mask, &pt.v[0][0]);
            it2n__summarise(mdl, &pt);
            stop = cb(ctx, r, c, u, w, &pt);
            if (stop != 0) {
                return stop;
            }
        }
    }
    return IT2N_OK;
}
