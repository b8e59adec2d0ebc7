/*
 * Internal interfaces shared by the core's translation units.
 */
#ifndef IT2N_INTERNAL_H
#define IT2N_INTERNAL_H

#include "it2n.h"
#include "it2n_fixed.h"

/* Fill *err (when non-NULL) and return code. */
int it2n__fail(it2n_errinfo *err, int code, int i, int j, int fp, int ch, it2n_val value, it2n_val lo, it2n_val hi);

/* Bernstein basis of degree deg at t (Q32, within [0, 1]) into b[0..deg] in
 * Q30 (1.0 = 2^30) by the de Casteljau recurrence, one rounding per step. */
void it2n__basis30(unsigned deg, it2n_par t, int32_t b[IT2N_DIM]);

/* round(v / 2^s) to nearest (ties toward +inf) for s >= 1; v * 2^-s for
 * s <= 0 (the caller has proved it fits). |v| < 2^62. Inline where a
 * 64-bit shift is an instruction or two; one copy on ARMv6-M (flash). */
#if IT2N_MUL_HALVES
int64_t it2n__shift_round(int64_t v, int s);
#define IT2N__SHIFT_ROUND_DEF int64_t it2n__shift_round(int64_t v, int s)
#else
#define IT2N__SHIFT_ROUND_DEF static inline int64_t it2n__shift_round(int64_t v, int s)
#endif
#if !IT2N_MUL_HALVES || defined(IT2N__SHIFT_ROUND_HERE)
IT2N__SHIFT_ROUND_DEF
{
    if (s <= 0) {
        return (int64_t)((uint64_t)v << (unsigned)-s);
    }
    if (s >= 63) {
        return 0; /* |v| < 2^62 < 2^(s-1): rounds to zero */
    }
    return (v + ((int64_t)1 << (s - 1))) >> s;
}
#endif

/* Inverse collocation matrix of one direction in fixed point:
 * C[r][k] = (hi[r * (deg + 1) + k] * 2^24 + lo[...]) * 2^-frac, hi signed,
 * 0 <= lo < 2^24, every row's absolute sum below 2^55. Split in 32-bit
 * halves so the solve multiplies 32 x 32 -> 64 only. Low degrees also have
 * a one-word table w (C = w * 2^-wfrac, row sums below 2^31) for the short
 * solve path; w is NULL otherwise. */
typedef struct it2n__uinv {
    const int32_t *hi, *lo;
    int frac;
    const int32_t *w;
    int wfrac;
} it2n__uinv;

/* The uniform tables, degree d at index d - 1 (it2n_uniform_inv.c). */
extern const it2n__uinv it2n__uniform_inv[IT2N_MAX_DEGREE];

/*
 * Invert the collocation matrix M[r][c] = B_c^deg(t_r) in 62-bit soft
 * floating point (Gauss-Jordan, partial pivoting) and round the inverse into
 * hi[], lo[] as above, *frac its scale. IT2N_ERR_SINGULAR or
 * IT2N_ERR_OVERFLOW.
 */
int it2n__invert(unsigned deg, const it2n_par t[IT2N_DIM], int32_t hi[IT2N_DIM * IT2N_DIM],
                 int32_t lo[IT2N_DIM * IT2N_DIM], int *frac, it2n_errinfo *err) IT2N_WUR;

/* Store checked values into the compact layout; memberships have
 * IT2N_MEMB_FRAC - shift fraction bits (shift 6: Q24 input, 0: fine). */
void it2n__dataset_store(it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                         unsigned shift);

/* Validate one footprint's values for a data set with `flags`:
 * coordinates in Q24, memberships with mfrac fraction bits (IT2N_VAL_FRAC
 * or IT2N_MEMB_FRAC). Errors report Q24, a finer membership rounded down
 * (1 + 2^-24 for one just above 1) so the value shown is outside too. */
int it2n__check_vals(unsigned flags, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT], int mfrac,
                     it2n_errinfo *err) IT2N_WUR;

/* Fraction bits channel ch has in a data set: Q24 coordinates, Q30
 * memberships. The solves scale each net's exponent by it. */
static inline int it2n__ch_frac(unsigned ch)
{
    return ch >= IT2N_CH_T ? IT2N_MEMB_FRAC : IT2N_VAL_FRAC;
}

/* Check that vals (the new values of footprint fp at (i, j)) nest with the
 * stored footprints fp - 1 and fp + 1 on every coordinate axis (no-op for
 * type-1). Reports as a full check would. */
int it2n__check_nesting_point(const it2n_dataset *ds, unsigned i, unsigned j, unsigned fp,
                              const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err) IT2N_WUR;

/* Number of coordinate channels in use (2 or 3). */
static inline unsigned it2n__ncoord(unsigned flags)
{
    return (flags & IT2N_F_Z) ? 3u : 2u;
}

/* Channel `ch` is in use for these flags. */
static inline bool it2n__ch_used(unsigned flags, unsigned ch)
{
    return ch != IT2N_CH_Z || (flags & IT2N_F_Z) != 0u;
}

/* Footprint bit mask a complete grid point carries. */
static inline unsigned it2n__fp_mask(unsigned flags)
{
    return (flags & IT2N_F_TYPE1) ? (1u << IT2N_FP_D) : 0x7Fu;
}

/* Values (v, may be NULL), dS/du and dS/dw (may be NULL) of the footprints
 * in fpmask at (u, w), flat [fp][ch] arrays. IT2N_ERR_OVERFLOW (err says
 * which fp, ch) if a derivative does not fit Q39.24. */
int it2n__eval_full(const it2n_model *mdl, unsigned fpmask, it2n_par u, it2n_par w, it2n_val *v, it2n_val *du,
                    it2n_val *dw, it2n_errinfo *err);

/* it2n__eval_full for a B-spline model (values, d/du, d/dw of the
 * footprints in fpmask, all three arrays required). */
int it2n__bspline_eval_full(const it2n_bspline_model *mdl, unsigned fpmask, it2n_par u, it2n_par w, it2n_val *v,
                            it2n_val *du, it2n_val *dw, it2n_errinfo *err);

/* Fill out->sum and out->out_of_range from out->v. */
void it2n__summarise(const it2n_model *mdl, it2n_point *out);
/* The same for a model of either kind with these IT2N_F_* flags. */
void it2n__summarise_flags(unsigned flags, it2n_point *out);

/* Parameter within [0, 1] (Q32). */
static inline bool it2n__par_ok(it2n_par t)
{
    return t >= 0 && t <= IT2N_PAR_ONE;
}

/* Common parameter check of the evaluation entry points: IT2N_ERR_RANGE
 * (err->value the parameter in Q24, ch 0 for u, 1 for w) unless both are
 * within [0, 1]. */
static inline int it2n__check_uw(it2n_par u, it2n_par w, it2n_errinfo *err)
{
    if (!it2n__par_ok(u) || !it2n__par_ok(w)) {
        it2n_par bad = it2n__par_ok(u) ? w : u;
        /* value in Q24 (parameters are Q32; saturate far-off values) */
        it2n_val v = bad > ((int64_t)1 << 60) ? INT64_MAX >> 8 : bad < -((int64_t)1 << 60) ? INT64_MIN >> 8 : bad >> 8;
        return it2n__fail(err, IT2N_ERR_RANGE, -1, -1, -1, it2n__par_ok(u) ? 1 : 0, v, 0, IT2N_VAL_ONE);
    }
    return IT2N_OK;
}

/* Grid size check of it2n_sample and it2n_bspline_sample: IT2N_ERR_RANGE
 * (i names rows, j cols, clamped to an int16; value the size, lo 2, hi
 * 65535) unless both are within 2..65535 (it2n_eval.c). */
int it2n__check_grid(unsigned rows, unsigned cols, it2n_errinfo *err);

/* B-spline coefficient net of footprint fp, channel ch, as the solve lays
 * them out in mdl->coef (footprint-major, channels x, y, [z], T, I, F; a
 * type-1 model holds D only), (n + 3) x (m + 3) each. */
static inline int32_t *it2n__bspline_net(const it2n_bspline_model *mdl, unsigned fp, unsigned ch)
{
    unsigned nch = IT2N_BSPLINE_NCH(mdl->flags);
    unsigned slot = (mdl->flags & IT2N_F_TYPE1) ? 0u : fp;
    unsigned c = (ch > IT2N_CH_Z && nch == 5u) ? ch - 1u : ch;
    size_t size = (size_t)(mdl->n + 3u) * (mdl->m + 3u);
    return mdl->coef + (slot * nch + c) * size;
}

/* B-spline solve: round(2^32 / d_k), the reciprocal of pivot k of the
 * (1, 4, 1) elimination (it2n_bspline.c; the tests recompute the table). */
uint32_t it2n__bspline_pivot_inv(unsigned k);

#endif /* IT2N_INTERNAL_H */
