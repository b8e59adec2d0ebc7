/* Footprint D of the paper's 4x4 example (examples/paper_4x4.csv) as a
 * type-1 model: put 16 data points, solve once, evaluate anywhere.
 * C99, no heap, no float: the same file builds for a host and an MCU. */
#include "paper_model.h"

/* x, y (whole units) and T, I, F (hundredths) of grid point (i, j). */
static const int16_t paper_d[4][4][5] = {
    {{-17, 17, 40, 70, 20}, {-17, 7, 90, 30, 10}, {-17, -7, 40, 40, 50}, {-17, -17, 60, 50, 20}},
    {{-7, 17, 60, 40, 30}, {-7, 7, 80, 20, 30}, {-7, -7, 50, 50, 30}, {-7, -17, 70, 40, 20}},
    {{7, 17, 60, 20, 50}, {7, 7, 80, 40, 10}, {7, -7, 50, 70, 10}, {7, -17, 50, 30, 50}},
    {{17, 17, 70, 30, 30}, {17, 7, 40, 60, 30}, {17, -7, 40, 60, 30}, {17, -17, 70, 40, 20}},
};

/* Both structs are large (sizes per IT2N_MAX_DEGREE: docs/portability.md):
 * static, never on the stack. The model does not hold the data set. */
static it2n_dataset ds;
static it2n_model mdl;

/* Hundredths to Q24, rounded to nearest like it2n_parse_val. */
static it2n_val from_hundredths(int16_t h)
{
    return ((it2n_val)h * IT2N_VAL_ONE + 50) / 100;
}

int paper_model_solve(it2n_errinfo *err)
{
    it2n_val v[IT2N_CH_COUNT];
    int rc = it2n_dataset_init(&ds, 3, 3, IT2N_F_TYPE1, err); /* degrees 3 x 3 */
    for (unsigned i = 0; i < 4 && rc == IT2N_OK; i++) {
        for (unsigned j = 0; j < 4 && rc == IT2N_OK; j++) {
            const int16_t *p = paper_d[i][j];
            v[IT2N_CH_X] = (it2n_val)p[0] * IT2N_VAL_ONE;
            v[IT2N_CH_Y] = (it2n_val)p[1] * IT2N_VAL_ONE;
            v[IT2N_CH_Z] = 0;
            v[IT2N_CH_T] = from_hundredths(p[2]);
            v[IT2N_CH_I] = from_hundredths(p[3]);
            v[IT2N_CH_F] = from_hundredths(p[4]);
            rc = it2n_dataset_put(&ds, i, j, IT2N_FP_D, v, false, err);
        }
    }
    if (rc == IT2N_OK) {
        it2n_model_init(&mdl);
        rc = it2n_model_solve(&mdl, &ds, err);
    }
    return rc;
}

int paper_model_eval(it2n_par u, it2n_par w, it2n_val out[IT2N_CH_COUNT],
                     it2n_errinfo *err)
{
    it2n_point pt; /* every footprint; sizeof: docs/portability.md */
    int rc = it2n_eval(&mdl, u, w, &pt, err);
    if (rc == IT2N_OK) {
        for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++) {
            out[ch] = pt.v[IT2N_FP_D][ch];
        }
    }
    return rc;
}
