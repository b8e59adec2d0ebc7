/*
 * Plain floating-point baselines (float and double): the full query and the
 * solve written as a firmware engineer would, to compare the it2n core with.
 *   query  Bernstein basis by recurrence, then for each of the 7 footprints
 *          and channels x, y, T, I, F a two-stage tensor sum over the control
 *          net (along u per column, then along w), plus the interval summary
 *          (upper: min/max over LL, D, RR; lower: over LR, D, RL; T, I, F).
 *   solve  uniform parameters t_k = k/n, collocation matrices
 *          M[k][i] = B_i^n(t_k), Gauss-Jordan inverse with partial pivoting,
 *          then P = M^-1 F N^-T as two matrix products per footprint and
 *          channel.
 * The code is baseline_impl.h, compiled once per type.
 */
#ifndef BENCH_BASELINE_H
#define BENCH_BASELINE_H

#define BL_DIM 8 /* degree <= 7 */
#define BL_FP 7  /* LL, LR, L, D, R, RL, RR */
#define BL_CH 5  /* x, y, T, I, F */

#define BL_DECLARE(T, P)                                                      \
    typedef struct P##_model {                                               \
        unsigned n, m;                                                        \
        T p[BL_FP][BL_CH][BL_DIM][BL_DIM]; /* control nets p[fp][ch][i][j] */ \
    } P##_model;                                                              \
    typedef struct P##_point {                                               \
        T v[BL_FP][BL_CH];                                                    \
        T upper_min[3], upper_max[3], lower_min[3], lower_max[3];            \
    } P##_point;                                                              \
    /* data[fp][ch][k][l]: the value at grid point (k, l) */                 \
    typedef T P##_data[BL_FP][BL_CH][BL_DIM][BL_DIM];                        \
    void P##_bernstein(unsigned n, T t, T b[BL_DIM]);                         \
    /* 0, or -1 when a collocation matrix is singular */                     \
    int P##_solve(P##_model *mdl, unsigned n, unsigned m, const P##_data *f); \
    void P##_query(const P##_model *mdl, T u, T w, P##_point *out);

BL_DECLARE(float, blf)
BL_DECLARE(double, bld)

#endif /* BENCH_BASELINE_H */
