/*
 * Internal interfaces shared by the core's translation units.
 */
#ifndef IT2N_INTERNAL_H
#define IT2N_INTERNAL_H

#include "it2n.h"
#include "it2n_fixed.h"

/* Fill *err (when non-NULL) and return code. */
int it2n__fail(it2n_errinfo *err, int code, int i, int j, int fp, int ch,
               it2n_val value, it2n_val lo, it2n_val hi);

/* Bernstein basis of degree deg at t (Q32, within [0,1]) into b[0..deg],
 * Q32, by the de Casteljau recurrence (every value in [0, 1]). */
void it2n__basis(unsigned deg, it2n_par t, it2n_par b[IT2N_DIM]);

/* Validate one footprint's values for a data set with `flags`. */
int it2n__check_vals(unsigned flags, unsigned i, unsigned j, unsigned fp,
                     const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err)
    IT2N_WUR;

/* Check the nesting LL <= ... <= RR of one grid point's footprints on every
 * coordinate axis (no-op for type-1). */
int it2n__check_nesting(unsigned flags, unsigned i, unsigned j,
                        const it2n_val *pt, it2n_errinfo *err) IT2N_WUR;

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

/* Flat indexing of a control net (it2n_model.ctrl) and of a stage-1 row. */
#define IT2N_NET_AT(i, j, fp, ch) \
    ((((i) * IT2N_DIM + (j)) * IT2N_FP_COUNT + (fp)) * IT2N_CH_COUNT + (ch))
#define IT2N_Q_AT(j, fp, ch) (((j) * IT2N_FP_COUNT + (fp)) * IT2N_CH_COUNT + (ch))
#define IT2N_Q_SIZE (IT2N_DIM * IT2N_FP_COUNT * IT2N_CH_COUNT)

/*
 * Stage 1 of tensor evaluation along u: q[j][fp][ch] =
 * round(sum_i bu[i] * net[i][j][fp][ch]) for i = 0..nb, j < cols. Values stay
 * in Q24 and are convex combinations, so they cannot overflow.
 */
void it2n__stage_u(const it2n_val *net, unsigned nb,
                   const it2n_par bu[IT2N_DIM], unsigned cols, unsigned fpmask,
                   it2n_val *q);

/* Stage 2 along w: out[fp][ch] = round(sum_j bw[j] * q[j][fp][ch]). */
void it2n__stage_w(const it2n_val *q, unsigned mb,
                   const it2n_par bw[IT2N_DIM], unsigned fpmask, it2n_val *out);

/* Values (v, may be NULL), dS/du and dS/dw of the footprints in fpmask at
 * (u, w), flat [fp][ch] arrays. IT2N_ERR_OVERFLOW if a derivative does not
 * fit. */
int it2n__eval_full(const it2n_model *mdl, unsigned fpmask, it2n_par u,
                    it2n_par w, it2n_val *v, it2n_val *du, it2n_val *dw);

/* Fill out->sum and out->out_of_range from out->v. */
void it2n__summarise(const it2n_model *mdl, it2n_point *out);

#endif /* IT2N_INTERNAL_H */
