/*
 * Locate: for a location (x, y), find on each footprint surface the (u, w)
 * whose (x, y) coordinates match, and report the memberships there.
 *
 * Newton's method on the 2x2 system, started from the best node of a coarse
 * parameter grid. The safe fallback is step halving: a step is taken only if
 * it reduces the residual, and iterates are clamped to [0, 1]^2. An iterate
 * stuck on the boundary means the location lies outside the surface's image.
 */
#include <string.h>

#include "it2n_internal.h"
#include "it2n_xf.h"

#define COORD_MAX ((it2n_val)IT2N_COORD_LIMIT << IT2N_VAL_FRAC)

/* The model being located on, of either kind, and the convergence
 * tolerance per footprint. Its evaluation (values and derivatives of the
 * footprints in fpmask) is a constant argument of the always-inlined
 * search below: each entry point gets its own copy with direct calls, so
 * an application using one kind links only that kind's code and the stack
 * analysis sees every call. */
typedef int (*loc_eval_fn)(const void *mdl, unsigned fpmask, it2n_par u, it2n_par w, it2n_val *v, it2n_val *du,
                           it2n_val *dw);
typedef struct loc_model {
    const void *mdl;
    int64_t tol[IT2N_FP_COUNT];
} loc_model;

typedef struct loc_state {
    it2n_par u, w;
    it2n_val v[IT2N_FP_COUNT][IT2N_CH_COUNT];
    it2n_val du[IT2N_FP_COUNT][IT2N_CH_COUNT];
    it2n_val dw[IT2N_FP_COUNT][IT2N_CH_COUNT];
    int64_t rx, ry, res;
} loc_state;

static int64_t abs64(int64_t v)
{
    return v < 0 ? -v : v;
}

/* Evaluate footprint fp at (u, w) into st; false on derivative overflow. */
IT2N_INLINE bool probe(const loc_model *mdl, loc_eval_fn eval, unsigned fp, it2n_par u, it2n_par w, it2n_val x,
                       it2n_val y, loc_state *st)
{
    int64_t ax, ay;
    st->u = u;
    st->w = w;
    if (eval(mdl->mdl, 1u << fp, u, w, &st->v[0][0], &st->du[0][0], &st->dw[0][0]) != IT2N_OK) {
        return false;
    }
    /* Surface points lie in the control net's hull (< 2^62): no overflow. */
    st->rx = st->v[fp][IT2N_CH_X] - x;
    st->ry = st->v[fp][IT2N_CH_Y] - y;
    ax = abs64(st->rx);
    ay = abs64(st->ry);
    st->res = ax > ay ? ax : ay;
    return true;
}

static unsigned bitlen(uint64_t v)
{
    unsigned k = 0;
    while (v != 0u && k < 64u) {
        v >>= 1;
        k++;
    }
    return k;
}

/* Arithmetic shift right that is well defined for negatives. */
static int64_t shr(int64_t v, unsigned s)
{
    return v < 0 ? -(int64_t)((uint64_t)(-v) >> s) : (int64_t)((uint64_t)v >> s);
}

/*
 * Newton step (du, dw) in Q32 solving J d = -r by Cramer's rule in the soft
 * float (range without scaling tricks); false if J is singular.
 */
static bool newton_step(const loc_state *st, unsigned fp, int64_t *su, int64_t *sw)
{
    it2n__xf xu, xw, yu, yw, rx, ry, det, p, q;
    it2n__xf_set(&xu, st->du[fp][IT2N_CH_X], 0);
    it2n__xf_set(&xw, st->dw[fp][IT2N_CH_X], 0);
    it2n__xf_set(&yu, st->du[fp][IT2N_CH_Y], 0);
    it2n__xf_set(&yw, st->dw[fp][IT2N_CH_Y], 0);
    it2n__xf_set(&rx, st->rx, 0);
    it2n__xf_set(&ry, st->ry, 0);
    it2n__xf_mul(&p, &xu, &yw);
    it2n__xf_mul(&q, &xw, &yu);
    it2n__xf_sub(&det, &p, &q);
    if (det.m == 0) {
        return false;
    }
    /* du = (xw ry - yw rx) / det, dw = (yu rx - xu ry) / det */
    it2n__xf_mul(&p, &xw, &ry);
    it2n__xf_mul(&q, &yw, &rx);
    it2n__xf_sub(&p, &p, &q);
    it2n__xf_div(&p, &p, &det);
    *su = it2n__xf_to_q32(&p);
    it2n__xf_mul(&p, &yu, &rx);
    it2n__xf_mul(&q, &xu, &ry);
    it2n__xf_sub(&p, &p, &q);
    it2n__xf_div(&p, &p, &det);
    *sw = it2n__xf_to_q32(&p);
    return true;
}

static it2n_par clamp01(int64_t t)
{
    return t < 0 ? 0 : (t > IT2N_PAR_ONE ? IT2N_PAR_ONE : t);
}

static bool on_boundary(const loc_state *st)
{
    return st->u == 0 || st->u == IT2N_PAR_ONE || st->w == 0 || st->w == IT2N_PAR_ONE;
}

/* Convergence tolerance: ~1e-6 absolute plus ~1e-6 of the net's extent,
 * since basis rounding scales with the control points. */
static int64_t tol_of(int64_t big)
{
    return 16 + (big >> 20);
}

/* The largest |Q24 control point| of the x and y nets of fp. */
static int64_t bz_extent(const it2n_model *mdl, unsigned fp)
{
    int64_t big = 0;
    unsigned k, ch, count = (mdl->n + 1u) * (mdl->m + 1u);
    for (ch = IT2N_CH_X; ch <= IT2N_CH_Y; ch++) {
        /* rounding is monotone: the largest |Q24 control point| comes from
         * the largest and the smallest mantissa */
        int32_t lo = 0, hi = 0;
        int s = mdl->frac[fp][ch] - IT2N_VAL_FRAC;
        int64_t a, b;
        for (k = 0; k < count; k++) {
            int32_t v = mdl->net[fp][ch][k];
            lo = v < lo ? v : lo;
            hi = v > hi ? v : hi;
        }
        a = it2n__shift_round(hi, s);
        b = -it2n__shift_round(lo, s);
        big = a > big ? a : big;
        big = b > big ? b : big;
    }
    return big;
}

/* The same bound for a B-spline model: a net's largest |mantissa| is in
 * [2^30, 2^31) by construction, so 2^31 bounds it, O(1) whatever the grid.
 * An all-zero net has exponent 0 (as have nets near 2^31 units): only then
 * are its coefficients read. */
static int64_t bs_extent(const it2n_bspline_model *mdl, unsigned fp)
{
    int64_t big = 0;
    unsigned ch, r, c;
    for (ch = IT2N_CH_X; ch <= IT2N_CH_Y; ch++) {
        if (mdl->frac[fp][ch] != 0) {
            int64_t a = it2n__shift_round(INT32_MAX, mdl->frac[fp][ch] - IT2N_VAL_FRAC);
            big = a > big ? a : big;
            continue;
        }
        for (r = 0; r <= mdl->n + 2u; r++) {
            for (c = 0; c <= mdl->m + 2u; c++) {
                it2n_val q = it2n_bspline_coef(mdl, r, c, fp, ch);
                q = q < 0 ? -q : q;
                big = q > big ? q : big;
            }
        }
    }
    return big;
}

IT2N_INLINE void locate_fp(const loc_model *mdl, loc_eval_fn eval, unsigned fp, it2n_val x, it2n_val y,
                           it2n_locate_fp *out)
{
    loc_state best, cand;
    int64_t tol = mdl->tol[fp];
    unsigned a, b, it;
    uint8_t status = IT2N_LOC_NOCONV;
    bool have = false;
    memset(&best, 0, sizeof(best));
    for (a = 0; a <= IT2N_LOCATE_GRID; a++) {
        for (b = 0; b <= IT2N_LOCATE_GRID; b++) {
            it2n_par u = (it2n_par)(((uint64_t)a << IT2N_PAR_FRAC) / IT2N_LOCATE_GRID);
            it2n_par w = (it2n_par)(((uint64_t)b << IT2N_PAR_FRAC) / IT2N_LOCATE_GRID);
            if (probe(mdl, eval, fp, u, w, x, y, &cand) && (!have || cand.res < best.res)) {
                best = cand;
                have = true;
            }
        }
    }
    if (!have) {
        memset(out, 0, sizeof(*out));
        out->status = IT2N_LOC_NOCONV;
        return;
    }
    for (it = 0; it < IT2N_LOCATE_MAX_ITER; it++) {
        int64_t su, sw, mag;
        unsigned half;
        bool moved = false;
        if (best.res <= tol / 16) {
            break; /* polished well below the tolerance */
        }
        if (!newton_step(&best, fp, &su, &sw)) {
            break;
        }
        /* Limit a step to half the square: Newton far from the root can
         * overshoot wildly. */
        mag = abs64(su) > abs64(sw) ? abs64(su) : abs64(sw);
        if (mag > IT2N_PAR_ONE / 2) {
            unsigned s = bitlen((uint64_t)mag) - 31u;
            su = shr(su, s);
            sw = shr(sw, s);
        }
        for (half = 0; half < 24u; half++) {
            it2n_par u = clamp01(best.u + su), w = clamp01(best.w + sw);
            if ((u != best.u || w != best.w) && probe(mdl, eval, fp, u, w, x, y, &cand) && cand.res < best.res) {
                best = cand;
                moved = true;
                break;
            }
            su = shr(su, 1u);
            sw = shr(sw, 1u);
        }
        if (!moved) {
            break;
        }
    }
    if (best.res <= tol) {
        status = IT2N_LOC_INSIDE;
    } else if (on_boundary(&best)) {
        status = IT2N_LOC_OUTSIDE;
    }
    out->u = best.u;
    out->w = best.w;
    memcpy(out->v, best.v[fp], sizeof(out->v));
    out->residual = best.res;
    out->status = status;
}

/* Both kinds: range checks, then every footprint the model carries. */
IT2N_INLINE int locate_all(const loc_model *lm, loc_eval_fn eval, unsigned flags, it2n_val x, it2n_val y,
                           it2n_locate_result *out, it2n_errinfo *err)
{
    unsigned fp;
    if (x < -COORD_MAX || x > COORD_MAX) {
        return it2n__fail(err, IT2N_ERR_RANGE, -1, -1, -1, IT2N_CH_X, x, -COORD_MAX, COORD_MAX);
    }
    if (y < -COORD_MAX || y > COORD_MAX) {
        return it2n__fail(err, IT2N_ERR_RANGE, -1, -1, -1, IT2N_CH_Y, y, -COORD_MAX, COORD_MAX);
    }
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if ((it2n__fp_mask(flags) & (1u << fp)) != 0u) {
            locate_fp(lm, eval, fp, x, y, &out->fp[fp]);
        } else {
            memset(&out->fp[fp], 0, sizeof(out->fp[fp]));
            out->fp[fp].status = IT2N_LOC_NOCONV;
        }
    }
    return IT2N_OK;
}

static int bz_eval(const void *mdl, unsigned fpmask, it2n_par u, it2n_par w, it2n_val *v, it2n_val *du, it2n_val *dw)
{
    return it2n__eval_full((const it2n_model *)mdl, fpmask, u, w, v, du, dw, NULL);
}

static int bs_eval(const void *mdl, unsigned fpmask, it2n_par u, it2n_par w, it2n_val *v, it2n_val *du, it2n_val *dw)
{
    return it2n__bspline_eval_full((const it2n_bspline_model *)mdl, fpmask, u, w, v, du, dw, NULL);
}

int it2n_locate(const it2n_model *mdl, it2n_val x, it2n_val y, it2n_locate_result *out, it2n_errinfo *err)
{
    loc_model lm;
    unsigned fp;
    if (mdl == NULL || out == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (!mdl->solved) {
        return it2n__fail(err, IT2N_ERR_STATE, -1, -1, -1, -1, 0, 0, 0);
    }
    lm.mdl = mdl;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        lm.tol[fp] = it2n_model_has_fp(mdl, fp) ? tol_of(bz_extent(mdl, fp)) : 0;
    }
    return locate_all(&lm, bz_eval, mdl->flags, x, y, out, err);
}

int it2n_bspline_locate(const it2n_bspline_model *mdl, it2n_val x, it2n_val y, it2n_locate_result *out,
                        it2n_errinfo *err)
{
    loc_model lm;
    unsigned fp;
    if (mdl == NULL || out == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (!mdl->solved || mdl->coef == NULL) {
        return it2n__fail(err, IT2N_ERR_STATE, -1, -1, -1, -1, 0, 0, 0);
    }
    lm.mdl = mdl;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        lm.tol[fp] = (it2n__fp_mask(mdl->flags) & (1u << fp)) != 0u ? tol_of(bs_extent(mdl, fp)) : 0;
    }
    return locate_all(&lm, bs_eval, mdl->flags, x, y, out, err);
}
