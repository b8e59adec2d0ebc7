/*
 * The benchmark's only contact with the it2n core: a few wrappers over the
 * public API (it2n_dataset_init/put, it2n_model_init/solve, it2n_eval) and
 * the reads of results. When the core's API changes, it2n_calls.c is the one
 * file to adapt. The data set, model and last point are static here.
 */
#ifndef BENCH_IT2N_CALLS_H
#define BENCH_IT2N_CALLS_H

#include <stdint.h>

#include "bench_set.h"

/* it2n_dataset_init + one it2n_dataset_put per row (Q24 values, no z). */
int bc_load(const bench_set *s);
/* it2n_model_init + it2n_model_solve of the loaded data set. */
int bc_solve(void);
/* it2n_eval at (u, w) in Q32 (0 .. 2^32 inclusive) into the last point. */
int bc_query(int64_t u_q32, int64_t w_q32);
/* From the last query: value of footprint fp, channel ch (0..4 = x, y, T,
 * I, F), Q24. */
int64_t bc_value(unsigned fp, unsigned ch);
/* From the last query: interval summary, k = 0..2 (T, I, F);
 * which = 0 upper_min, 1 upper_max, 2 lower_min, 3 lower_max. Q24. */
int64_t bc_summary(unsigned which, unsigned k);
/* Control point (i, j) of footprint fp, channel ch (0..4) of the solved
 * model, Q24. */
int64_t bc_ctrl(unsigned i, unsigned j, unsigned fp, unsigned ch);

#endif /* BENCH_IT2N_CALLS_H */
