/*
 * Shared helpers of the core tests: test cases held as exact decimals (for
 * the reference) plus their Q24 conversion (for the core), generators, the
 * issue's tolerances, and a deterministic PRNG.
 */
#ifndef TESTS_CORE_TC_UTIL_H
#define TESTS_CORE_TC_UTIL_H

#include "it2n.h"
#include "ref.h"

#define TC_Q24 16777216.0L   /* 2^24 */
#define TC_Q32 4294967296.0L /* 2^32 */

/* One data set: v[] are the exact decimals, q[] what the core is given, in
 * the fine layout (x, y, z Q24, T, I, F Q30: it2n_dataset_put_fine). */
typedef struct tc_case {
    unsigned n, m, flags;
    long double v[REF_D][REF_D][REF_FP][REF_CH];
    it2n_val q[REF_D][REF_D][REF_FP][REF_CH];
} tc_case;

/* Decimal string -> Q24 / Q32 through the core's parser, cross-checked
 * against llroundl(strtold(s) * 2^k) (exact for <= 6 decimals). */
it2n_val tc_q24(const char *s);
it2n_par tc_q32(const char *s);
/* Decimal string -> Q30 membership through it2n_parse_memb, cross-checked
 * likewise. */
it2n_val tc_q30(const char *s);
/* Round x to 6 decimals; store the decimal in *exact and return Q24. */
it2n_val tc_q24_dec6(long double x, long double *exact);
/* The same in channel ch's format in q[] (Q30 for T, I, F). */
it2n_val tc_fine_dec6(unsigned ch, long double x, long double *exact);

#define TC_Q30 1073741824.0L /* 2^30 */

static inline long double tc_ld(it2n_val v) { return (long double)v / TC_Q24; }
/* A value of q[] (channel ch) as a number. */
static inline long double tc_ldq(unsigned ch, it2n_val v)
{
    return (long double)v / (ch >= IT2N_CH_T ? TC_Q30 : TC_Q24);
}
static inline long double tc_ldp(it2n_par p) { return (long double)p / TC_Q32; }

/* Set one value of a case (rounded to 6 decimals). */
void tc_set(tc_case *c, unsigned i, unsigned j, unsigned fp, unsigned ch,
            long double x);
/* Empty case of degrees n x m. */
void tc_init(tc_case *c, unsigned n, unsigned m, unsigned flags);
/* The paper's 4x4 example (examples/paper_4x4.csv), embedded. */
void tc_paper(tc_case *c);
/* Smooth generated data: x ~ scale*i/n, y ~ scale*j/m, small perturbation,
 * footprints nested with spacing scale/40; memberships 0.5 +- 0.3 sin(). */
void tc_smooth(tc_case *c, unsigned n, unsigned m, unsigned flags,
               long double scale, unsigned seed);
/* Worst case for the value range: degree IT2N_MAX_DEGREE both ways, x, y, z
 * alternating near +-IT2N_COORD_LIMIT, memberships alternating 0/1. */
void tc_extreme(tc_case *c);
/* Footprint present in this case? */
bool tc_has_fp(const tc_case *c, unsigned fp);
/* Largest |coordinate| in the case. */
long double tc_maxabs(const tc_case *c);

/* Values of q[] (fine layout) in Q24, memberships rounded as
 * it2n_dataset_get does, for the Q24 entry points. */
void tc_q24_vals(const it2n_val fine[IT2N_CH_COUNT], it2n_val out[IT2N_CH_COUNT]);

/* Build the core data set (cmocka-asserts every call succeeds). */
void tc_dataset(const tc_case *c, it2n_dataset *ds);
/* Build and solve the core model (asserts success). */
void tc_model(const tc_case *c, it2n_model *mdl);
/* Build the data set into *ds and solve *mdl from it (asserts success). */
void tc_model_ds(const tc_case *c, it2n_model *mdl, it2n_dataset *ds);
/* Every byte of two models but the generation counter is equal. */
bool tc_nets_equal(const it2n_model *a, const it2n_model *b);
/* The core's collocation parameters for the case (it2n_params). */
void tc_params(const tc_case *c, it2n_par u[IT2N_DIM], it2n_par w[IT2N_DIM]);
/* Build and solve the reference model (chord params from footprint D). */
void tc_ref(const tc_case *c, ref_model *r);

/* The tolerances for degrees n x m. */
long double tc_tol_memb(unsigned n, unsigned m);
long double tc_tol_coord(unsigned n, unsigned m, long double maxabs);

/* Deterministic xorshift64*. */
uint64_t tc_rand(uint64_t *s);
/* A random parameter with 6 decimals: exact value and Q32 for the core. */
long double tc_rand_par(uint64_t *s, it2n_par *q);

#endif
