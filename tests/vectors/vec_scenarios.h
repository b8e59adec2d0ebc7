/*
 * The fixed computations behind the core test vectors. The generator (host)
 * and the checker (host and Cortex-M3) run exactly this code, so an expected
 * value can only differ when the core computes something different.
 *
 * Freestanding C99: no heap, no float, no libc beyond memset/memcpy.
 */
#ifndef IT2N_VEC_SCENARIOS_H
#define IT2N_VEC_SCENARIOS_H

#include <stdint.h>

#include "it2n.h"

/*
 * Output stream contract: `put` is called once per recorded output, always
 * in the same order; `tag` is a static string naming the quantity (for
 * diagnostics only, never compared), `value` the exact raw result (Q24, Q32,
 * an error code, a count or a 64-bit FNV-1a hash of a larger array). `state`
 * is the caller's, passed through untouched.
 */
typedef void (*it2n_vec_put)(void *state, const char *tag, int64_t value);

/* B-spline scenario storage (records, coefficient words per model). */
#define VEC_BS_RECS 640u
#define VEC_BS_WORDS 4600u

/* Working memory for one run. Large (two data sets and two models, about
 * 50 KB at IT2N_MAX_DEGREE 7): callers keep it in static storage (.bss),
 * never on a small embedded stack. */
typedef struct it2n_vec_work {
    it2n_dataset ds, ds2;
    it2n_model a, b;
    it2n_point pt, du, dw;
    it2n_locate_result loc;
    it2n_par u[IT2N_DIM], w[IT2N_DIM];
    it2n_errinfo err;
    /* B-spline scenarios: up to 21 x 21 points type-1 or 11 x 8 type-2 */
    it2n_bspline_rec bs_rec[VEC_BS_RECS];
    int32_t bs_coef[VEC_BS_WORDS], bs_coef2[VEC_BS_WORDS];
    it2n_bspline_data bs_ds;
    it2n_bspline_model bs_a, bs_b;
} it2n_vec_work;

/* Run every scenario, streaming outputs to put(state, ...). */
void it2n_vec_scenarios(it2n_vec_work *work, it2n_vec_put put, void *state);

/* Q24 rows of the paper's 4x4 example (examples/paper_4x4.csv). */
typedef struct it2n_vec_paper_row {
    uint8_t i, j, fp;
    it2n_val x, y, t, ind, f;
} it2n_vec_paper_row;

#define IT2N_VEC_PAPER_ROWS 112
extern const it2n_vec_paper_row it2n_vec_paper[IT2N_VEC_PAPER_ROWS];

#endif /* IT2N_VEC_SCENARIOS_H */
