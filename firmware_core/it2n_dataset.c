/*
 * Data set assembly and validation. Every check reports what, where and
 * which limit; nothing is written unless every check passed.
 */
#include <string.h>

#include "it2n_internal.h"

#define COORD_MAX ((it2n_val)IT2N_COORD_LIMIT << IT2N_VAL_FRAC)

int it2n_dataset_init(it2n_dataset *ds, unsigned n, unsigned m, unsigned flags, it2n_errinfo *err)
{
    if (ds == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (n < 1u || n > IT2N_MAX_DEGREE) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, (it2n_val)n, 1, IT2N_MAX_DEGREE);
    }
    if (m < 1u || m > IT2N_MAX_DEGREE) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, (it2n_val)m, 1, IT2N_MAX_DEGREE);
    }
    if ((flags & ~IT2N_F_ALL) != 0u) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, (it2n_val)flags, 0, IT2N_F_ALL);
    }
    memset(ds, 0, sizeof(*ds));
    ds->n = (uint8_t)n;
    ds->m = (uint8_t)m;
    ds->flags = (uint8_t)flags;
    return IT2N_OK;
}

int it2n__check_vals(unsigned flags, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT], int mfrac,
                     it2n_errinfo *err)
{
    unsigned ch;
    for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
        it2n_val v = vals[ch], lo, hi;
        if (!it2n__ch_used(flags, ch)) {
            continue;
        }
        if (ch <= IT2N_CH_Z) {
            lo = -COORD_MAX;
            hi = COORD_MAX;
        } else {
            lo = 0;
            hi = (it2n_val)1 << mfrac;
        }
        if (v < lo || v > hi) {
            if (ch > IT2N_CH_Z) {
                /* to Q24 (floor), kept outside [0, 1]: only 1 + 2^-30 ..
                 * 1 + 63 2^-30 floor to 1 itself */
                v >>= mfrac - IT2N_VAL_FRAC;
                v += v == IT2N_VAL_ONE ? 1 : 0;
                hi = IT2N_VAL_ONE;
            }
            return it2n__fail(err, IT2N_ERR_RANGE, (int)i, (int)j, (int)fp, (int)ch, v, lo, hi);
        }
    }
    return IT2N_OK;
}

/* it2n_dataset_put for memberships of mfrac fraction bits. */
static int dataset_put(it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                       bool replace, int mfrac, it2n_errinfo *err)
{
    int rc;
    if (ds == NULL || vals == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    if (i > ds->n || j > ds->m) {
        return it2n__fail(err, IT2N_ERR_INVAL, (int)i, (int)j, -1, -1, (it2n_val)(i > ds->n ? i : j), 0,
                          (it2n_val)(i > ds->n ? ds->n : ds->m));
    }
    if (fp >= IT2N_FP_COUNT || ((1u << fp) & it2n__fp_mask(ds->flags)) == 0u) {
        return it2n__fail(err, IT2N_ERR_INVAL, (int)i, (int)j, (int)fp, -1, (it2n_val)fp, 0, IT2N_FP_COUNT - 1);
    }
    rc = it2n__check_vals(ds->flags, i, j, fp, vals, mfrac, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    if (!replace && (ds->present[i][j] & (1u << fp)) != 0u) {
        return it2n__fail(err, IT2N_ERR_DUPLICATE, (int)i, (int)j, (int)fp, -1, 0, 0, 0);
    }
    it2n__dataset_store(ds, i, j, fp, vals, (unsigned)(IT2N_MEMB_FRAC - mfrac));
    ds->present[i][j] = (uint8_t)(ds->present[i][j] | (1u << fp));
    return IT2N_OK;
}

int it2n_dataset_put(it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                     bool replace, it2n_errinfo *err)
{
    return dataset_put(ds, i, j, fp, vals, replace, IT2N_VAL_FRAC, err);
}

int it2n_dataset_put_fine(it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                          bool replace, it2n_errinfo *err)
{
    return dataset_put(ds, i, j, fp, vals, replace, IT2N_MEMB_FRAC, err);
}

void it2n__dataset_store(it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                         unsigned shift)
{
    unsigned ch;
    for (ch = 0; ch < 3u; ch++) {
        /* checked: |coordinate| < 2^47, membership in [0, 2^(30 - shift)] */
        uint64_t v = it2n__ch_used(ds->flags, ch) ? (uint64_t)vals[ch] : 0u;
        ds->coord_lo[i][j][fp][ch] = (uint32_t)v;
        ds->coord_hi[i][j][fp][ch] = (int16_t)((int64_t)vals[ch] >> 32);
        if (!it2n__ch_used(ds->flags, ch)) {
            ds->coord_hi[i][j][fp][ch] = 0;
        }
        ds->memb[i][j][fp][ch] = (uint32_t)vals[3u + ch] << shift;
    }
}

void it2n_dataset_get(const it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, it2n_val vals[IT2N_CH_COUNT])
{
    unsigned k;
    it2n_dataset_get_fine(ds, i, j, fp, vals);
    for (k = IT2N_CH_T; k < IT2N_CH_COUNT; k++) {
        /* in [0, 2^30]: Q24 rounded to nearest, ties up */
        vals[k] = (vals[k] + ((it2n_val)1 << (IT2N_MEMB_FRAC - IT2N_VAL_FRAC - 1))) >> (IT2N_MEMB_FRAC - IT2N_VAL_FRAC);
    }
}

void it2n_dataset_get_fine(const it2n_dataset *ds, unsigned i, unsigned j, unsigned fp, it2n_val vals[IT2N_CH_COUNT])
{
    unsigned k;
    for (k = 0; k < 3u; k++) {
        vals[k] = it2n_dataset_value_fine(ds, i, j, fp, k);
    }
    for (k = 0; k < 3u; k++) {
        vals[3u + k] = (it2n_val)ds->memb[i][j][fp][k];
    }
}

unsigned it2n_dataset_missing(const it2n_dataset *ds)
{
    unsigned i, j, fp, missing = 0u, mask = it2n__fp_mask(ds->flags);
    for (i = 0; i <= ds->n; i++) {
        for (j = 0; j <= ds->m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if ((mask & (1u << fp)) && !(ds->present[i][j] & (1u << fp))) {
                    missing++;
                }
            }
        }
    }
    return missing;
}

int it2n__check_nesting_point(const it2n_dataset *ds, unsigned i, unsigned j, unsigned fp,
                              const it2n_val vals[IT2N_CH_COUNT], it2n_errinfo *err)
{
    unsigned ch;
    if (ds->flags & IT2N_F_TYPE1) {
        return IT2N_OK;
    }
    /* in the order a full check reports: fp against fp - 1, then fp + 1
     * against fp (the rest of the chain is unchanged) */
    for (ch = 0; ch < it2n__ncoord(ds->flags) && fp > 0u; ch++) {
        it2n_val prev = it2n_dataset_value_fine(ds, i, j, fp - 1u, ch);
        if (vals[ch] < prev) {
            return it2n__fail(err, IT2N_ERR_ORDER, (int)i, (int)j, (int)fp, (int)ch, vals[ch], prev, vals[ch]);
        }
    }
    for (ch = 0; ch < it2n__ncoord(ds->flags) && fp + 1u < IT2N_FP_COUNT; ch++) {
        it2n_val next = it2n_dataset_value_fine(ds, i, j, fp + 1u, ch);
        if (next < vals[ch]) {
            return it2n__fail(err, IT2N_ERR_ORDER, (int)i, (int)j, (int)fp + 1, (int)ch, next, vals[ch], next);
        }
    }
    return IT2N_OK;
}

/* Nesting of the stored footprints of (i, j), read straight from ds. */
static int check_nesting_ds(const it2n_dataset *ds, unsigned i, unsigned j, it2n_errinfo *err)
{
    unsigned ch, fp;
    if (ds->flags & IT2N_F_TYPE1) {
        return IT2N_OK;
    }
    for (fp = 1; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < it2n__ncoord(ds->flags); ch++) {
            it2n_val prev = it2n_dataset_value_fine(ds, i, j, fp - 1u, ch);
            it2n_val v = it2n_dataset_value_fine(ds, i, j, fp, ch);
            if (v < prev) {
                return it2n__fail(err, IT2N_ERR_ORDER, (int)i, (int)j, (int)fp, (int)ch, v, prev, v);
            }
        }
    }
    return IT2N_OK;
}

int it2n_dataset_check(const it2n_dataset *ds, it2n_errinfo *err)
{
    it2n_val vals[IT2N_CH_COUNT] = {0, 0, 0, 0, 0, 0};
    unsigned i, j, fp, mask;
    int rc;
    if (ds == NULL || ds->n < 1u || ds->n > IT2N_MAX_DEGREE || ds->m < 1u || ds->m > IT2N_MAX_DEGREE ||
        (ds->flags & ~IT2N_F_ALL) != 0u) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    mask = it2n__fp_mask(ds->flags);
    for (i = 0; i <= ds->n; i++) {
        for (j = 0; j <= ds->m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (!(mask & (1u << fp))) {
                    continue;
                }
                if (!(ds->present[i][j] & (1u << fp))) {
                    return it2n__fail(err, IT2N_ERR_MISSING, (int)i, (int)j, (int)fp, -1, 0, 0, 0);
                }
                /* Re-check ranges: the struct may have been filled by hand. */
                it2n_dataset_get_fine(ds, i, j, fp, vals);
                rc = it2n__check_vals(ds->flags, i, j, fp, vals, IT2N_MEMB_FRAC, err);
                if (rc != IT2N_OK) {
                    return rc;
                }
            }
            rc = check_nesting_ds(ds, i, j, err);
            if (rc != IT2N_OK) {
                return rc;
            }
        }
    }
    return IT2N_OK;
}
