/*
 * A data set of either kind behind one set of accessors (cli_data,
 * cli.h): it2nctl push walks the same entries over Modbus and the link,
 * and plot draws the data points of either kind, with this code.
 */
#include "cli.h"

cli_data cli_data_bezier(const it2n_dataset *ds)
{
    cli_data d = {ds, NULL, ds ? ds->n : 0u, ds ? ds->m : 0u, ds ? ds->flags : 0u};
    return d;
}

cli_data cli_data_bspline(const it2n_bspline_data *bds)
{
    cli_data d = {NULL, bds, bds ? bds->n : 0u, bds ? bds->m : 0u, bds ? bds->flags : 0u};
    return d;
}

bool cli_data_has(const cli_data *d, unsigned i, unsigned j, unsigned fp)
{
    if (i > d->n || j > d->m || fp >= IT2N_FP_COUNT) {
        return false;
    }
    if (d->bds != NULL) {
        const it2n_bspline_data *b = d->bds;
        bool t1 = (b->flags & IT2N_F_TYPE1) != 0u;
        if (t1 && fp != IT2N_FP_D) {
            return false;
        }
        return b->rec[((size_t)i * (b->m + 1u) + j) * IT2N_BSPLINE_NFP(b->flags) + (t1 ? 0u : fp)].present != 0u;
    }
    return d->ds != NULL && ((d->ds->present[i][j] >> fp) & 1u) != 0u;
}

void cli_data_get(const cli_data *d, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT])
{
    if (d->bds != NULL) {
        it2n_bspline_data_get(d->bds, i, j, fp, v);
    } else {
        it2n_dataset_get(d->ds, i, j, fp, v);
    }
}

void cli_data_get_fine(const cli_data *d, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT])
{
    if (d->bds != NULL) {
        it2n_bspline_data_get_fine(d->bds, i, j, fp, v);
    } else {
        it2n_dataset_get_fine(d->ds, i, j, fp, v);
    }
}

unsigned cli_data_count(const cli_data *d)
{
    unsigned i, j, fp, total = 0;
    for (i = 0; i <= d->n; i++) {
        for (j = 0; j <= d->m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                total += cli_data_has(d, i, j, fp);
            }
        }
    }
    return total;
}
