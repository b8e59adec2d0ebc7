/*
 * Names of footprints, channels and error codes (const tables only).
 */
#include "it2n_internal.h"

static const char *const fp_names[IT2N_FP_COUNT] = {"LL", "LR", "L", "D", "R", "RL", "RR"};
static const char *const ch_names[IT2N_CH_COUNT] = {"x", "y", "z", "T", "I", "F"};

const char *it2n_fp_name(unsigned fp)
{
    return fp < IT2N_FP_COUNT ? fp_names[fp] : NULL;
}

int it2n_fp_from_name(const char *name, size_t len)
{
    unsigned k;
    /* Hand-rolled compare: the core links only memcpy/memset/memmove. */
    for (k = 0; k < IT2N_FP_COUNT && name != NULL; k++) {
        const char *ref = fp_names[k];
        size_t i = 0;
        while (i < len && ref[i] != '\0' && ref[i] == name[i]) {
            i++;
        }
        if (i == len && ref[i] == '\0') {
            return (int)k;
        }
    }
    return IT2N_ERR_INVAL;
}

const char *it2n_ch_name(unsigned ch)
{
    return ch < IT2N_CH_COUNT ? ch_names[ch] : NULL;
}

const char *it2n_strerror(int code)
{
    switch (code) {
    case IT2N_OK: return "ok";
    case IT2N_ERR_INVAL: return "invalid argument";
    case IT2N_ERR_RANGE: return "value out of range";
    case IT2N_ERR_DUPLICATE: return "duplicate data point";
    case IT2N_ERR_MISSING: return "missing data point";
    case IT2N_ERR_ORDER: return "footprints not nested";
    case IT2N_ERR_OVERFLOW: return "fixed-point overflow";
    case IT2N_ERR_SINGULAR: return "singular collocation matrix";
    case IT2N_ERR_DEGENERATE: return "degenerate parameterisation";
    case IT2N_ERR_STATE: return "model not in the required state";
    case IT2N_ERR_NOCONV: return "no convergence";
    default: return "unknown error";
    }
}

int it2n__fail(it2n_errinfo *err, int code, int i, int j, int fp, int ch, it2n_val value, it2n_val lo, it2n_val hi)
{
    if (err != NULL) {
        err->code = code;
        err->i = (int16_t)i;
        err->j = (int16_t)j;
        err->fp = (int8_t)fp;
        err->ch = (int8_t)ch;
        err->value = value;
        err->lo = lo;
        err->hi = hi;
    }
    return code;
}
