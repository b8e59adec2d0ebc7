/*
 * it2n — interval type-2 neutrosophic Bézier surface (IT2NBS) interpolation.
 *
 * Portable C99 core: fixed-point only, no heap, no floating point, no global
 * mutable state. All memory is in the structs below, sized at compile time
 * and owned by the caller. See docs/numerics.md for every Q format.
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#ifndef IT2N_H
#define IT2N_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* ---- Compile-time options ------------------------------------------------ */

/* Set every option in one place: build with -DIT2N_CONFIG=my_it2n_config.h
 * (a header on the include path that #defines the options below); options
 * it leaves out keep their defaults. -D flags work as well. */
#ifdef IT2N_CONFIG
#define IT2N_STRINGIZE_(x) #x
#define IT2N_STRINGIZE(x) IT2N_STRINGIZE_(x)
#include IT2N_STRINGIZE(IT2N_CONFIG)
#endif

/* Largest polynomial degree in either direction (grid up to (D+1)x(D+1)).
 * Memory grows with (D+1)^2; 7 is the documented default. */
#ifndef IT2N_MAX_DEGREE
#define IT2N_MAX_DEGREE 7
#endif

/* Largest |coordinate| accepted on input, in whole units. With the worst
 * degree-7 amplification of the inverse collocation matrices (~4.4e4) the
 * control points still fit the Q39.24 value type. */
#ifndef IT2N_COORD_LIMIT
#define IT2N_COORD_LIMIT 8388607
#endif

/* Chord-length parameterisation (IT2N_F_CHORD). 0 leaves out its run-time
 * inverse and parameter code (about 2 KB of Cortex-M0+ flash); data sets
 * asking for it are then refused with IT2N_ERR_INVAL. */
#ifndef IT2N_CHORD
#define IT2N_CHORD 1
#endif

/* Newton iterations per footprint in it2n_locate before giving up. */
#ifndef IT2N_LOCATE_MAX_ITER
#define IT2N_LOCATE_MAX_ITER 40
#endif

/* Coarse start grid for it2n_locate (per direction). */
#ifndef IT2N_LOCATE_GRID
#define IT2N_LOCATE_GRID 8
#endif

/* Check of an internal invariant (a core bug, never bad input: bad input
 * gets an IT2N_ERR_* code). Off by default; the sanitizer test build traps.
 * Define as e.g. ((c) ? (void)0 : my_fault_handler()) on a target. */
#ifndef IT2N_ASSERT
#define IT2N_ASSERT(c) ((void)0)
#endif

#if IT2N_MAX_DEGREE < 1 || IT2N_MAX_DEGREE > 15
#error "IT2N_MAX_DEGREE must be within 1..15"
#endif

/* The overflow-free solve bound (docs/numerics.md) assumes |coordinate| <
 * 2^23 in Q24; larger limits would let control points leave int64. */
#if IT2N_COORD_LIMIT < 1 || IT2N_COORD_LIMIT > 8388607
#error "IT2N_COORD_LIMIT must be within 1..8388607"
#endif

/* Largest number of intervals n, m per direction of a B-spline model (grid
 * up to (n+1) x (n+1) points, see "B-spline kind" below). Bounds the solve's
 * stack (about 11 bytes per interval on MCUs, 20 on 64-bit hosts, which
 * solve two lines at a time); MCU builds with small grids set it lower, to
 * the largest grid their static storage holds (docs/firmware.md "B-spline
 * grids on an MCU": bytes per grid point, the largest grid in 32 KiB and
 * 128 KiB). Storage itself is the caller's and sized per grid. Part of the
 * link-time names (ABI guard below): a plain decimal literal. */
#ifndef IT2N_BSPLINE_MAX_N
#define IT2N_BSPLINE_MAX_N 255
#endif

#if IT2N_BSPLINE_MAX_N < 1 || IT2N_BSPLINE_MAX_N > 255
#error "IT2N_BSPLINE_MAX_N must be within 1..255"
#endif

#if IT2N_LOCATE_GRID < 1 || IT2N_LOCATE_GRID > 64 || IT2N_LOCATE_MAX_ITER < 1
#error "IT2N_LOCATE_GRID must be within 1..64 and IT2N_LOCATE_MAX_ITER >= 1"
#endif

/* Link-time ABI guard. it2n_dataset and it2n_model are sized by
 * IT2N_MAX_DEGREE, and IT2N_CHORD decides which flags the library accepts:
 * a program compiled with other values than the library would overrun
 * them. So the functions every use of those structs starts with are named
 * after the values (it2n_dataset_init_abi_degree7_chord1, say), and such a
 * program fails to link ("undefined reference to
 * it2n_dataset_init_abi_degree3_chord1": it asked for degree 3, `nm` on the
 * library shows what it was built with). Callers just write
 * it2n_dataset_init. IT2N_MAX_DEGREE must be a plain decimal literal. */
#if IT2N_CHORD
#define IT2N_ABI_CHORD_ 1
#else
#define IT2N_ABI_CHORD_ 0
#endif
#define IT2N_ABI_CORE_(f, d, c) f##_abi_degree##d##_chord##c
#define IT2N_ABI_CORE(f, d, c) IT2N_ABI_CORE_(f, d, c)
#define IT2N_CORE_ABI(f) IT2N_ABI_CORE(f, IT2N_MAX_DEGREE, IT2N_ABI_CHORD_)
#define it2n_dataset_init IT2N_CORE_ABI(it2n_dataset_init)
#define it2n_model_init IT2N_CORE_ABI(it2n_model_init)
/* IT2N_BSPLINE_MAX_N sizes no struct (B-spline storage is the caller's),
 * but a firmware sizes its storage for a largest grid and checks it
 * against this limit at compile time (examples/firmware/survey.c): a
 * library built with a smaller one would refuse that grid at run time. So
 * it2n_bspline_data_init carries it too (..._abi_bspline63) and such a
 * program fails to link instead. A plain decimal literal. */
#define IT2N_ABI_BSPLINE_(f, n) f##_abi_bspline##n
#define IT2N_ABI_BSPLINE(f, n) IT2N_ABI_BSPLINE_(f, n)
#define it2n_bspline_data_init IT2N_ABI_BSPLINE(it2n_bspline_data_init, IT2N_BSPLINE_MAX_N)

/* ---- Fixed-point formats ------------------------------------------------ */

/* it2n_val: coordinates, memberships, control points, results, derivatives.
 * Signed Q39.24 in int64_t: value = raw / 2^24. Every function takes and
 * returns this format unless its name ends in _fine (below). */
typedef int64_t it2n_val;
#define IT2N_VAL_FRAC 24
#define IT2N_VAL_ONE ((it2n_val)1 << IT2N_VAL_FRAC)

/* Memberships T, I, F as data sets store them: Q30, raw / 2^30 in
 * [0, 2^30] (uint32_t in the data sets). A degree-7 Bezier inverse
 * amplifies input rounding up to 4.4e4 times: Q24 input (rounding up to
 * 3e-8) moves a control net by up to 1.3e-3, Q30 by up to 2e-5 (measured on
 * 6-decimal data: 5e-4 and 7e-6). The _fine functions (it2n_dataset_put_fine,
 * ..., it2n_parse_memb) take and give memberships in this format, x, y, z
 * still in Q24: an array vals[IT2N_CH_COUNT] "in the fine layout" is
 * x, y, z in Q24 and T, I, F in Q30. The Q24 functions convert at the edge:
 * a Q24 membership is stored exactly (times 2^6), a stored one is read back
 * rounded to Q24 (to nearest, ties up). Results (evaluation, control points,
 * coefficients) stay Q24: their rounding, 3e-8, is within every goal. */
#define IT2N_MEMB_FRAC 30
#define IT2N_MEMB_ONE ((it2n_val)1 << IT2N_MEMB_FRAC)

/* it2n_par: surface parameters u, w and basis values. Q31.32 in int64_t:
 * value = raw / 2^32, so 1.0 is exactly representable. */
typedef int64_t it2n_par;
#define IT2N_PAR_FRAC 32
#define IT2N_PAR_ONE ((it2n_par)1 << IT2N_PAR_FRAC)

/* ---- Errors ------------------------------------------------------------- */

/* Negative codes so functions can return a count or an error. */
enum it2n_error {
    IT2N_OK = 0,
    IT2N_ERR_INVAL = -1,      /* bad argument (degree, index, flags)      */
    IT2N_ERR_RANGE = -2,      /* value outside its accepted range         */
    IT2N_ERR_DUPLICATE = -3,  /* (i, j, footprint) given twice            */
    IT2N_ERR_MISSING = -4,    /* (i, j, footprint) absent                 */
    IT2N_ERR_ORDER = -5,      /* footprints not nested on an axis         */
    IT2N_ERR_OVERFLOW = -6,   /* intermediate result not representable    */
    IT2N_ERR_SINGULAR = -7,   /* collocation matrix singular              */
    IT2N_ERR_DEGENERATE = -8, /* degenerate chord-length parameterisation */
    IT2N_ERR_STATE = -9,      /* model not solved / wrong kind            */
    IT2N_ERR_NOCONV = -10     /* iteration did not converge               */
};

/* Footprints, in nesting order on every coordinate axis. */
enum it2n_fp { IT2N_FP_LL = 0, IT2N_FP_LR, IT2N_FP_L, IT2N_FP_D, IT2N_FP_R, IT2N_FP_RL, IT2N_FP_RR, IT2N_FP_COUNT };

/* Channels of one footprint surface. */
enum it2n_ch { IT2N_CH_X = 0, IT2N_CH_Y, IT2N_CH_Z, IT2N_CH_T, IT2N_CH_I, IT2N_CH_F, IT2N_CH_COUNT };

/* Where and why an operation failed; filled on every error. */
typedef struct it2n_errinfo {
    int code;        /* enum it2n_error                                  */
    int16_t i, j;    /* grid point, or -1                                */
    int8_t fp;       /* footprint, or -1                                 */
    int8_t ch;       /* channel, or -1                                   */
    it2n_val value;  /* offending value (Q24), when meaningful           */
    it2n_val lo, hi; /* accepted range or neighbour bound (Q24)          */
} it2n_errinfo;

/* ---- Data set ----------------------------------------------------------- */

#define IT2N_DIM (IT2N_MAX_DEGREE + 1)

/* Model flags (it2n_dataset.flags). */
#define IT2N_F_Z 0x01u     /* coordinates carry z                   */
#define IT2N_F_TYPE1 0x02u /* only footprint D (type-1 neutrosophic) */
#define IT2N_F_CHORD 0x04u /* chord-length params instead of uniform */
/* Flags this build accepts. */
#define IT2N_F_ALL (IT2N_F_Z | IT2N_F_TYPE1 | (IT2N_CHORD ? IT2N_F_CHORD : 0u))

/* Grid data being assembled. present[i][j] is a bit mask of the footprints
 * given. Values are stored compactly (read them with it2n_dataset_get,
 * it2n_dataset_get_fine or it2n_dataset_value): a coordinate in Q24
 * (|x| < 2^47) as its low 32 bits in coord_lo and high 16 bits in coord_hi,
 * a membership in Q30 (IT2N_MEMB_FRAC, in [0, 2^30]) in memb. Unused z
 * channels are zero. 30 bytes per grid point and footprint instead of 48. */
typedef struct it2n_dataset {
    uint32_t coord_lo[IT2N_DIM][IT2N_DIM][IT2N_FP_COUNT][3]; /* x, y, z */
    uint32_t memb[IT2N_DIM][IT2N_DIM][IT2N_FP_COUNT][3];     /* T, I, F */
    int16_t coord_hi[IT2N_DIM][IT2N_DIM][IT2N_FP_COUNT][3];
    uint8_t n, m;  /* degrees: grid is (n+1) x (m+1) */
    uint8_t flags; /* IT2N_F_*                       */
    uint8_t present[IT2N_DIM][IT2N_DIM];
} it2n_dataset;

/* Channel ch of footprint fp at grid point (i, j) in the fine layout: a
 * coordinate in Q24, a membership in Q30 (no bounds checks: i, j <
 * IT2N_DIM, fp < IT2N_FP_COUNT, ch < IT2N_CH_COUNT). */
static inline it2n_val it2n_dataset_value_fine(const it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, unsigned ch)
{
    if (ch >= 3u) {
        return (it2n_val)ds->memb[i][j][fp][ch - 3u];
    }
    return (it2n_val)((uint64_t)(int64_t)ds->coord_hi[i][j][fp][ch] * 4294967296u | ds->coord_lo[i][j][fp][ch]);
}

/* The same in Q24 for every channel (a membership rounded to nearest, ties
 * up). */
static inline it2n_val it2n_dataset_value(const it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, unsigned ch)
{
    it2n_val v = it2n_dataset_value_fine(ds, i, j, fp, ch);
    if (ch >= 3u) {
        return (v + ((it2n_val)1 << (IT2N_MEMB_FRAC - IT2N_VAL_FRAC - 1))) >> (IT2N_MEMB_FRAC - IT2N_VAL_FRAC);
    }
    return v;
}

/* All channels of footprint fp at (i, j) into vals (Q24; memberships
 * rounded to nearest, ties up). */
void it2n_dataset_get(const it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, it2n_val vals[IT2N_CH_COUNT]);

/* The same in the fine layout (memberships in Q30, exactly as stored). */
void it2n_dataset_get_fine(const it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, it2n_val vals[IT2N_CH_COUNT]);

/*
 * Start an empty data set of degrees n x m (1..IT2N_MAX_DEGREE each) with
 * IT2N_F_* flags. Returns IT2N_OK, or IT2N_ERR_INVAL (ds untouched).
 */
int it2n_dataset_init(it2n_dataset *ds, unsigned n, unsigned m, unsigned flags, it2n_errinfo *err);

/*
 * Store one footprint of grid point (i, j): vals[IT2N_CH_COUNT] in Q24
 * (z ignored unless IT2N_F_Z). Checks index, footprint (only D for type-1),
 * coordinate limit and T, I, F in [0, 1]. With replace false a second put of
 * the same (i, j, fp) fails with IT2N_ERR_DUPLICATE. On error nothing changes.
 */
int it2n_dataset_put(it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                     bool replace, it2n_errinfo *err);

/*
 * it2n_dataset_put with vals in the fine layout (T, I, F in Q30, in
 * [0, IT2N_MEMB_ONE]): what a reader of decimal text uses, so memberships
 * keep 2^-30. Same checks and errors; err->value, lo, hi stay Q24 (an
 * out-of-range membership is reported rounded down to Q24, and one that
 * would round to 1 as 1 + 2^-24, so the value shown is outside too).
 */
int it2n_dataset_put_fine(it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                          bool replace, it2n_errinfo *err);

/* Number of (i, j, footprint) entries the data set still lacks. */
unsigned it2n_dataset_missing(const it2n_dataset *ds);

/*
 * Full validation: every entry present, footprints nested
 * LL <= LR <= L <= D <= R <= RL <= RR on every coordinate axis.
 * Returns IT2N_OK or the first error found (row-major order).
 */
int it2n_dataset_check(const it2n_dataset *ds, it2n_errinfo *err);

/* ---- Model -------------------------------------------------------------- */

/* A solved model: the control nets of every footprint and channel in block
 * floating point. Control point (i, j) of footprint fp, channel ch is
 * net[fp][ch][i * (m + 1) + j] * 2^-frac[fp][ch]: one exponent per net,
 * chosen at solve time so that its largest point uses the full 32 bits
 * (relative precision 2^-31 of the net's range, whatever its magnitude).
 * The data set is not part of the model (keep it next to it; the update
 * needs both). Read control points with it2n_model_ctrl(). */
typedef struct it2n_model {
    uint8_t n, m;        /* degrees                               */
    uint8_t flags;       /* IT2N_F_* of the data set solved       */
    uint8_t solved;      /* 1 once solved                         */
    uint32_t generation; /* bumped on every change                */
    int8_t frac[IT2N_FP_COUNT][IT2N_CH_COUNT];
    int32_t net[IT2N_FP_COUNT][IT2N_CH_COUNT][IT2N_DIM * IT2N_DIM];
} it2n_model;

/* Mark a model empty (unsolved). Always succeeds. */
void it2n_model_init(it2n_model *mdl);

/*
 * Validate ds and solve every control net, P = (M^T)^-1 F N^-1. Atomic: on
 * any error mdl is unchanged. Bumps mdl->generation on success. Uniform
 * parameters use exact inverse tables built into the library; chord-length
 * parameters invert at run time in 62-bit soft floating point.
 */
int it2n_model_solve(it2n_model *mdl, const it2n_dataset *ds, it2n_errinfo *err);

/*
 * Replace one footprint of one data point: ds (the data set mdl was solved
 * from) and mdl change together. Only the nets of that footprint are solved
 * again (all footprints for a chord-length model when footprint D moves,
 * since its parameters follow D), by the same arithmetic as
 * it2n_model_solve, so the result is bit-identical to a full re-solve.
 * Atomic: on any error neither ds nor mdl changes.
 */
int it2n_model_update(it2n_model *mdl, it2n_dataset *ds, unsigned i, unsigned j, unsigned fp,
                      const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err);

/* it2n_model_update with vals in the fine layout (T, I, F in Q30). */
int it2n_model_update_fine(it2n_model *mdl, it2n_dataset *ds, unsigned i, unsigned j, unsigned fp,
                           const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err);

/*
 * Control point (i, j) of footprint fp, channel ch in Q24, rounded to
 * nearest; 0 outside the model's degrees or footprints.
 */
it2n_val it2n_model_ctrl(const it2n_model *mdl, unsigned i, unsigned j, unsigned fp, unsigned ch);

/*
 * Collocation parameters of a data set (as the solve uses them): u[0..n],
 * w[0..m] in Q32. Uniform k/n, or chord-length from footprint D (which the
 * data set must then hold in full). Returns IT2N_OK or an error.
 */
int it2n_params(const it2n_dataset *ds, it2n_par u[IT2N_DIM], it2n_par w[IT2N_DIM], it2n_errinfo *err);

/* Footprints a model carries: IT2N_FP_D only for type-1, else all seven. */
static inline bool it2n_model_has_fp(const it2n_model *mdl, unsigned fp)
{
    return (mdl->flags & IT2N_F_TYPE1) ? fp == IT2N_FP_D : fp < IT2N_FP_COUNT;
}

/* ---- Evaluation --------------------------------------------------------- */

/* Interval summary of T, I, F (index 0..2) at one (u, w). */
typedef struct it2n_summary {
    it2n_val upper_min[3], upper_max[3]; /* over LL, D, RR */
    it2n_val lower_min[3], lower_max[3]; /* over LR, D, RL */
} it2n_summary;

/* All surfaces at one (u, w). out_of_range bit (fp*3 + k) flags membership
 * k (T, I, F) of footprint fp leaving [0, 1]; the raw value is kept. */
typedef struct it2n_point {
    it2n_val v[IT2N_FP_COUNT][IT2N_CH_COUNT];
    it2n_summary sum;
    uint32_t out_of_range;
} it2n_point;

/*
 * Evaluate every footprint surface at (u, w), Q32, within [0, 1] inclusive.
 * Returns IT2N_OK, IT2N_ERR_INVAL, IT2N_ERR_STATE (unsolved) or
 * IT2N_ERR_RANGE (err->value is the offending parameter in Q24, ch 0 for u,
 * 1 for w). err may be NULL.
 */
int it2n_eval(const it2n_model *mdl, it2n_par u, it2n_par w, it2n_point *out, it2n_errinfo *err);

/*
 * Partial derivatives dS/du (du) and dS/dw (dw) of every surface at (u, w).
 * Only the v arrays are filled. Errors as it2n_eval, plus IT2N_ERR_OVERFLOW
 * (fp, ch say which derivative does not fit Q39.24).
 */
int it2n_deriv(const it2n_model *mdl, it2n_par u, it2n_par w, it2n_point *du, it2n_point *dw, it2n_errinfo *err);

/* Sink for it2n_sample: called once per grid node, row-major. Return
 * non-zero to stop early (that value is returned by it2n_sample). */
typedef int (*it2n_sample_cb)(void *ctx, unsigned r, unsigned c, it2n_par u, it2n_par w, const it2n_point *pt);

/*
 * Evaluate on a uniform rows x cols parameter grid (each >= 2, <= 65535),
 * u = r/(rows-1), w = c/(cols-1). Every node is bit-identical to it2n_eval
 * at the same (u, w). Returns IT2N_OK, an error (err filled; IT2N_ERR_RANGE
 * names rows (i) or cols (j) and the limits), or the callback's non-zero
 * stop value.
 */
int it2n_sample(const it2n_model *mdl, unsigned rows, unsigned cols, it2n_sample_cb cb, void *ctx, it2n_errinfo *err);

/* ---- Locate ------------------------------------------------------------- */

enum it2n_loc_status {
    IT2N_LOC_INSIDE = 0,  /* surface passes through (x, y) in [0,1]^2    */
    IT2N_LOC_OUTSIDE = 1, /* nearest point is on the boundary, not exact */
    IT2N_LOC_NOCONV = 2   /* Newton and fallback failed                  */
};

typedef struct it2n_locate_fp {
    it2n_par u, w;             /* parameters found (Q32)       */
    it2n_val v[IT2N_CH_COUNT]; /* surface values there         */
    it2n_val residual;         /* |S_xy(u,w) - (x,y)|_inf, Q24 */
    uint8_t status;            /* enum it2n_loc_status         */
} it2n_locate_fp;

typedef struct it2n_locate_result {
    it2n_locate_fp fp[IT2N_FP_COUNT];
} it2n_locate_result;

/*
 * For each footprint find (u, w) with (x(u,w), y(u,w)) = (x, y): Newton from
 * the best node of a coarse grid, with step halving as the safe fallback.
 * x, y beyond +-IT2N_COORD_LIMIT give IT2N_ERR_RANGE (ch 0 or 1 names
 * which, lo/hi the limit). err may be NULL.
 */
int it2n_locate(const it2n_model *mdl, it2n_val x, it2n_val y, it2n_locate_result *out, it2n_errinfo *err);

/* ---- B-spline kind (cubic, not-a-knot) ----------------------------------- */

/*
 * The second model kind: tensor-product cubic B-spline interpolation through
 * every data point of an (n+1) x (m+1) grid, n, m in 1..IT2N_BSPLINE_MAX_N
 * (up to 256 x 256 points), for every footprint and channel as the Bezier
 * kind, on the uniform parameters u_i = i/n, w_j = j/m with not-a-knot end
 * conditions: the interpolant of MATLAB's spline / interp2(..., 'spline') and
 * SciPy's make_interp_spline(k=3) and CubicSpline. In a direction with fewer
 * than 4 points not-a-knot is undefined; as CubicSpline and MATLAB do, the
 * interpolant there is the polynomial through the points: a straight line
 * for 2 points (n = 1), a parabola for 3 (n = 2); 4 points give the cubic
 * through them. Parameterisation is uniform only (IT2N_F_CHORD is refused).
 *
 * The surface is stored as coefficients c[r][s] of uniform cubic B-splines
 * on the knots i/n extended by one knot beyond each end, r = 0..n+2
 * (c_{-1}..c_{n+1}), s = 0..m+2: a query touches only the 4 x 4 coefficients
 * of its knot span, whatever the grid size. The solve is O(n m): two passes
 * of banded (almost tridiagonal, constant-coefficient) line solves, rows
 * then columns, in integer arithmetic; no inverse matrix. Formats and
 * accuracy: docs/numerics.md.
 *
 * All storage is the caller's (no heap): the data set's records and the
 * model's coefficients live in arrays sized with the macros below, e.g. for
 * a fixed largest grid on an MCU
 *   static it2n_bspline_rec rec[IT2N_BSPLINE_DATA_RECS(63, 63, IT2N_F_TYPE1)];
 *   static int32_t coef[IT2N_BSPLINE_MODEL_WORDS(63, 63, IT2N_F_TYPE1)];
 */

/* Footprints stored per grid point: 1 for type-1 (D only), else 7. */
/* clang-format off */
#define IT2N_BSPLINE_NFP(flags) (((flags) & IT2N_F_TYPE1) ? 1u : 7u)
/* Channels stored per footprint in a model: 6 with z, else 5. */
#define IT2N_BSPLINE_NCH(flags) (((flags) & IT2N_F_Z) ? 6u : 5u)
/* clang-format on */
/* Records a data set of n x m intervals needs. */
#define IT2N_BSPLINE_DATA_RECS(n, m, flags) ((size_t)((n) + 1u) * ((m) + 1u) * IT2N_BSPLINE_NFP(flags))
/* int32 words a model of n x m intervals needs. */
#define IT2N_BSPLINE_MODEL_WORDS(n, m, flags) \
    ((size_t)((n) + 3u) * ((m) + 3u) * IT2N_BSPLINE_NFP(flags) * IT2N_BSPLINE_NCH(flags))

/* One footprint of one grid point as it2n_dataset: a coordinate in Q24 as
 * its low 32 bits (lo) and high 16 bits (hi), a membership in Q30 in memb.
 * 32 bytes. Read it with it2n_bspline_data_get(_fine). */
typedef struct it2n_bspline_rec {
    uint32_t lo[3];   /* x, y, z: low 32 bits of Q24   */
    uint32_t memb[3]; /* T, I, F: Q30 in [0, 2^30]     */
    int16_t hi[3];    /* x, y, z: bits 32..47 of Q24   */
    uint16_t present; /* 1 once stored                 */
} it2n_bspline_rec;

/* A B-spline data set: grid sizes, flags and the caller's record array.
 * Record of footprint fp at (i, j): rec[(i (m+1) + j) nfp + (type-1 ? 0 :
 * fp)]. */
typedef struct it2n_bspline_data {
    it2n_bspline_rec *rec; /* caller storage                       */
    size_t cap;            /* records at rec                       */
    uint16_t n, m;         /* intervals: grid (n+1) x (m+1)        */
    uint8_t flags;         /* IT2N_F_Z, IT2N_F_TYPE1               */
} it2n_bspline_data;

/*
 * Start an empty data set of n x m intervals (1..IT2N_BSPLINE_MAX_N each)
 * in rec[0..cap), which must hold IT2N_BSPLINE_DATA_RECS(n, m, flags)
 * records. flags: IT2N_F_Z, IT2N_F_TYPE1. Returns IT2N_OK, IT2N_ERR_INVAL
 * (bad size or flags: value, lo, hi say which limit) or IT2N_ERR_RANGE (cap
 * too small: value is cap, lo the records needed); ds untouched on error.
 */
int it2n_bspline_data_init(it2n_bspline_data *ds, it2n_bspline_rec *rec, size_t cap, unsigned n, unsigned m,
                           unsigned flags, it2n_errinfo *err);

/*
 * Store footprint fp of grid point (i, j), vals in Q24 as it2n_dataset_put
 * (same checks and errors; with replace false a second put fails with
 * IT2N_ERR_DUPLICATE). On error nothing changes.
 */
int it2n_bspline_data_put(it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                          const it2n_val vals[IT2N_CH_COUNT], bool replace, it2n_errinfo *err);

/* it2n_bspline_data_put with vals in the fine layout (T, I, F in Q30), as
 * it2n_dataset_put_fine. */
int it2n_bspline_data_put_fine(it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                               const it2n_val vals[IT2N_CH_COUNT], bool replace, it2n_errinfo *err);

/* All channels of footprint fp at (i, j) into vals (Q24, memberships
 * rounded to nearest, ties up); zeros for an index, footprint or record not
 * stored. */
void it2n_bspline_data_get(const it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                           it2n_val vals[IT2N_CH_COUNT]);

/* The same in the fine layout (memberships in Q30, exactly as stored). */
void it2n_bspline_data_get_fine(const it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                                it2n_val vals[IT2N_CH_COUNT]);

/* Number of (i, j, footprint) entries the data set still lacks. */
uint32_t it2n_bspline_data_missing(const it2n_bspline_data *ds);

/*
 * Full validation as it2n_dataset_check: every entry present, values in
 * range, footprints nested on every coordinate axis. IT2N_OK or the first
 * error in row-major order.
 */
int it2n_bspline_data_check(const it2n_bspline_data *ds, it2n_errinfo *err);

/* A solved B-spline model: per footprint and channel a net of (n+3) x (m+3)
 * int32 mantissas in the caller's coef array, block floating point as the
 * Bezier model (coefficient = mantissa * 2^-frac[fp][ch], the net's largest
 * |mantissa| in [2^30, 2^31)). Read coefficients with
 * it2n_bspline_coef(). */
typedef struct it2n_bspline_model {
    int32_t *coef;       /* caller storage                           */
    size_t cap;          /* int32 words at coef                      */
    uint16_t n, m;       /* intervals of the data set solved         */
    uint8_t flags;       /* its IT2N_F_*                             */
    uint8_t solved;      /* 1 once solved                            */
    uint32_t generation; /* bumped on every change                   */
    int8_t frac[IT2N_FP_COUNT][IT2N_CH_COUNT];
} it2n_bspline_model;

/* An empty (unsolved) model over coef[0..cap). Always succeeds. */
void it2n_bspline_model_init(it2n_bspline_model *mdl, int32_t *coef, size_t cap);

/*
 * Validate ds (it2n_bspline_data_check) and solve every net. Needs
 * IT2N_BSPLINE_MODEL_WORDS(n, m, flags) words at mdl->coef (IT2N_ERR_RANGE,
 * value = cap, lo = words needed). Atomic: on any error mdl is unchanged.
 * Bumps mdl->generation. Cannot overflow: every coefficient is below 256
 * times the net's largest |value| (docs/numerics.md).
 */
int it2n_bspline_solve(it2n_bspline_model *mdl, const it2n_bspline_data *ds, it2n_errinfo *err);

/*
 * Replace footprint fp of data point (i, j) in ds (the data set mdl was
 * solved from) and solve that footprint's nets again, with exactly the
 * arithmetic of it2n_bspline_solve: bit-identical to a full re-solve.
 * Checks as it2n_bspline_data_put (replace) plus nesting with the other
 * footprints of (i, j). IT2N_ERR_STATE if mdl is unsolved or was solved
 * from a data set of other sizes or flags. Atomic: on error neither
 * changes. Cost: the nets of one footprint, O(n m) each.
 */
int it2n_bspline_update(it2n_bspline_model *mdl, it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                        const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err);

/* it2n_bspline_update with vals in the fine layout (T, I, F in Q30). */
int it2n_bspline_update_fine(it2n_bspline_model *mdl, it2n_bspline_data *ds, unsigned i, unsigned j, unsigned fp,
                             const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err);

/*
 * Coefficient c_{r-1, s-1} (r in 0..n+2, s in 0..m+2) of footprint fp,
 * channel ch in Q24, rounded to nearest; 0 outside the model.
 */
it2n_val it2n_bspline_coef(const it2n_bspline_model *mdl, unsigned r, unsigned s, unsigned fp, unsigned ch);

/*
 * Every footprint surface at (u, w) (Q32, within [0, 1]): values, interval
 * summary and out_of_range as it2n_eval, same errors. Touches 4 x 4
 * coefficients per net whatever n and m.
 */
int it2n_bspline_eval(const it2n_bspline_model *mdl, it2n_par u, it2n_par w, it2n_point *out, it2n_errinfo *err);

/*
 * Partial derivatives dS/du and dS/dw at (u, w) as it2n_deriv (only the v
 * arrays are filled; IT2N_ERR_OVERFLOW names fp, ch if one does not fit
 * Q39.24).
 */
int it2n_bspline_deriv(const it2n_bspline_model *mdl, it2n_par u, it2n_par w, it2n_point *du, it2n_point *dw,
                       it2n_errinfo *err);

/*
 * For each footprint the (u, w) whose surface passes through (x, y), as
 * it2n_locate (same method, statuses and errors): Newton from the best node
 * of the (IT2N_LOCATE_GRID+1)^2 start grid. The start grid does not grow
 * with the model: on a large grid folded in (x, y) Newton may stop in a
 * local minimum (status noconv or outside).
 */
int it2n_bspline_locate(const it2n_bspline_model *mdl, it2n_val x, it2n_val y, it2n_locate_result *out,
                        it2n_errinfo *err);

/*
 * Evaluate on a uniform rows x cols parameter grid as it2n_sample (same
 * callback, limits and errors); every node bit-identical to
 * it2n_bspline_eval at the same (u, w).
 */
int it2n_bspline_sample(const it2n_bspline_model *mdl, unsigned rows, unsigned cols, it2n_sample_cb cb, void *ctx,
                        it2n_errinfo *err);

/* ---- Text conversion (no stdio; exact decimal rounding) ----------------- */

/*
 * Parse a decimal number ("-12.5", "0.000001", "3e-2") of len bytes into Q24,
 * rounded to nearest, ties away from zero. Returns IT2N_OK, IT2N_ERR_INVAL
 * (not a number) or IT2N_ERR_RANGE (|value| beyond IT2N_COORD_LIMIT).
 */
int it2n_parse_val(const char *s, size_t len, it2n_val *out);

/*
 * Parse a decimal membership into Q30 (IT2N_MEMB_FRAC), rounded as
 * it2n_parse_val. Accepts the magnitudes it2n_parse_val does (same errors):
 * the [0, 1] check is the data set's (it2n_dataset_put_fine), so a reader
 * reports a membership out of range like any other value.
 */
int it2n_parse_memb(const char *s, size_t len, it2n_val *out);

/* Parse a decimal parameter into Q32; must lie within [0, 1]. */
int it2n_parse_par(const char *s, size_t len, it2n_par *out);

/*
 * Format a Q24 value with `decimals` (0..9) digits after the point, rounded
 * to nearest, into buf (NUL-terminated). Returns the length, or
 * IT2N_ERR_RANGE if buf is too small.
 */
int it2n_format_val(char *buf, size_t size, it2n_val v, unsigned decimals);

/* Same for a Q32 parameter / basis value. */
int it2n_format_par(char *buf, size_t size, it2n_par p, unsigned decimals);

/* ---- Names and messages ------------------------------------------------- */

/* "LL", "LR", "L", "D", "R", "RL", "RR", or NULL. */
const char *it2n_fp_name(unsigned fp);
/* Footprint index for a name, or IT2N_ERR_INVAL. */
int it2n_fp_from_name(const char *name, size_t len);
/* "x", "y", "z", "T", "I", "F", or NULL. */
const char *it2n_ch_name(unsigned ch);
/* Short English description of an error code. */
const char *it2n_strerror(int code);

#endif /* IT2N_H */
