/*
 * Long-double reference for the core's tests: Bernstein collocation solved by
 * Gaussian elimination with partial pivoting, independent of firmware_core's
 * fixed-point code. Values are the exact decimal inputs (strtold), so the
 * difference to the core is the core's whole error (input rounding included).
 */
#ifndef TESTS_CORE_REF_H
#define TESTS_CORE_REF_H

#include "it2n.h"

#define REF_D IT2N_DIM
#define REF_FP IT2N_FP_COUNT
#define REF_CH IT2N_CH_COUNT

typedef struct ref_model {
    unsigned n, m, flags;                           /* as it2n_dataset     */
    long double data[REF_D][REF_D][REF_FP][REF_CH]; /* exact decimal data  */
    long double u[REF_D], w[REF_D];                 /* parameters          */
    long double ctrl[REF_D][REF_D][REF_FP][REF_CH]; /* control nets        */
} ref_model;

/* b[0..n] = Bernstein basis of degree n at t. */
void ref_bernstein(unsigned n, long double t, long double b[REF_D]);

/*
 * Averaged chord-length parameters (The NURBS Book, A9.3) from the x, y (and
 * z when flags has IT2N_F_Z) coordinates of footprint fp. Returns 0, or -1
 * when every row (for u) or every column (for w) is degenerate.
 */
int ref_chord_params(const ref_model *r, unsigned fp, long double u[REF_D],
                     long double w[REF_D]);

/*
 * Fill r->u, r->w (uniform, or chord from footprint chord_fp when flags has
 * IT2N_F_CHORD) and solve every control net. Returns 0 or -1 (degenerate or
 * singular).
 */
int ref_solve(ref_model *r, unsigned chord_fp);

/* Solve every control net with the parameters already in r->u, r->w. */
int ref_solve_params(ref_model *r);

/* Every footprint/channel at (u, w). */
void ref_eval(const ref_model *r, long double u, long double w,
              long double out[REF_FP][REF_CH]);

/* Central finite differences (step h) of the reference surfaces. */
void ref_deriv_fd(const ref_model *r, long double u, long double w,
                  long double h, long double du[REF_FP][REF_CH],
                  long double dw[REF_FP][REF_CH]);

#endif
