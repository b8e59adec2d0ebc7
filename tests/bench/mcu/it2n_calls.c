/* Wrappers over the it2n public API; see it2n_calls.h. */
#include "it2n_calls.h"

#include "it2n.h"

static it2n_dataset bc_ds;
static it2n_model bc_mdl;
static it2n_point bc_pt;

static const unsigned bc_ch[BENCH_CH] = {IT2N_CH_X, IT2N_CH_Y, IT2N_CH_T, IT2N_CH_I, IT2N_CH_F};

int bc_load(const bench_set *s)
{
    it2n_errinfo err;
    unsigned r, c;
    int rc = it2n_dataset_init(&bc_ds, s->n, s->m, 0u, &err);
    for (r = 0; rc == IT2N_OK && r < s->nrows; r++) {
        const bench_row *row = &s->rows[r];
        it2n_val v[IT2N_CH_COUNT] = {0};
        for (c = 0; c < BENCH_CH; c++) {
            v[bc_ch[c]] = row->q24[c];
        }
        rc = it2n_dataset_put(&bc_ds, row->i, row->j, row->fp, v, false, &err);
    }
    return rc;
}

int bc_solve(void)
{
    it2n_errinfo err;
    it2n_model_init(&bc_mdl);
    return it2n_model_solve(&bc_mdl, &bc_ds, &err);
}

int bc_query(int64_t u_q32, int64_t w_q32)
{
    return it2n_eval(&bc_mdl, u_q32, w_q32, &bc_pt, NULL);
}

int64_t bc_value(unsigned fp, unsigned ch)
{
    return bc_pt.v[fp][bc_ch[ch]];
}

int64_t bc_summary(unsigned which, unsigned k)
{
    switch (which) {
    case 0:
        return bc_pt.sum.upper_min[k];
    case 1:
        return bc_pt.sum.upper_max[k];
    case 2:
        return bc_pt.sum.lower_min[k];
    default:
        return bc_pt.sum.lower_max[k];
    }
}

int64_t bc_ctrl(unsigned i, unsigned j, unsigned fp, unsigned ch)
{
    return it2n_model_ctrl(&bc_mdl, i, j, fp, bc_ch[ch]);
}
