/*
 * ctl_src: the data it2nctl push uploads, one set of accessors for the
 * link and the Modbus transports (ctl_src.h).
 */
#include "ctl_src.h"

unsigned ctl_src_n(const ctl_src *s)
{
    return s->bds != NULL ? s->bds->n : s->ds->n;
}

unsigned ctl_src_m(const ctl_src *s)
{
    return s->bds != NULL ? s->bds->m : s->ds->m;
}

unsigned ctl_src_flags(const ctl_src *s)
{
    return s->bds != NULL ? s->bds->flags : s->ds->flags;
}

bool ctl_src_has(const ctl_src *s, unsigned i, unsigned j, unsigned fp)
{
    if (s->bds != NULL) {
        const it2n_bspline_data *b = s->bds;
        bool t1 = (b->flags & IT2N_F_TYPE1) != 0u;
        if (t1 && fp != IT2N_FP_D) {
            return false;
        }
        return b->rec[((size_t)i * (b->m + 1u) + j) * IT2N_BSPLINE_NFP(b->flags) + (t1 ? 0u : fp)].present != 0u;
    }
    return (s->ds->present[i][j] >> fp) & 1u;
}

void ctl_src_get(const ctl_src *s, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT])
{
    if (s->bds != NULL) {
        it2n_bspline_data_get(s->bds, i, j, fp, v);
    } else {
        it2n_dataset_get(s->ds, i, j, fp, v);
    }
}

void ctl_src_get_fine(const ctl_src *s, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT])
{
    if (s->bds != NULL) {
        it2n_bspline_data_get_fine(s->bds, i, j, fp, v);
    } else {
        it2n_dataset_get_fine(s->ds, i, j, fp, v);
    }
}
