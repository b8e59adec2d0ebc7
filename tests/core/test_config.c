/*
 * IT2N_CONFIG: the core and this program are built with
 * -DIT2N_CONFIG=it2n_test_config.h and no other option; every option in that
 * header must take effect in the header and in the compiled library.
 */
#include <stdio.h>
#include <string.h>

#include "it2n.h"

typedef char check_degree[IT2N_MAX_DEGREE == 3 && IT2N_DIM == 4 ? 1 : -1];
typedef char check_limit[IT2N_COORD_LIMIT == 1000 ? 1 : -1];
typedef char check_grid[IT2N_LOCATE_GRID == 4 && IT2N_LOCATE_MAX_ITER == 20 ? 1 : -1];
typedef char check_chord[IT2N_CHORD == 0 && (IT2N_F_ALL & IT2N_F_CHORD) == 0 ? 1 : -1];

typedef char check_bspline[IT2N_BSPLINE_MAX_N == 15 ? 1 : -1];

static it2n_dataset ds;
static it2n_model mdl;
/* B-spline storage for the configured largest grid, 16 x 16 points */
static it2n_bspline_rec brec[IT2N_BSPLINE_DATA_RECS(IT2N_BSPLINE_MAX_N, IT2N_BSPLINE_MAX_N, IT2N_F_TYPE1)];
static int32_t bcoef[IT2N_BSPLINE_MODEL_WORDS(IT2N_BSPLINE_MAX_N, IT2N_BSPLINE_MAX_N, IT2N_F_TYPE1)];

int main(void)
{
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    int rc, fails = 0;
    /* degree 4 is beyond the configured maximum: refused by the library */
    rc = it2n_dataset_init(&ds, 4, 1, IT2N_F_TYPE1, &err);
    if (rc != IT2N_ERR_INVAL || err.hi != 3) {
        printf("FAIL: degree 4 accepted or wrong limit (rc %d, hi %lld)\n", rc, (long long)err.hi);
        fails++;
    }
    /* chord-length parameters are not built in: refused, naming the flags */
    rc = it2n_dataset_init(&ds, 1, 1, IT2N_F_CHORD, &err);
    if (rc != IT2N_ERR_INVAL || err.hi != (it2n_val)IT2N_F_ALL) {
        printf("FAIL: IT2N_F_CHORD accepted without IT2N_CHORD (rc %d)\n", rc);
        fails++;
    }
    /* the coordinate limit of the config, not the default */
    rc = it2n_dataset_init(&ds, 1, 1, IT2N_F_TYPE1, &err);
    memset(v, 0, sizeof v);
    v[IT2N_CH_X] = (it2n_val)1001 << IT2N_VAL_FRAC;
    rc = it2n_dataset_put(&ds, 0, 0, IT2N_FP_D, v, false, &err);
    if (rc != IT2N_ERR_RANGE || err.hi != (it2n_val)1000 << IT2N_VAL_FRAC) {
        printf("FAIL: coordinate 1001 accepted or wrong limit (rc %d)\n", rc);
        fails++;
    }
    /* a degree-3 model solves and evaluates */
    rc = it2n_dataset_init(&ds, 3, 3, IT2N_F_TYPE1, &err);
    for (unsigned i = 0; i <= 3 && rc == IT2N_OK; i++)
        for (unsigned j = 0; j <= 3 && rc == IT2N_OK; j++) {
            v[IT2N_CH_X] = (it2n_val)i << IT2N_VAL_FRAC;
            v[IT2N_CH_Y] = (it2n_val)j << IT2N_VAL_FRAC;
            v[IT2N_CH_T] = IT2N_VAL_ONE / 2;
            v[IT2N_CH_I] = IT2N_VAL_ONE / 4;
            v[IT2N_CH_F] = IT2N_VAL_ONE / 8;
            rc = it2n_dataset_put(&ds, i, j, IT2N_FP_D, v, false, &err);
        }
    if (rc == IT2N_OK)
        rc = it2n_model_solve(&mdl, &ds, &err);
    it2n_point pt;
    if (rc == IT2N_OK)
        rc = it2n_eval(&mdl, IT2N_PAR_ONE / 3, IT2N_PAR_ONE / 5, &pt, &err);
    if (rc != IT2N_OK || pt.v[IT2N_FP_D][IT2N_CH_T] != IT2N_VAL_ONE / 2 ||
        pt.v[IT2N_FP_D][IT2N_CH_X] != IT2N_VAL_ONE) {
        printf("FAIL: degree-3 model (rc %d)\n", rc);
        fails++;
    }
    /* B-spline grids up to IT2N_BSPLINE_MAX_N intervals, no more */
    {
        it2n_bspline_data bds;
        it2n_bspline_model bm;
        rc = it2n_bspline_data_init(&bds, brec, sizeof brec / sizeof brec[0], 16, 15,
                                    IT2N_F_TYPE1, &err);
        if (rc != IT2N_ERR_INVAL || err.hi != 15) {
            printf("FAIL: B-spline n = 16 accepted or wrong limit (rc %d)\n", rc);
            fails++;
        }
        rc = it2n_bspline_data_init(&bds, brec, sizeof brec / sizeof brec[0], 15, 15,
                                    IT2N_F_TYPE1, &err);
        for (unsigned i = 0; i <= 15 && rc == IT2N_OK; i++)
            for (unsigned j = 0; j <= 15 && rc == IT2N_OK; j++) {
                v[IT2N_CH_X] = (it2n_val)(i * 60) << IT2N_VAL_FRAC;
                v[IT2N_CH_Y] = (it2n_val)(j * 60) << IT2N_VAL_FRAC;
                rc = it2n_bspline_data_put(&bds, i, j, IT2N_FP_D, v, false, &err);
            }
        it2n_bspline_model_init(&bm, bcoef, sizeof bcoef / sizeof bcoef[0]);
        if (rc == IT2N_OK)
            rc = it2n_bspline_solve(&bm, &bds, &err);
        if (rc == IT2N_OK)
            rc = it2n_bspline_eval(&bm, IT2N_PAR_ONE / 3, IT2N_PAR_ONE / 5, &pt, &err);
        /* linear data are reproduced (to 2^-31 of the range: 900 * 2^-7
         * LSB here), constants exactly */
        if (rc != IT2N_OK || pt.v[IT2N_FP_D][IT2N_CH_T] != IT2N_VAL_ONE / 2 ||
            pt.v[IT2N_FP_D][IT2N_CH_X] - (it2n_val)300 * IT2N_VAL_ONE > 16 ||
            pt.v[IT2N_FP_D][IT2N_CH_X] - (it2n_val)300 * IT2N_VAL_ONE < -16) {
            printf("FAIL: 16x16 B-spline model (rc %d, T %lld, x %lld)\n", rc,
                   (long long)pt.v[IT2N_FP_D][IT2N_CH_T], (long long)pt.v[IT2N_FP_D][IT2N_CH_X]);
            fails++;
        }
    }
    printf("%s: IT2N_CONFIG options applied (MAX_DEGREE 3, COORD_LIMIT 1000, "
           "LOCATE_GRID 4, CHORD 0, BSPLINE_MAX_N 15, sizeof(it2n_model) %zu)\n",
           fails ? "FAIL" : "PASS", sizeof(it2n_model));
    return fails != 0;
}
